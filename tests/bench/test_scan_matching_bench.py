"""The scan-matching bench returns its cases with same-run references and equal results (the
timings themselves are not asserted)."""

from __future__ import annotations

import numpy as np

from slamkit.bench import scan_matching as benchmark
from slamkit.frontend.icp import IcpConfig, icp


def test_naive_reference_equals_vectorised_icp():
    rng = np.random.default_rng(0)
    target = rng.uniform(-5, 5, (60, 2))
    source = target + np.array([0.05, -0.03])
    cfg = IcpConfig(method="point_to_point", max_iterations=5, translation_tol_m=0.0,
                    rotation_tol_rad=0.0, max_correspondence_m=1.0)
    fast = icp(source, target, np.zeros(3), cfg).target_T_source
    slow = benchmark.naive_icp(source, target, np.zeros(3), 5, 1.0)
    np.testing.assert_allclose(fast, slow, atol=1e-12)


def test_quick_bench_cases():
    cases = benchmark.run(quick=True)
    names = [c.name for c in cases]
    assert names == ["icp2d_point_to_point_360_beams", "icp2d_point_to_line_360_beams_to_convergence",
                     "icp_rotation_search_10deg", "icp_point_to_line_submap_compiled",
                     "icp_submap_target_compiled", "global_match_bnb_window_2m_20deg",
                     "global_match_bnb_compiled_descent"]
    c = cases[0]
    assert c.reference is not None and c.ratio is not None and c.ratio > 0
    assert c.extra["max_abs_difference"] < 1e-9  # both did the same work
    r = cases[2]
    # the batched heading search returns the per-heading one's heading and score exactly
    assert r.extra["same_result"] and r.ratio is not None and r.ratio > 0
    m = cases[3]
    # the compiled ICP loop (or, unbuilt, the numpy one against itself) takes the numpy loop's
    # iterations and correspondences to the same pose (tests/frontend/test_icp_kernel.py: 1e-12)
    assert m.extra["same_iterations_and_correspondences"] and m.extra["max_abs_difference"] < 1e-12
    assert m.ratio is not None and m.ratio > 0 and cases[4].ratio is not None and cases[4].ratio > 0
    g = cases[5]
    # the branch and bound is exact: the exhaustive search's pose and score, from fewer nodes
    assert g.extra["same_optimum"] and g.ratio is not None and g.ratio > 0
    assert 0 < g.extra["nodes_scored_mean"] < g.extra["candidates_in_window"]
    # the compiled descent (or, unbuilt, the Python one against itself) finds the same optimum
    # from the same nodes as the Python descent
    k = cases[6]
    assert k.extra["same_result_and_nodes"] and k.ratio is not None and k.ratio > 0
