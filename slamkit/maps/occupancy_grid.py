"""Occupancy grids: the map type shared by the simulator, planners, controllers and mapping.

Convention: ``occupied[iy, ix]``; cell (iy, ix) covers world x in
``origin_xy_m[0] + ix * resolution_m + [0, resolution_m)`` and likewise y. So a MovingAI map
loaded with one file line per row has x = column, y = line number, exactly as its ``.scen``
files count them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from slamkit.errors import DataError


@dataclass(frozen=True)
class OccupancyGrid:
    occupied: np.ndarray
    resolution_m: float = 1.0
    # default_factory: a shared ndarray default is rejected by dataclasses (unhashable)
    origin_xy_m: np.ndarray = field(default_factory=lambda: np.zeros(2))
    name: str = "grid"

    def __post_init__(self) -> None:
        occ = np.asarray(self.occupied, dtype=bool)
        if occ.ndim != 2 or occ.size == 0:
            raise DataError(f"occupancy grid must be a non-empty 2D array, got shape {occ.shape}")
        if not (self.resolution_m > 0 and np.isfinite(self.resolution_m)):
            raise DataError(f"resolution_m must be positive, got {self.resolution_m}")
        origin = np.asarray(self.origin_xy_m, dtype=float).reshape(2)
        occ = occ.copy()
        occ.setflags(write=False)
        origin.setflags(write=False)
        object.__setattr__(self, "occupied", occ)
        object.__setattr__(self, "origin_xy_m", origin)
        object.__setattr__(self, "resolution_m", float(self.resolution_m))

    @property
    def shape(self) -> tuple[int, int]:
        return self.occupied.shape  # (height, width)

    @property
    def width(self) -> int:
        return self.occupied.shape[1]

    @property
    def height(self) -> int:
        return self.occupied.shape[0]

    def world_to_cell(self, world_xy_m: np.ndarray) -> np.ndarray:
        """(N, 2) world points -> (N, 2) integer (ix, iy); may lie outside the grid."""
        xy = np.asarray(world_xy_m, dtype=float).reshape(-1, 2)
        return np.floor((xy - self.origin_xy_m) / self.resolution_m).astype(np.int64)

    def cell_to_world(self, cell_ixy: np.ndarray) -> np.ndarray:
        """(N, 2) integer (ix, iy) -> (N, 2) world coordinates of the cell centres."""
        c = np.asarray(cell_ixy, dtype=float).reshape(-1, 2)
        return self.origin_xy_m + (c + 0.5) * self.resolution_m

    def in_bounds(self, cell_ixy: np.ndarray) -> np.ndarray:
        c = np.asarray(cell_ixy).reshape(-1, 2)
        return (c[:, 0] >= 0) & (c[:, 0] < self.width) & (c[:, 1] >= 0) & (c[:, 1] < self.height)

    def is_free_world(self, world_xy_m: np.ndarray) -> np.ndarray:
        """(N,) True where the point is inside the grid and its cell is free."""
        c = self.world_to_cell(world_xy_m)
        ok = self.in_bounds(c)
        out = np.zeros(len(c), dtype=bool)
        out[ok] = ~self.occupied[c[ok, 1], c[ok, 0]]
        return out


def wall_face_points(grid: OccupancyGrid) -> np.ndarray:
    """(N, 2) world points at the mid-point of every occupied cell face that borders a free cell
    (the grid's border counts as free)."""
    occ = np.pad(grid.occupied, 1, constant_values=False)
    core = occ[1:-1, 1:-1]
    out = []
    for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)):
        free_nb = ~occ[1 + dy:occ.shape[0] - 1 + dy, 1 + dx:occ.shape[1] - 1 + dx]
        iy, ix = np.nonzero(core & free_nb)
        centres = grid.cell_to_world(np.column_stack([ix, iy]))
        out.append(centres + 0.5 * grid.resolution_m * np.array([dx, dy], dtype=float))
    return np.concatenate(out)
