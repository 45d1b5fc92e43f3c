"""Solvers: the iteration hook observes without changing anything, GN / dog-leg / QR agree with
raw GTSAM, the QR fallback rescues input_INTEL_g2o, iSAM2 replay agrees with batch, and bad
configs are typed errors."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from backend_reference import DEFAULT_SETTINGS, load, raw_problem, raw_solve, rel_close
from slamkit.backend.isam2 import Isam2Params
from slamkit.backend.solvers import OptimizeConfig, optimize
from slamkit.errors import BackendError, ConfigError

INTEL = "pose_graph_2d/intel.g2o"
INTEL_CARLONE = "pose_graph_2d/input_INTEL_g2o.g2o"


def test_hook_sees_every_iteration_and_changes_nothing(shared_datasets):
    graph = load(INTEL)
    seen = []
    hooked = optimize(graph, OptimizeConfig(), on_iteration=lambda it, e, p: seen.append((it, e, p)))
    plain = optimize(graph, OptimizeConfig())
    # GTSAM's own optimize() on the same problem: 3 iterations, error 22.5021165442
    graph_raw, initial = raw_problem(INTEL, 0)
    optimizer = gtsam.LevenbergMarquardtOptimizer(graph_raw, initial, gtsam.LevenbergMarquardtParams())
    optimizer.optimize()
    assert hooked.iterations == plain.iterations == optimizer.iterations() == 3
    assert hooked.final_error == plain.final_error
    assert rel_close(hooked.final_error, optimizer.error(), 1e-9)
    assert hooked.final_error == pytest.approx(22.5021165, rel=1e-8)
    # called for the initial state and after each of the 3 iterations
    assert [s[0] for s in seen] == [0, 1, 2, 3]
    assert [s[1] for s in seen] == pytest.approx(list(hooked.errors), rel=0)
    assert hooked.errors[0] == pytest.approx(276.997898, rel=1e-8)
    assert np.all(np.diff(hooked.errors) <= 0)  # LM only accepts decreasing steps
    assert seen[0][2].shape == (1728, 3)
    np.testing.assert_allclose(seen[0][2], hooked.initial_poses)
    np.testing.assert_allclose(seen[-1][2], hooked.poses)


@pytest.mark.parametrize("solver", ["gn", "dogleg"])
def test_gauss_newton_and_dogleg_equal_raw_gtsam(solver, shared_datasets):
    file = "pose_graph_2d/intel_g2o_943.g2o"
    result = optimize(load(file), OptimizeConfig(solver=solver, **DEFAULT_SETTINGS))
    _, raw_final, raw_iterations, _ = raw_solve(file, solver=solver)
    assert result.solver == solver and not result.warnings
    assert rel_close(result.final_error, raw_final, 1e-6)
    assert result.iterations == raw_iterations
    assert result.final_error == pytest.approx(273.2316, rel=1e-5)


def test_lm_on_qr_equals_raw_gtsam_on_qr(shared_datasets):
    result = optimize(load(INTEL), OptimizeConfig(linear_solver="qr"))
    _, raw_final, raw_iterations, _ = raw_solve(INTEL, linear_solver="MULTIFRONTAL_QR")
    assert result.linear_solver == "qr"
    assert rel_close(result.final_error, raw_final, 1e-6) and result.iterations == raw_iterations


@pytest.mark.parametrize("solver", ["dogleg", "lm", "gn"])
def test_qr_fallback_solves_input_intel(solver, shared_datasets):
    """input_INTEL_g2o's information spans 10 .. 2.7e12: Cholesky fails (dog-leg and GN raise
    IndeterminantLinearSystem, LM gives up at its maximum lambda without a step); the fallback,
    dog-leg on multifrontal QR, reaches GTSAM error 107.919 (python-graphslam: chi2 215.8405) in
    19 iterations, exactly as raw GTSAM's DoglegOptimizer with MULTIFRONTAL_QR."""
    result = optimize(load(INTEL_CARLONE), OptimizeConfig(solver=solver))
    assert (result.solver, result.linear_solver) == ("dogleg", "qr")
    assert any("redone with dogleg on multifrontal QR" in w for w in result.warnings)
    _, raw_final, raw_iterations, _ = raw_solve(INTEL_CARLONE, solver="dogleg",
                                                linear_solver="MULTIFRONTAL_QR")
    assert rel_close(result.final_error, raw_final, 1e-6)
    assert result.iterations == raw_iterations == 19
    assert result.final_error == pytest.approx(107.919, rel=1e-5)
    assert result.chi2 == pytest.approx(215.838, rel=1e-5)


def test_without_fallback_cholesky_failure_is_a_backend_error(shared_datasets):
    with pytest.raises(BackendError, match="Cholesky|cholesky"):
        optimize(load(INTEL_CARLONE), OptimizeConfig(solver="dogleg", qr_fallback=False))


@pytest.mark.parametrize("file,threshold,rel", [
    ("pose_graph_2d/intel_g2o_943.g2o", 0.1, 1e-5),   # measured 1.6e-6
    ("pose_graph_2d/ring.g2o", 0.1, 1e-3),            # measured 2.2e-4
    ("pose_graph_2d/ring.g2o", 0.01, 1e-5),           # measured 1.2e-6
    ("pose_graph_3d/smallGrid3D.g2o", 0.01, 1e-5),    # measured 2.1e-6
])
def test_isam2_replay_reaches_the_batch_optimum(file, threshold, rel, shared_datasets):
    """iSAM2 replay (one update per new pose, then forced relinearisation) ends within ``rel`` of
    the batch LM error; the gap is set by the relinearisation threshold."""
    graph = load(file)
    batch = optimize(graph, OptimizeConfig())
    inc = optimize(graph, OptimizeConfig(solver="isam2",
                                         isam2=Isam2Params(relinearize_threshold=threshold,
                                                           relinearize_skip=1)))
    assert inc.solver == "isam2"
    assert inc.final_error >= batch.final_error * (1 - 1e-9)
    assert inc.final_error == pytest.approx(batch.final_error, rel=rel)
    assert inc.iterations >= graph.num_poses  # one update per pose plus the final ones


