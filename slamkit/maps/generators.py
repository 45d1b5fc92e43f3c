"""Seeded generators of indoor occupancy grids: offices (rooms, corridors, doors) and
warehouses (shelf rows, aisles, pallets), and a hall split by a partition with one narrow gap and
one wide door (planning under localisation uncertainty: the short way is tight, the safe way long).

The layouts are structured rather than noise so that planners, localisation and scan matching
meet the geometry they meet indoors: long corridors (aliasing), doorways (narrow passages),
rooms (loop closures) and shelf aisles (repetitive structure). Every random choice goes through
the ``rng`` passed in, so one seed gives one map. Free space is connected by construction (a
spine corridor crosses every room band; warehouse aisles form a grid), which the tests check.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import DataError
from slamkit.maps.occupancy_grid import OccupancyGrid


class _Canvas:
    """Draws axis-aligned rectangles given in metres onto a boolean cell array."""

    def __init__(self, width_m: float, height_m: float, resolution_m: float):
        if width_m <= 0 or height_m <= 0 or resolution_m <= 0:
            raise DataError(f"map size and resolution must be positive, got {width_m} x {height_m} "
                            f"at {resolution_m}")
        self.res = resolution_m
        self.occ = np.zeros((int(round(height_m / resolution_m)), int(round(width_m / resolution_m))),
                            dtype=bool)

    def _cells(self, lo: float, hi: float, n: int) -> slice:
        a = int(np.clip(np.floor(lo / self.res + 1e-9), 0, n))
        b = int(np.clip(np.ceil(hi / self.res - 1e-9), 0, n))
        return slice(a, max(a, b))

    def rect(self, x0: float, y0: float, x1: float, y1: float, value: bool = True) -> None:
        h, w = self.occ.shape
        self.occ[self._cells(min(y0, y1), max(y0, y1), h), self._cells(min(x0, x1), max(x0, x1), w)] = value

    def border(self, t: float) -> None:
        h, w = self.occ.shape
        W, H = w * self.res, h * self.res
        self.rect(0, 0, W, t)
        self.rect(0, H - t, W, H)
        self.rect(0, 0, t, H)
        self.rect(W - t, 0, W, H)


@dataclass(frozen=True)
class OfficeConfig:
    width_m: float = 50.0
    height_m: float = 50.0
    resolution_m: float = 0.05
    wall_thickness_m: float = 0.15
    corridor_width_m: float = 2.0
    room_depth_m: tuple[float, float] = (4.0, 6.0)
    room_width_m: tuple[float, float] = (3.0, 7.0)
    door_width_m: float = 1.0
    #: number of furniture boxes (desks, cabinets) per room, drawn uniformly from this range
    furniture_per_room: tuple[int, int] = (0, 2)
    furniture_size_m: tuple[float, float] = (0.5, 1.2)


@dataclass(frozen=True)
class WarehouseConfig:
    width_m: float = 50.0
    height_m: float = 50.0
    resolution_m: float = 0.05
    wall_thickness_m: float = 0.2
    shelf_depth_m: float = 1.2
    shelf_length_m: float = 10.0
    aisle_width_m: float = 2.5
    cross_aisle_width_m: float = 3.0
    #: depth of the open loading area along the bottom wall
    dock_depth_m: float = 8.0
    num_pallets: int = 12
    pallet_size_m: float = 1.2


def office(rng: np.random.Generator, config: OfficeConfig = OfficeConfig(),
           name: str = "office") -> OccupancyGrid:
    """Bands of rooms along horizontal corridors, one door per room, a vertical spine corridor
    through the middle that connects every corridor, furniture boxes inside rooms."""
    c = config
    cv = _Canvas(c.width_m, c.height_m, c.resolution_m)
    t = c.wall_thickness_m
    W, H = cv.occ.shape[1] * c.resolution_m, cv.occ.shape[0] * c.resolution_m
    cv.border(t)
    spine = (W / 2 - c.corridor_width_m / 2, W / 2 + c.corridor_width_m / 2)
    rooms: list[tuple[float, float, float, float]] = []
    y = t
    while True:
        d1 = rng.uniform(*c.room_depth_m)
        d2 = rng.uniform(*c.room_depth_m)
        if y + d1 + c.corridor_width_m + d2 + 2 * t > H - t:
            break
        band1 = (y, y + d1)
        corridor = (band1[1] + t, band1[1] + t + c.corridor_width_m)
        band2 = (corridor[1] + t, corridor[1] + t + d2)
        # walls between the room bands and the corridor, and after the second band
        cv.rect(t, band1[1], W - t, band1[1] + t)
        cv.rect(t, corridor[1], W - t, corridor[1] + t)
        cv.rect(t, band2[1], W - t, band2[1] + t)
        for (b0, b1), door_wall in ((band1, band1[1]), (band2, corridor[1])):
            x = t
            while x < W - t - 1e-9:
                rw = rng.uniform(*c.room_width_m)
                if W - t - (x + rw) < c.room_width_m[0]:
                    rw = W - t - x  # the last room takes what is left
                x1 = x + rw
                if x1 < W - t - 1e-9:
                    cv.rect(x1, b0, x1 + t, b1)  # wall to the next room
                if x1 - x > c.door_width_m + 0.2:
                    dx = rng.uniform(x + 0.1, x1 - 0.1 - c.door_width_m)
                    cv.rect(dx, door_wall, dx + c.door_width_m, door_wall + t, value=False)
                rooms.append((x, b0, x1, b1))
                x = x1 + t
        y = band2[1] + t
    for (x0, y0, x1, y1) in rooms:
        for _ in range(int(rng.integers(c.furniture_per_room[0], c.furniture_per_room[1] + 1))):
            fw, fh = rng.uniform(*c.furniture_size_m, size=2)
            # furniture keeps 0.8 m from walls so it never closes a doorway or a room
            if x1 - x0 < fw + 1.6 or y1 - y0 < fh + 1.6:
                continue
            fx = rng.uniform(x0 + 0.8, x1 - 0.8 - fw)
            fy = rng.uniform(y0 + 0.8, y1 - 0.8 - fh)
            if fx + fw > spine[0] - 0.8 and fx < spine[1] + 0.8:
                continue  # keep the spine corridor clear
            cv.rect(fx, fy, fx + fw, fy + fh)
    # the spine corridor cuts every band and wall so all corridors are connected
    cv.rect(spine[0], t, spine[1], H - t, value=False)
    return OccupancyGrid(cv.occ, c.resolution_m, np.zeros(2), name=name)


def warehouse(rng: np.random.Generator, config: WarehouseConfig = WarehouseConfig(),
              name: str = "warehouse") -> OccupancyGrid:
    """Columns of shelf blocks separated by aisles, cross aisles between blocks, an open loading
    dock along the bottom wall with pallets scattered on it."""
    c = config
    cv = _Canvas(c.width_m, c.height_m, c.resolution_m)
    t = c.wall_thickness_m
    W, H = cv.occ.shape[1] * c.resolution_m, cv.occ.shape[0] * c.resolution_m
    cv.border(t)
    y_lo = t + c.dock_depth_m
    y_hi = H - t - c.cross_aisle_width_m
    x = t + c.aisle_width_m
    while x + c.shelf_depth_m <= W - t - c.aisle_width_m:
        y = y_lo
        while True:
            # shelf blocks vary a little in length, so aisles do not all look alike
            length = c.shelf_length_m * rng.uniform(0.7, 1.0)
            if y + length > y_hi:
                break
            cv.rect(x, y, x + c.shelf_depth_m, y + length)
            y += length + c.cross_aisle_width_m
        x += c.shelf_depth_m + c.aisle_width_m
    for _ in range(c.num_pallets):
        px = rng.uniform(t + 1.0, W - t - 1.0 - c.pallet_size_m)
        py = rng.uniform(t + 1.0, y_lo - 1.0 - c.pallet_size_m)
        cv.rect(px, py, px + c.pallet_size_m, py + c.pallet_size_m)
    return OccupancyGrid(cv.occ, c.resolution_m, np.zeros(2), name=name)


@dataclass(frozen=True)
class PassageHallConfig:
    width_m: float = 12.0
    height_m: float = 6.0
    resolution_m: float = 0.05
    wall_thickness_m: float = 0.15
    #: the gap in the partition (x = width / 2), centred at a height drawn in ``narrow_y_m``;
    #: a whole number of cells, so its width is exact
    narrow_width_m: float = 0.55
    narrow_y_m: tuple[float, float] = (2.2, 3.8)
    #: the door at the end of the partition farther from the gap
    wide_width_m: float = 1.2


def passage_hall(rng: np.random.Generator, config: PassageHallConfig = PassageHallConfig(),
                 name: str = "passage") -> OccupancyGrid:
    """A hall split across by a partition wall with a narrow gap near the middle and a wide door
    near the end farther from it: a robot going from one side to the other either threads the
    gap or detours through the door (about 2 |y_door - y_gap| longer)."""
    c = config
    cells = c.narrow_width_m / c.resolution_m
    if abs(cells - round(cells)) > 1e-6 or not 0 < c.narrow_width_m < c.wide_width_m:
        raise DataError(f"PassageHallConfig.narrow_width_m must be a whole number of cells below wide_width_m, "
                        f"got {c.narrow_width_m}")
    cv = _Canvas(c.width_m, c.height_m, c.resolution_m)
    t = c.wall_thickness_m
    W, H = cv.occ.shape[1] * c.resolution_m, cv.occ.shape[0] * c.resolution_m
    cv.border(t)
    x0 = round((W / 2 - t / 2) / c.resolution_m) * c.resolution_m
    cv.rect(x0, 0, x0 + t, H)
    y_lo = round((rng.uniform(*c.narrow_y_m) - c.narrow_width_m / 2) / c.resolution_m) * c.resolution_m
    cv.rect(x0, y_lo, x0 + t, y_lo + c.narrow_width_m, value=False)
    door = (t + 0.2, t + 0.2 + c.wide_width_m)
    if y_lo + c.narrow_width_m / 2 < H / 2:
        door = (H - door[1], H - door[0])
    cv.rect(x0, door[0], x0 + t, door[1], value=False)
    return OccupancyGrid(cv.occ, c.resolution_m, np.zeros(2), name=name)


def random_free_poses(grid: OccupancyGrid, rng: np.random.Generator, n: int,
                      clearance_m: float = 0.0) -> np.ndarray:
    """(n, 3) poses at uniformly drawn free cell centres at least ``clearance_m`` from obstacles
    (centre to centre), headings uniform in [-pi, pi)."""
    from slamkit.maps.distance_field import distance_field_m

    ok = distance_field_m(grid) > clearance_m
    iy, ix = np.nonzero(ok)
    if len(iy) == 0:
        raise DataError(f"no free cell with clearance {clearance_m} m in grid {grid.name!r}")
    pick = rng.integers(0, len(iy), size=n)
    xy = grid.cell_to_world(np.column_stack([ix[pick], iy[pick]]))
    return np.column_stack([xy, rng.uniform(-np.pi, np.pi, size=n)])
