"""Occupancy grids from images, as ROS ``map_server`` reads them.

Pixel to occupancy (ROS ``map_server`` / ``nav2_map_server`` "trinary" mode, documented at
wiki.ros.org/map_server): with the pixel's brightness v in 0..255 (the mean of the colour
channels), p = (255 - v) / 255, or v / 255 when ``negate`` is set; p > ``occupied_thresh`` is
occupied, p < ``free_thresh`` is free, anything between is unknown. The image's top row is the
largest y: row r of an H-row image becomes ``occupied[H - 1 - r]`` so that cell (0, 0) sits at
``origin`` (the lower-left corner), as in ROS.

Image files are decoded by :func:`slamkit.data.formats.image.read_image` (Pillow, with a pixel
limit checked before decoding): a file format is not an algorithm package's business. The YAML
side lives in :mod:`slamkit.sim.ros_map` (algorithm packages do not import yaml).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slamkit.errors import DataError
from slamkit.maps.occupancy_grid import OccupancyGrid


@dataclass(frozen=True)
class ImageMap:
    """The grid (unknown cells counted as occupied or free as asked) and the unknown mask."""

    grid: OccupancyGrid
    unknown: np.ndarray


def occupancy_from_image(grey: np.ndarray, resolution_m: float, origin_xy_m=(0.0, 0.0),
                         negate: bool = False, occupied_thresh: float = 0.65,
                         free_thresh: float = 0.196, unknown_is_occupied: bool = True,
                         name: str = "map") -> ImageMap:
    """ROS map_server trinary interpretation of a grey image (rows top to bottom)."""
    g = np.asarray(grey, dtype=float)
    if g.ndim != 2:
        raise DataError(f"map image must be 2D grey levels, got shape {g.shape}")
    if not 0.0 <= free_thresh <= occupied_thresh <= 1.0:
        raise DataError(f"need 0 <= free_thresh <= occupied_thresh <= 1, got {free_thresh}, {occupied_thresh}")
    p = g / 255.0 if negate else (255.0 - g) / 255.0
    p = p[::-1]  # first image row is the top of the map
    occupied = p > occupied_thresh
    free = p < free_thresh
    unknown = ~occupied & ~free
    cells = occupied | unknown if unknown_is_occupied else occupied
    unknown.setflags(write=False)
    return ImageMap(OccupancyGrid(cells, resolution_m, np.asarray(origin_xy_m, float)[:2], name=name), unknown)


def grid_to_pgm_bytes(grid: OccupancyGrid, unknown: np.ndarray | None = None) -> bytes:
    """P5 PGM as map_server's map_saver writes it: occupied 0, free 254, unknown 205."""
    pixels = np.where(grid.occupied, 0, 254).astype(np.uint8)
    if unknown is not None:
        pixels[np.asarray(unknown, bool) & ~grid.occupied] = 205  # a known obstacle stays one
    pixels = pixels[::-1]
    return b"P5\n%d %d\n255\n" % (grid.width, grid.height) + pixels.tobytes()
