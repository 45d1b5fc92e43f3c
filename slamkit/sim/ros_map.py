"""ROS ``map_server`` map files: a YAML (image, resolution, origin, negate, occupied_thresh,
free_thresh, optional mode) next to a PGM or PNG image. The YAML is read here (sim may import
yaml); the image decoding and the pixel rule live in :mod:`slamkit.maps.image_map`.
"""

from __future__ import annotations

from pathlib import Path

from typing import Annotated, Literal

import numpy as np
import yaml
from pydantic import BaseModel, Field

from slamkit.config import STRICT, load_yaml, validate
from slamkit.errors import DataError
from slamkit.data.formats.image import read_image
from slamkit.maps.image_map import ImageMap, grid_to_pgm_bytes, occupancy_from_image
from slamkit.maps.occupancy_grid import OccupancyGrid

class RosMapYaml(BaseModel):
    """The fields of a map_server YAML (ROS wiki, map_server): what is read and how it is bounded."""

    model_config = STRICT
    image: Annotated[str, Field(min_length=1)]
    resolution: Annotated[float, Field(ge=1e-4, le=1e3)]
    origin: Annotated[list[Annotated[float, Field(ge=-1e6, le=1e6)]], Field(min_length=2, max_length=3)]
    negate: Literal[0, 1] = 0
    occupied_thresh: Annotated[float, Field(ge=0.0, le=1.0)] = 0.65
    free_thresh: Annotated[float, Field(ge=0.0, le=1.0)] = 0.196
    mode: Literal["trinary", "scale"] = "trinary"


def load_ros_map(yaml_path: str | Path, unknown_is_occupied: bool = True) -> ImageMap:
    """Read a map_server YAML and its image; unknown cells are occupied unless told otherwise."""
    path = Path(yaml_path)
    doc = load_yaml(path, "map YAML")
    meta = validate(RosMapYaml, doc.data, doc, str(path))
    resolution, origin, negate = meta.resolution, meta.origin, bool(meta.negate)
    occ_t, free_t = meta.occupied_thresh, meta.free_thresh
    if len(origin) > 2 and abs(origin[2]) > 1e-12:
        raise DataError("field 'origin': a rotated map (yaw != 0) is not supported", path)
    image = Path(meta.image)
    if not image.is_absolute():
        image = path.parent / image
    grey = read_image(image)
    try:
        return occupancy_from_image(grey, resolution, origin[:2], negate, occ_t, free_t,
                                    unknown_is_occupied, name=path.stem)
    except DataError as exc:
        raise DataError(str(exc), path) from None


def save_ros_map(yaml_path: str | Path, grid: OccupancyGrid, unknown: np.ndarray | None = None) -> Path:
    """Write ``<stem>.pgm`` and the YAML map_server reads back into the same grid."""
    path = Path(yaml_path)
    path.parent.mkdir(parents=True, exist_ok=True)
    pgm = path.with_suffix(".pgm")
    pgm.write_bytes(grid_to_pgm_bytes(grid, unknown))
    meta = {"image": pgm.name, "resolution": grid.resolution_m,
            "origin": [float(grid.origin_xy_m[0]), float(grid.origin_xy_m[1]), 0.0],
            "negate": 0, "occupied_thresh": 0.65, "free_thresh": 0.196}
    path.write_text(yaml.safe_dump(meta, sort_keys=False))
    return path
