"""``slamkit bench scan-matching``: 2D ICP per scan pair (360 beams) against a naive
nearest-neighbour ICP written as a Python loop, timed in the same run on the same scan pairs.

Both run point-to-point ICP with the same gate, the same number of iterations (fixed, no early
stop, so the work is equal) and the same SVD step; they differ only in how correspondences are
found: slamkit's KD-tree query vectorised over the scan (``scipy.spatial.cKDTree``) against an
O(N M) double loop over source and target points in Python (the textbook formulation). The
reference is run on fewer pairs in quick mode; times are per scan pair. The two results are
checked to agree (same correspondences, same transform) so the ratio compares equal work.

The heading search before lidar-only ICP (``rotation_search``: +-10 deg, coarse then fine) scores
every heading's points with one batched KD-tree query, timed against a query per heading (the
previous implementation, ``rotation_search_per_heading``) on the same pairs; same result checked.

The global matcher of loop closure (``slamkit.frontend.branch_and_bound``) is timed against the
exhaustive search of the same window in the same run: a scan from a pose 1-1.5 m and 10-15 deg
off the guess, matched against the map of a scan from the guess's neighbourhood over +-2 m x
+-20 deg (81 x 81 cells, 41 headings at 1 deg); both must return the same pose and score (the
branch and bound is exact), and the ratio is the time the pruning saves. The same branch and
bound is also timed with its descent in Python (``SLAMKIT_NO_NATIVE=1``) against the compiled
kernel (``_bnbkernel.c``): same optimum, score and nodes scored; the ratio is the kernel's gain.

The lidar SLAM frontend's match (point-to-line, the logs pipeline's gate 0.5 m, trim 0.9, tolerances
1e-4, against a submap of 8 stacked scans) is timed in the compiled kernel (``_icpkernel.c``: k-d
tree, correspondences, trimming and the Gauss-Newton loop in C) against the numpy loop with
scipy's cKDTree (``SLAMKIT_NO_NATIVE=1``) on the same prepared targets: same iterations and
correspondences checked, the pose difference reported. Preparing such a target (tree and PCA
normals) is timed the same way.
"""

from __future__ import annotations

import os
from contextlib import contextmanager

import numpy as np

from slamkit.frontend import branch_and_bound as bnb_mod
from slamkit.frontend import icp as icp_mod
from slamkit.frontend.branch_and_bound import (BranchAndBoundConfig, MaxGridPyramid, branch_and_bound_search,
                                               exhaustive_search)
from slamkit.frontend.icp import IcpConfig, IcpTarget, _best_rigid, icp, rotation_search, scan_to_points
from slamkit.geometry import se2
from slamkit.maps.generators import office, random_free_poses
from slamkit.maps.raycast import RayCaster
from slamkit.bench.cases import BenchCase, best_of, compare


def naive_icp(source: np.ndarray, target: np.ndarray, initial: np.ndarray, iterations: int,
              max_correspondence_m: float) -> np.ndarray:
    """Point-to-point ICP with a Python nearest-neighbour loop (the reference)."""
    T = np.asarray(initial, float).copy()
    gate2 = max_correspondence_m ** 2
    tgt = target.tolist()
    for _ in range(iterations):
        moved = se2.transform_points(T, source)
        src_i, tgt_i = [], []
        for i, (px, py) in enumerate(moved.tolist()):
            best, best_j = float("inf"), -1
            for j, (qx, qy) in enumerate(tgt):
                d = (px - qx) ** 2 + (py - qy) ** 2
                if d < best:
                    best, best_j = d, j
            if best <= gate2:
                src_i.append(i)
                tgt_i.append(best_j)
        if len(src_i) < 3:
            break
        delta = _best_rigid(moved[src_i], target[tgt_i])
        T = se2.compose(delta, T)
    return T


def rotation_search_per_heading(source_xy: np.ndarray, target: IcpTarget, guess: np.ndarray,
                                half_window_rad: float, step_rad: float = float(np.deg2rad(0.5)),
                                cap_m: float = 0.3) -> tuple[np.ndarray, float]:
    """``slamkit.frontend.icp.rotation_search`` as it was: one KD-tree query and one mean per
    heading (the reference of the batched one)."""
    g = np.asarray(guess, dtype=float).reshape(3)

    def best(offsets: np.ndarray) -> tuple[float, float]:
        scores = []
        for d in offsets:
            dist, _ = target.tree.query(se2.transform_points(g + np.array([0.0, 0.0, d]), source_xy), k=1,
                                        distance_upper_bound=cap_m)
            scores.append(np.mean(np.minimum(dist, cap_m) ** 2))
        k = int(np.argmin(scores))
        return float(offsets[k]), float(scores[k])

    coarse, _ = best(np.arange(-half_window_rad, half_window_rad + 1e-12, 4 * step_rad))
    fine, score = best(coarse + np.arange(-3, 4) * step_rad)
    return g + np.array([0.0, 0.0, fine]), score


