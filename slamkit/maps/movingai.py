"""MovingAI grid-pathfinding benchmark files: ``.map`` grids and ``.map.scen`` scenarios.

Format (Sturtevant, "Benchmarks for Grid-Based Pathfinding", IEEE TCIAIG 4(2), 2012;
https://movingai.com/benchmarks/formats.html)::

    type octile
    height H
    width W
    map
    <H lines of W characters>

Passable terrain is '.', 'G' and 'S'; '@', 'O', 'T' and 'W' are blocked. Row ``y`` of the file
is grid row ``iy = y`` and column ``x`` is ``ix = x``, so the scenario coordinates index
:class:`~slamkit.maps.occupancy_grid.OccupancyGrid` cells directly (resolution 1, origin 0:
cell (x, y) has its centre at world (x + 0.5, y + 0.5)).

Scenario lines (``version 1``, tab-separated)::

    bucket  map  width  height  start_x  start_y  goal_x  goal_y  optimal_length

``optimal_length`` is the published optimum for 8-connected moves costing 1 and sqrt(2) with
no corner cutting; older files print 5 decimals, newer ones 8 (``decimals`` records which, so
tests can pick the tolerance).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slamkit._text import parse_int, parse_number, read_lines
from slamkit.errors import DataError
from slamkit.maps.occupancy_grid import OccupancyGrid

PASSABLE = b".GS"
BLOCKED = b"@OTW"


@dataclass(frozen=True)
class Scenario:
    bucket: int
    map_name: str
    width: int
    height: int
    start_ixy: tuple[int, int]
    goal_ixy: tuple[int, int]
    optimal_length: float
    decimals: int          # digits after the decimal point in the file (precision of the optimum)
    line: int              # one-based line in the .scen file


def _lines(path: Path) -> list[str]:
    # the shared line rule handles the CRLF endings of the street maps
    return read_lines(path, encoding="ascii")


def load_map(path: str | Path) -> OccupancyGrid:
    """Read a MovingAI ``.map`` file into an OccupancyGrid (occupied = blocked terrain)."""
    path = Path(path)
    lines = _lines(path)
    header: dict[str, str] = {}
    i = 0
    while i < len(lines) and lines[i].strip() != "map":
        parts = lines[i].split()
        if len(parts) != 2 or parts[0] not in ("type", "height", "width"):
            raise DataError(f"expected 'type', 'height', 'width' or 'map' header, got {lines[i]!r}",
                            path, i + 1)
        header[parts[0]] = parts[1]
        i += 1
    if i == len(lines):
        raise DataError("missing 'map' line", path, len(lines))
    for key in ("height", "width"):
        if key not in header:
            raise DataError(f"missing '{key}' header", path, i + 1)
    if not all(header[k].isascii() and header[k].isdigit() for k in ("height", "width")):
        raise DataError(f"height/width must be integers, got {header['height']!r}, {header['width']!r}",
                        path, i)
    height, width = int(header["height"]), int(header["width"])
    if height <= 0 or width <= 0:
        raise DataError(f"height and width must be positive, got {height} x {width}", path, i)
    rows = lines[i + 1:i + 1 + height]
    if len(rows) < height:
        raise DataError(f"expected {height} map rows, found {len(rows)}", path, len(lines))
    for r, row in enumerate(rows):
        if len(row) != width:
            raise DataError(f"map row has {len(row)} characters, expected {width}", path, i + 2 + r)
    chars = np.frombuffer("".join(rows).encode("ascii"), dtype=np.uint8).reshape(height, width)
    passable = np.isin(chars, np.frombuffer(PASSABLE, dtype=np.uint8))
    blocked = np.isin(chars, np.frombuffer(BLOCKED, dtype=np.uint8))
    bad = ~(passable | blocked)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise DataError(f"unknown terrain {chr(chars[r, c])!r} at column {c}", path, i + 2 + int(r))
    for extra in lines[i + 1 + height:]:
        if extra.strip():
            raise DataError("unexpected text after the last map row", path, i + 2 + height)
    return OccupancyGrid(blocked, resolution_m=1.0, origin_xy_m=np.zeros(2), name=path.name.removesuffix(".map"))


def load_scenarios(path: str | Path) -> list[Scenario]:
    """Read a MovingAI ``.scen`` file (version 1)."""
    path = Path(path)
    lines = _lines(path)
    if not lines or lines[0].split() not in (["version", "1"], ["version", "1.0"]):
        raise DataError(f"expected 'version 1' on the first line, got {lines[0] if lines else ''!r}", path, 1)
    out: list[Scenario] = []
    for n, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        parts = line.split("\t") if "\t" in line else line.split()
        parts = [p.strip() for p in parts]
        if len(parts) != 9:
            raise DataError(f"expected 9 fields (bucket map width height sx sy gx gy length), "
                            f"got {len(parts)}", path, n)
        names = {0: "bucket", 2: "width", 3: "height", 4: "start_x", 5: "start_y", 6: "goal_x", 7: "goal_y"}
        bucket, w, h, sx, sy, gx, gy = (parse_int(parts[k], f"field {names[k]}", path, n) for k in names)
        length = parse_number(parts[8], "field optimal_length", path, n)
        if not (0 <= sx < w and 0 <= gx < w and 0 <= sy < h and 0 <= gy < h):
            raise DataError(f"start ({sx}, {sy}) or goal ({gx}, {gy}) outside the {w} x {h} map", path, n)
        if not (np.isfinite(length) and length >= 0):
            raise DataError(f"optimal length must be finite and >= 0, got {parts[8]}", path, n)
        decimals = len(parts[8].split(".", 1)[1]) if "." in parts[8] else 0
        out.append(Scenario(bucket, parts[1], w, h, (sx, sy), (gx, gy), length, decimals, n))
    return out


def scenario_problem_points(grid: OccupancyGrid, scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """World (x, y) of the start and goal cell centres of a scenario on its map."""
    pts = grid.cell_to_world(np.array([scenario.start_ixy, scenario.goal_ixy]))
    return pts[0], pts[1]
