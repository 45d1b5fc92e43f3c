"""ROS ``map_server`` map files: a YAML (image, resolution, origin, negate, occupied_thresh,
free_thresh, optional mode) next to a PGM or PNG image. The YAML is read here (sim may import
yaml); the image decoding and the pixel rule live in :mod:`slamkit.maps.image_map`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from slamkit.errors import DataError
from slamkit.data.formats.image import read_image
from slamkit.maps.image_map import ImageMap, grid_to_pgm_bytes, occupancy_from_image
from slamkit.maps.occupancy_grid import OccupancyGrid

_REQUIRED = ("image", "resolution", "origin")


def load_ros_map(yaml_path: str | Path, unknown_is_occupied: bool = True) -> ImageMap:
    """Read a map_server YAML and its image; unknown cells are occupied unless told otherwise."""
    path = Path(yaml_path)
    try:
        meta = yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise DataError("no such map YAML", path) from None
    except yaml.YAMLError as exc:
        raise DataError(f"not valid YAML: {exc}", path) from None
    if not isinstance(meta, dict):
        raise DataError("map YAML must be a mapping", path)
    for key in _REQUIRED:
        if key not in meta:
            raise DataError(f"map YAML is missing field {key!r}", path)
    mode = meta.get("mode", "trinary")
    if mode not in ("trinary", "scale"):
        raise DataError(f"field 'mode': {mode!r} is not supported (trinary, scale)", path)
    try:
        resolution = float(meta["resolution"])
        origin = [float(v) for v in meta["origin"]]
        negate = bool(int(meta.get("negate", 0)))
        occ_t = float(meta.get("occupied_thresh", 0.65))
        free_t = float(meta.get("free_thresh", 0.196))
    except (TypeError, ValueError) as exc:
        raise DataError(f"bad numeric field: {exc}", path) from None
    if len(origin) < 2 or not resolution > 0:
        raise DataError(f"field 'origin' needs [x, y, yaw] and 'resolution' > 0, got {origin}, {resolution}", path)
    if len(origin) > 2 and abs(origin[2]) > 1e-12:
        raise DataError("field 'origin': a rotated map (yaw != 0) is not supported", path)
    image = Path(meta["image"])
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