def run(quick: bool = False) -> list[BenchCase]:
    rng = np.random.default_rng(0)
    grid = office(rng)
    caster = RayCaster(grid)
    beams = np.linspace(-np.pi, np.pi, 360, endpoint=False)
    n_pairs = 3 if quick else 20
    n_ref = 1 if quick else 3
    iterations = 10
    poses = random_free_poses(grid, rng, n_pairs, clearance_m=0.5)
    offsets = np.column_stack([rng.normal(0, 0.2, n_pairs), rng.normal(0, 0.2, n_pairs),
                               rng.normal(0, 0.05, n_pairs)])
    pairs = []
    for pose, off in zip(poses, offsets):
        r0 = caster.scan(pose, beams, 20.0)[0] + rng.normal(0, 0.02, 360)
        r1 = caster.scan(se2.compose(pose, off), beams, 20.0)[0] + rng.normal(0, 0.02, 360)
        pairs.append((scan_to_points(r1, beams), scan_to_points(r0, beams)))
    cfg = IcpConfig(method="point_to_point", max_iterations=iterations, translation_tol_m=0.0,
                    rotation_tol_rad=0.0, trim_fraction=1.0, max_correspondence_m=1.0)

    def fast():
        return [icp(s, t, np.zeros(3), cfg).target_T_source for s, t in pairs]

    def slow():
        return [naive_icp(s, t, np.zeros(3), iterations, 1.0) for s, t in pairs[:n_ref]]

    fast_s, fast_T = best_of(fast, repeat=3)
    slow_s, slow_T = best_of(slow, repeat=1)
    agree = float(max(np.max(np.abs(a - b)) for a, b in zip(fast_T, slow_T)))
    cfg_pl = IcpConfig(method="point_to_line")
    pl_s, _ = best_of(lambda: [icp(s, t, np.zeros(3), cfg_pl) for s, t in pairs], repeat=3)
    # the heading search before lidar-only ICP (+-10 deg, 0.5 deg steps): one batched query
    # against a query per heading (the previous implementation), same result
    targets = [IcpTarget(t, 6) for _, t in pairs]
    window = np.deg2rad(10.0)
    rot_s, rot = best_of(lambda: [rotation_search(s, t, np.zeros(3), window) for (s, _), t in zip(pairs, targets)],
                         repeat=3)
    ref_s, ref = best_of(lambda: [rotation_search_per_heading(s, t, np.zeros(3), window)
                                  for (s, _), t in zip(pairs, targets)], repeat=3)
    same_rot = all(np.array_equal(a[0], b[0]) and a[1] == b[1] for a, b in zip(rot, ref))
    return [
        compare("icp2d_point_to_point_360_beams", 1e3 * fast_s / len(pairs), "ms",
                "naive nearest-neighbour python loop, same iterations", 1e3 * slow_s / n_ref,
                goal=">= 10", iterations=iterations, pairs=len(pairs), max_abs_difference=agree),
        BenchCase("icp2d_point_to_line_360_beams_to_convergence", 1e3 * pl_s / len(pairs), "ms",
                  extra={"pairs": len(pairs)}),
        compare("icp_rotation_search_10deg", 1e3 * rot_s / len(pairs), "ms",
                "a KD-tree query per heading (the previous rotation_search)", 1e3 * ref_s / len(pairs),
                goal=">= 1.2", pairs=len(pairs), same_result=bool(same_rot)),
    ] + submap_icp_cases(caster, poses, beams, rng, quick) + global_match_cases(grid, caster, beams, rng, quick)


def submap_icp_cases(caster, poses, beams, rng, quick: bool) -> list[BenchCase]:
    """The frontend's point-to-line match against an 8-scan submap and the preparation of that
    submap, compiled kernel against the numpy/cKDTree reference (module docstring)."""
    n = 3 if quick else len(poses)
    cfg = IcpConfig(method="point_to_line", max_correspondence_m=0.5, trim_fraction=0.9, max_iterations=30,
                    translation_tol_m=1e-4, rotation_tol_rad=1e-4)
    submaps, sources = [], []
    for pose in poses[:n]:
        # 8 scans 5 cm / 1 deg apart, stacked in the first one's frame, as the frontend's submap
        scans = []
        for i in range(8):
            step = np.array([0.05 * i, 0.0, np.deg2rad(1.0) * i])
            r = caster.scan(se2.compose(pose, step), beams, 20.0)[0] + rng.normal(0, 0.02, len(beams))
            scans.append(se2.transform_points(step, scan_to_points(r, beams)))
        submaps.append(np.vstack(scans))
        off = np.array([rng.normal(0.45, 0.05), rng.normal(0, 0.05), rng.normal(0.15, 0.02)])
        r = caster.scan(se2.compose(pose, off), beams, 20.0)[0] + rng.normal(0, 0.02, len(beams))
        # the guess a few cm / 1 deg off the truth (the odometry's error)
        sources.append((scan_to_points(r, beams), off + np.array([0.03, -0.02, 0.017])))
    compiled = icp_mod._kernel() is not None
    prep_s, targets = best_of(lambda: [IcpTarget(m, cfg.normal_neighbours) for m in submaps], repeat=3)
    with _no_native():
        prep_py_s, _ = best_of(lambda: [IcpTarget(m, cfg.normal_neighbours) for m in submaps], repeat=3)

    def match():
        return [icp(s, t, g, cfg) for (s, g), t in zip(sources, targets)]

    icp_s, fast = best_of(match, repeat=3)
    for t in targets:  # the reference's cKDTree, built outside the timing as the targets are
        t.tree
    with _no_native():
        py_s, ref = best_of(match, repeat=3)
    same = all(a.iterations == b.iterations and a.num_correspondences == b.num_correspondences
               and a.fitness == b.fitness for a, b in zip(fast, ref))
    diff = float(max(np.max(np.abs(a.target_T_source - b.target_T_source)) for a, b in zip(fast, ref)))
    return [compare("icp_point_to_line_submap_compiled", 1e3 * icp_s / n, "ms",
                    "the numpy loop with scipy's cKDTree (SLAMKIT_NO_NATIVE=1), same targets", 1e3 * py_s / n,
                    goal=">= 4", pairs=n, compiled=compiled, same_iterations_and_correspondences=bool(same),
                    max_abs_difference=diff, iterations_mean=float(np.mean([r.iterations for r in fast]))),
            compare("icp_submap_target_compiled", 1e3 * prep_s / n, "ms",
                    "scipy cKDTree and numpy PCA normals (SLAMKIT_NO_NATIVE=1)", 1e3 * prep_py_s / n,
                    goal=">= 1.5", targets=n, points_mean=float(np.mean([len(m) for m in submaps])))]


