"""Robust back-ends under false loop closures (slamkit.backend.robust) on the Vertigo ring with
seeded outliers: least squares is ruined, the robust back-ends reject the outliers and return to
the outlier-free solution. The 1000-outlier goals of issue 16 are slow tests."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.backend.robust import ROBUST_BACKENDS, RobustSolveConfig, solve_robust
from slamkit.errors import ConfigError
from slamkit.metrics.trajectory_score import ate_paired_by_stamp
from slamkit.experiments.pose_graph_outliers import _trajectory
from slamkit.metrics.outliers import detection_scores
from slamkit.sim.outliers import OutlierConfig, add_outliers


def _ring(shared_datasets):
    from slamkit.data import registry

    graph, entry = registry.load_pose_graph_source("ring")
    return graph, registry.ground_truth(entry.name)


def _ate(gt, graph, poses) -> float:
    return ate_paired_by_stamp(gt, _trajectory(graph, poses))[0]


def test_detection_scores_worked_example():
    is_outlier = np.array([False, False, False, True, True, True, True])
    inlier = np.array([True, True, False, False, False, False, True])
    s = detection_scores(is_outlier, inlier)
    # rejected: edges 2..5; 3 of the 4 outliers rejected, 3 of 4 rejections right, 2 of 3 inliers kept
    assert (s["outlier_recall"], s["outlier_precision"]) == (0.75, 0.75)
    assert s["inlier_recall"] == pytest.approx(2 / 3)
    assert np.isnan(detection_scores(np.zeros(3, bool), np.ones(3, bool))["outlier_recall"])


def test_dcs_and_switchable_reject_20_random_outliers_on_ring(shared_datasets):
    graph, gt = _ring(shared_datasets)
    clean = _ate(gt, graph, solve_robust(graph, RobustSolveConfig(backend="none")).poses)
    assert clean == pytest.approx(1.4316, abs=1e-3)  # the outlier-free optimum (pose_graph tests)
    bad = add_outliers(graph, OutlierConfig(kind="random", count=20), np.random.default_rng(0), 0)
    ls = solve_robust(bad.graph, RobustSolveConfig(backend="none"))
    assert _ate(gt, bad.graph, ls.poses) > 10 * clean
    # measured: DCS 1.4321 m; switchable constraints 2.049 m (every outlier's switch below 1/2,
    # but the linear switch leaves each a residual pull of about Phi^2 / chi2)
    for backend, ate_bound in (("dcs", 1.01), ("switchable", 1.5)):
        r = solve_robust(bad.graph, RobustSolveConfig(backend=backend))
        s = detection_scores(bad.is_outlier, r.inlier)
        assert s["outlier_recall"] == 1.0 and s["inlier_recall"] == 1.0, backend
        assert _ate(gt, bad.graph, r.poses) < ate_bound * clean, backend
        assert np.all((r.weights >= 0) & (r.weights <= 1))
        assert r.inlier[~bad.graph.is_odometry() & ~bad.is_outlier].all()


def test_unknown_backend_is_a_config_error():
    with pytest.raises(ConfigError, match="robust back-end"):
        RobustSolveConfig(backend="ransac")
    assert set(ROBUST_BACKENDS) == {"none", "huber", "cauchy", "dcs", "switchable", "gnc"}


def test_readmission_brings_back_true_loop_closures_a_front_end_rejected(shared_datasets):
    from slamkit.backend.graph import build_graph
    from slamkit.backend._convert import values_from_poses

    graph, gt = _ring(shared_datasets)
    bad = add_outliers(graph, OutlierConfig(kind="random", count=20), np.random.default_rng(0), 0)
    true_loops = np.flatnonzero(~bad.graph.is_odometry() & ~bad.is_outlier)
    accepted = ~bad.is_outlier
    accepted[true_loops[::3]] = False  # a front-end verdict that lost 9 of the 26 true loop closures
    kept = solve_robust(bad.graph, RobustSolveConfig(backend="none", readmit=False), accepted=accepted)
    assert kept.readmitted == 0 and np.count_nonzero(~kept.inlier & ~bad.is_outlier) == 9
    r = solve_robust(bad.graph, RobustSolveConfig(backend="none"), accepted=accepted)
    # measured: the 9 come back (chi2 at the solution far inside the 0.99 gate), none of the 20
    # outliers does; the result is the outlier-free optimum (cost 5.58155, equal to 1e-6)
    assert r.readmitted == 9
    assert np.array_equal(r.inlier, ~bad.is_outlier)
    assert np.array_equal(r.weights, (~bad.is_outlier).astype(float))
    fg, _ = build_graph(graph, "none")
    clean = solve_robust(graph, RobustSolveConfig(backend="none"))
    cost = fg.error(values_from_poses(2, graph.vertex_ids, r.poses))
    assert cost == pytest.approx(fg.error(values_from_poses(2, graph.vertex_ids, clean.poses)), rel=1e-6)
    assert _ate(gt, bad.graph, r.poses) == pytest.approx(1.4316, rel=0.01)


def test_a_front_end_may_not_reject_odometry(shared_datasets):
    graph, _ = _ring(shared_datasets)
    accepted = np.ones(graph.num_edges, bool)
    accepted[0] = False
    with pytest.raises(ConfigError, match="only reject candidate"):
        solve_robust(graph, RobustSolveConfig(backend="none"), accepted=accepted)
    with pytest.raises(ConfigError, match="readmit_rounds"):
        RobustSolveConfig(readmit_rounds=0)


def test_tls_weights_worked_example():
    from slamkit.backend.robust import tls_weights

    # barc2 = 11.34 (chi2_3 at 0.99), mu = 1: weight 1 up to barc2 / 2 = 5.67, 0 from 2 barc2 = 22.68,
    # sqrt(barc2 * 2 / chi2) - 1 between (at chi2 = barc2: sqrt(2) - 1)
    w = tls_weights(np.array([0.0, 5.67, 11.34, 20.0, 22.68, 1e6]), 11.34, 1.0)
    assert w == pytest.approx([1.0, 1.0, np.sqrt(2) - 1, np.sqrt(22.68 / 20.0) - 1, 0.0, 0.0])
    # as mu grows the weights become the binary TLS verdict chi2 <= barc2
    assert tls_weights(np.array([11.0, 11.7]), 11.34, 1e4).tolist() == [1.0, 0.0]
    with pytest.raises(ConfigError, match="gnc_solver"):
        RobustSolveConfig(gnc_solver="ceres")


def test_both_gnc_solvers_reject_20_random_outliers_on_ring(shared_datasets):
    graph, gt = _ring(shared_datasets)
    bad = add_outliers(graph, OutlierConfig(kind="random", count=20), np.random.default_rng(0), 0)
    # measured: both end at the outlier-free optimum, ATE 1.4316 m, every outlier rejected, every
    # true loop closure kept; "global" picks its LAGO-started run (TLS cost 238.06) over the warm-
    # and LAGO-started one, which kept 2 outliers (ATE 78.5 m, TLS cost 311.80)
    for solver in ("global", "gtsam"):
        r = solve_robust(bad.graph, RobustSolveConfig(backend="gnc", gnc_solver=solver, readmit=False))
        assert np.array_equal(r.inlier, ~bad.is_outlier), solver
        assert _ate(gt, bad.graph, r.poses) == pytest.approx(1.4316, abs=1e-3), solver


def test_global_gnc_starts_one_run_from_dcs_which_alone_reaches_the_optimum_on_ring_plus_50(shared_datasets):
    from slamkit.backend import robust

    graph, gt = _ring(shared_datasets)
    bad = add_outliers(graph, OutlierConfig(kind="random", count=50), np.random.default_rng(0), 0)
    assert [s[0] for s in robust.GNC_STRATEGIES] == ["least_squares", "least_squares", "dcs"]
    # measured: the least-squares-started runs keep 1 and 2 outliers (ATE 44.2 m, TLS cost 603.5;
    # 48.3 m, 604.6); the DCS-started one rejects all 50 and keeps every true closure (1.43 m, 578.4)
    r = solve_robust(bad.graph, RobustSolveConfig(backend="gnc", readmit=False))
    assert np.array_equal(r.inlier, ~bad.is_outlier)
    assert _ate(gt, bad.graph, r.poses) == pytest.approx(1.4316, abs=2e-3)


def test_ten_grouped_outliers_on_ring_are_the_tls_optimum_so_gnc_keeps_them_and_dcs_does_not(shared_datasets):
    """A group of mutually consistent false loop closures can be cheaper under the truncated
    least-squares loss than the truth: the odometry absorbs them with every residual inside the
    gate. GNC minimises that loss and keeps them; DCS's kernel (Phi = 1) rejects them."""
    from slamkit.backend.graph import build_graph
    from slamkit.backend.robust import _chi2

    graph, gt = _ring(shared_datasets)
    bad = add_outliers(graph, OutlierConfig(kind="grouped", count=10), np.random.default_rng(0), 0)
    plain, _ = build_graph(bad.graph, "none", prior_sigma=1e-6)
    cand = ~bad.graph.is_odometry()
    barc2 = 11.345  # chi2 quantile 0.99, 3 dof

    def chi2(poses) -> np.ndarray:
        from slamkit.backend._convert import values_from_poses

        return _chi2(plain, values_from_poses(bad.graph.dim, bad.graph.vertex_ids, poses), bad.graph.num_edges)

    def tls_cost(poses) -> float:
        c = chi2(poses)
        return float(np.sum(c[~cand]) + np.sum(np.minimum(c[cand], barc2)))

    gnc = solve_robust(bad.graph, RobustSolveConfig(backend="gnc", readmit=False))
    dcs = solve_robust(bad.graph, RobustSolveConfig(backend="dcs", readmit=False))
    # measured: GNC keeps all 10 (ATE 41.530 m, TLS cost 83.615, every outlier's chi2 inside the
    # gate); DCS rejects all 10 (1.4310 m, TLS cost 124.613) -- identical with OPENBLAS_NUM_THREADS=1
    # and 2 and on 5 jittered twins (measurements + 1e-9, initial poses + 1e-6, rng (0, k)). Which
    # local minimum GNC's basin holds is not a figure to pin to the last digit (other groups: seed 2
    # kept at 45.3 m / TLS 48.5, seed 3 at 62.8 m / 113.0, seed 1 rejected at 1.43 m), so the test
    # checks what makes it the TLS optimum: kept, inside the gate, cheaper than the truth, far from it
    assert gnc.inlier[bad.is_outlier].all() and not dcs.inlier[bad.is_outlier].any()
    assert np.all(chi2(gnc.poses)[bad.is_outlier] <= barc2)
    assert tls_cost(gnc.poses) < tls_cost(dcs.poses)
    assert _ate(gt, bad.graph, gnc.poses) > 10 * 1.4316  # the outlier-free ATE (measured 29x that)
    # DCS returns to the outlier-free optimum (ATE 1.4316 m; measured 1.4309-1.4323 m over groups
    # seeds 0-3): its TLS cost is the optimum's chi2 (2 x its cost 5.58155, the MANIFEST anchor)
    # plus every outlier truncated at barc2 (measured 124.613 for seeds 0-3; band 1e-4 relative)
    assert _ate(gt, bad.graph, dcs.poses) == pytest.approx(1.4316, abs=2e-3)
    assert tls_cost(dcs.poses) == pytest.approx(2 * 5.58155 + 10 * barc2, rel=1e-4)
