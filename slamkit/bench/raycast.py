"""``slamkit bench raycast``: beams per second of the vectorised ray caster on 1000 x 1000
grids, against the per-beam Python Amanatides-Woo loop (:func:`cast_ray_loop`) timed in the
same run on a subset of the same beams (the loop returns bit-identical ranges, which is checked
here as well, so the ratio compares equal work).

Worlds: a generated office and warehouse (0.05 m cells, 50 m x 50 m), the simulator's use
case, and a uniformly cluttered grid (0.2% random occupied cells), the worst case for the
distance-field leaps. 360-beam scans with 30 m range from random free poses.

``path`` says which walk ran: the compiled one (``native``) or the numpy fallback
(``SLAMKIT_NO_NATIVE=1`` or no C compiler). ``distance_field_build_ms`` is the time to construct
the RayCaster: only the numpy walk needs the distance field, so with the compiled walk it is
close to 0.
"""

from __future__ import annotations

import numpy as np

from slamkit.maps.generators import office, random_free_poses, warehouse
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.maps.raycast import RayCaster, cast_ray_loop
from slamkit.bench.cases import BenchCase, best_of, compare


def _clutter(rng: np.random.Generator) -> OccupancyGrid:
    occ = rng.random((1000, 1000)) < 0.002
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    return OccupancyGrid(occ, 0.05, name="clutter")


def run(quick: bool = False) -> list[BenchCase]:
    rng = np.random.default_rng(0)
    num_poses = 20 if quick else 100
    num_loop = 300 if quick else 2000
    beams = np.linspace(-np.pi, np.pi, 360, endpoint=False)
    max_range_m = 30.0
    cases = []
    for grid in (office(rng), warehouse(rng), _clutter(rng)):
        poses = random_free_poses(grid, rng, num_poses, clearance_m=0.3)
        build_s, caster = best_of(lambda: RayCaster(grid), repeat=3)
        vec_s, ranges = best_of(lambda: caster.scan(poses, beams, max_range_m), repeat=5)
        origins = np.repeat(poses[:, :2], len(beams), axis=0)
        angles = (poses[:, 2:3] + beams).reshape(-1)
        pick = rng.choice(len(origins), size=num_loop, replace=False)

        def loop():
            return [cast_ray_loop(grid, origins[i], angles[i], max_range_m) for i in pick]

        loop_s, loop_ranges = best_of(loop, repeat=3)
        identical = bool(np.array_equal(np.asarray(loop_ranges), ranges.reshape(-1)[pick],
                                        equal_nan=True))
        cases.append(compare(
            f"raycast_{grid.name}_1000x1000", ranges.size / vec_s, "beams/s",
            "per-beam python Amanatides-Woo loop", num_loop / loop_s, goal=">= 30",
            higher_is_better=True, identical_to_reference=identical,
            # "native" (the compiled walk, _raycast.c) or "numpy" (the vectorised fallback)
            path=caster.last_path,
            distance_field_build_ms=round(build_s * 1e3, 2),
            mean_range_m=round(float(np.nanmean(ranges)), 3),
            no_hit_fraction=round(float(np.mean(np.isnan(ranges))), 4)))
    return cases