def global_match_cases(grid, caster, beams, rng, quick: bool) -> list[BenchCase]:
    """Branch and bound against the exhaustive search of the same window (module docstring)."""
    n = 2 if quick else 6
    cfg = BranchAndBoundConfig(window_xy_m=2.0, window_theta_rad=np.deg2rad(20.0), theta_step_rad=np.deg2rad(1.0),
                               depth=6, min_score=0.3)
    problems = []
    for pose in random_free_poses(grid, rng, n, clearance_m=1.0):
        r0 = caster.scan(pose, beams, 20.0)[0] + rng.normal(0, 0.02, len(beams))
        off = np.array([rng.choice([-1, 1]) * rng.uniform(0.7, 1.1), rng.choice([-1, 1]) * rng.uniform(0.7, 1.1),
                        rng.choice([-1, 1]) * np.deg2rad(rng.uniform(10, 15))])
        r1 = caster.scan(se2.compose(pose, off), beams, 20.0)[0] + rng.normal(0, 0.02, len(beams))
        target = MaxGridPyramid(scan_to_points(r0, beams), cfg)
        problems.append((scan_to_points(r1, beams), target))

    def bnb():
        return [branch_and_bound_search(s, t, np.zeros(3)) for s, t in problems]

    def full():
        return [exhaustive_search(s, t, np.zeros(3)) for s, t in problems]

    bnb_s, fast = best_of(bnb, repeat=3)
    full_s, slow = best_of(full, repeat=1)
    # the same branch and bound with the descent in Python (SLAMKIT_NO_NATIVE=1): the compiled
    # kernel's gain, same nodes scored
    compiled = bnb_mod._kernel() is not None
    with _no_native():
        py_s, py = best_of(bnb, repeat=1 if quick else 2)
    same_py = all((a is None and b is None) or (a is not None and b is not None and a.score == b.score
                                               and a.candidates_scored == b.candidates_scored
                                               and np.array_equal(a.target_T_source, b.target_T_source))
                  for a, b in zip(fast, py))
    same = all((a is None and b is None) or (a is not None and b is not None and a.score == b.score
                                            and np.array_equal(a.target_T_source, b.target_T_source))
               for a, b in zip(fast, slow))
    scored = [r.candidates_scored for r in fast if r is not None]
    return [compare("global_match_bnb_window_2m_20deg", 1e3 * bnb_s / n, "ms",
                    "exhaustive search of the same window (81 x 81 cells x 41 headings)", 1e3 * full_s / n,
                    goal=">= 10", problems=n, same_optimum=bool(same),
                    nodes_scored_mean=float(np.mean(scored)) if scored else 0.0,
                    candidates_in_window=81 * 81 * 41),
            compare("global_match_bnb_compiled_descent", 1e3 * bnb_s / n, "ms",
                    "the same branch and bound, descent in Python (SLAMKIT_NO_NATIVE=1)", 1e3 * py_s / n,
                    goal=">= 3", problems=n, compiled=compiled, same_result_and_nodes=bool(same_py))]


@contextmanager
def _no_native():
    """``SLAMKIT_NO_NATIVE=1`` for the block (the kernels' numpy/Python fallbacks run)."""
    old = os.environ.get("SLAMKIT_NO_NATIVE")
    os.environ["SLAMKIT_NO_NATIVE"] = "1"
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("SLAMKIT_NO_NATIVE")
        else:
            os.environ["SLAMKIT_NO_NATIVE"] = old