def test_isam2_hook_sees_error_per_update(shared_datasets):
    graph = load("pose_graph_3d/tinyGrid3D.g2o")
    seen = []
    result = optimize(graph, OptimizeConfig(solver="isam2"),
                      on_iteration=lambda u, e, p: seen.append((u, e, np.isnan(p[:, 0]).sum())))
    assert seen[0][0] == 0 and seen[0][2] == 0            # initial estimate, every pose known
    assert seen[1][2] == graph.num_poses - 1              # first update: only the root is placed
    assert seen[-1][2] == 0
    assert len(seen) == result.iterations + 1
    assert seen[-1][1] == pytest.approx(result.final_error, rel=1e-9)


def test_isam2_falls_back_to_qr_on_csail(shared_datasets):
    """CSAIL's information makes iSAM2's incremental Cholesky indeterminant at x92; the replay is
    redone with QR and still ends within 3e-4 of the batch error 20.2754."""
    result = optimize(load("pose_graph_2d/CSAIL.g2o"), OptimizeConfig(solver="isam2"))
    assert result.linear_solver == "qr"
    assert any("QR" in w for w in result.warnings)
    assert result.final_error == pytest.approx(20.2754, rel=3e-4)


@pytest.mark.parametrize("kwargs", [dict(solver="newton"), dict(init="random"), dict(robust="tukey"),
                                    dict(linear_solver="lu"), dict(max_iterations=-1),
                                    dict(prior_sigma=0.0), dict(robust_k=-1.0),
                                    dict(relative_error_tol=float("nan"))])
def test_bad_config_is_a_config_error(kwargs):
    with pytest.raises(ConfigError):
        OptimizeConfig(**kwargs)


def test_max_iterations_cap_is_reported(shared_datasets):
    result = optimize(load("pose_graph_2d/input_MITb_g2o.g2o"), OptimizeConfig(max_iterations=2))
    assert result.iterations == 2 and not result.converged
    assert any("iteration cap" in w for w in result.warnings)


def _torn_chain() -> "PoseGraph":
    """Poses 0-1-2 on a line, odometry 0->1 and 1->2 of 1 m, a loop 0->2 of 2 m; pose 1 sits
    0.5 m to the side of its odometry (the chain is torn there)."""
    from slamkit.data.pose_graph import PoseGraph

    info = np.repeat(np.diag([100.0, 100.0, 400.0])[None], 3, axis=0)
    return PoseGraph(2, np.arange(3), np.array([[0.0, 0.0, 0.0], [1.0, 0.5, 0.0], [2.0, 0.0, 0.0]]),
                     np.array([0, 1, 0]), np.array([1, 2, 2]),
                     np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]), info)


def test_robust_edges_loop_closures_keeps_the_odometry_chain_least_squares() -> None:
    """Worked example: each odometry edge is 0.5 m off sideways, whitened 0.5 / 0.1 = 5 (chi2 25);
    the loop 0->2 is exact. Least squares on the chain costs
    0.5 * chi2 per edge; Cauchy (c = 2.3849) would cost 0.5 c^2 log(1 + chi2 / c^2): 25 against
    9.59 here, and the gap grows with the tear (at chi2 7633, the Intel lidar-only tear of issue
    28: 3817 against 20.5), so a robust chain tears cheaply."""
    from slamkit.geometry import se2

    graph = _torn_chain()
    err = se2.log(se2.between(graph.measurements, se2.between(graph.poses[graph.edge_from],
                                                                 graph.poses[graph.edge_to])))
    chi2 = np.einsum("ni,nij,nj->n", err, graph.information, err)
    assert chi2[2] == pytest.approx(0.0, abs=1e-20) and chi2[:2] == pytest.approx([25.0, 25.0])
    c = 2.3849
    cauchy = 0.5 * c * c * np.log1p(chi2 / (c * c))
    base = dict(robust="cauchy", max_iterations=0)
    every = optimize(graph, OptimizeConfig(**base))
    loops = optimize(graph, OptimizeConfig(**base, robust_edges="loop_closures"))
    # the gauge prior sits exactly on pose 0 and adds nothing
    assert every.initial_error == pytest.approx(cauchy.sum(), rel=1e-9)
    assert loops.initial_error == pytest.approx(0.5 * chi2[:2].sum() + cauchy[2], rel=1e-9)
    assert loops.initial_error == pytest.approx(25.0) and every.initial_error == pytest.approx(9.587, abs=1e-3)
    # solved, both put pose 1 back on the line (nothing contradicts the chain here)
    solved = optimize(graph, OptimizeConfig(robust="cauchy", robust_edges="loop_closures"))
    np.testing.assert_allclose(solved.poses[1], [1.0, 0.0, 0.0], atol=1e-6)


def test_robust_edges_is_checked() -> None:
    with pytest.raises(ConfigError, match="robust_edges"):
        OptimizeConfig(robust_edges="odometry")
