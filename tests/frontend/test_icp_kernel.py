"""slamkit.frontend._icpkernel: the compiled k-d tree returns scipy cKDTree's nearest neighbours
(distance and index) and the numpy normals, and the compiled point-to-line ICP loop ends where
the numpy one does -- the same iterations, convergence flag, correspondences and fitness, the pose
and covariance within the last bits (sums in another order, the 3x3 system by elimination instead
of LAPACK) -- on seeded synthetic scans and on consecutive scans of the real FR079 log."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from slamkit.data import registry
from slamkit.data.sequence import Scan
from slamkit.frontend import icp as icp_module
from slamkit.frontend.icp import IcpConfig, IcpTarget, estimate_normals, icp, scan_to_points
from slamkit.geometry import se2
from slamkit.maps.generators import OfficeConfig, office
from slamkit.maps.raycast import RayCaster

pytestmark = pytest.mark.skipif(icp_module._kernel() is None, reason="the ICP kernel is not built")

BEAMS = np.linspace(-np.pi, np.pi, 360, endpoint=False)
#: the logs pipeline's frontend ICP (pipelines/lidar_slam_logs.yaml)
LOGS = IcpConfig(trim_fraction=0.9, max_correspondence_m=0.5, max_iterations=30, translation_tol_m=1e-4,
                 rotation_tol_rad=1e-4)
CONFIGS = {"default": IcpConfig(), "logs": LOGS,
           "logs_lidar_only": IcpConfig(trim_fraction=1.0, max_correspondence_m=0.5, max_iterations=30,
                                        translation_tol_m=1e-4, rotation_tol_rad=1e-4, target_voxel_m=0.05),
           "wide_fitness": IcpConfig(fitness_distance_m=2.0, max_correspondence_m=1.0, trim_fraction=0.8)}
#: compiled vs numpy pose (the relative pose between them, m and rad): measured at most 2.0e-16 over
#: the 320 synthetic matches and 1.8e-15 over the 318 FR079 ones below; the bound leaves ~500x for
#: other machines' libm and BLAS
POSE_ATOL = 1e-12
#: covariance, relative to its largest entry: measured at most 4.3e-15 (synthetic) / 1.1e-13 (FR079)
COV_RTOL = 1e-10
#: RMS residual, relative: measured at most 1.6e-15 / 4.9e-15
RMSE_RTOL = 1e-12


def _both(monkeypatch, source, target, guess, config):
    """(compiled, numpy) results of the same match on the same prepared target."""
    monkeypatch.delenv("SLAMKIT_NO_NATIVE", raising=False)
    native = icp(source, target, guess, config)
    monkeypatch.setenv("SLAMKIT_NO_NATIVE", "1")
    python = icp(source, target, guess, config)
    monkeypatch.delenv("SLAMKIT_NO_NATIVE", raising=False)
    return native, python


def _agree(native, python) -> float:
    """Asserts the two results agree; returns the pose difference (the spread the tolerances are
    measured from)."""
    assert native.iterations == python.iterations
    assert native.converged == python.converged
    assert native.num_correspondences == python.num_correspondences
    assert native.fitness == python.fitness
    diff = float(np.max(np.abs(se2.between(python.target_T_source, native.target_T_source))))
    assert diff <= POSE_ATOL
    scale = np.max(np.abs(python.covariance))
    assert np.max(np.abs(native.covariance - python.covariance)) <= COV_RTOL * scale
    assert native.rmse_m == pytest.approx(python.rmse_m, rel=RMSE_RTOL)
    return diff


@pytest.fixture(scope="module")
def office_caster():
    return RayCaster(office(np.random.default_rng(4), OfficeConfig(width_m=20.0, height_m=20.0)))


@pytest.mark.parametrize("name", list(CONFIGS))
@pytest.mark.parametrize("seed", range(4))
def test_compiled_icp_equals_the_python_one(monkeypatch, office_caster, name, seed):
    """Twenty seeded matches per case: a source scan 2 cm noisy, up to 0.3 m / 0.15 rad off, against
    a target of two or eight stacked scans (the frontend's submap) -- every config the lidar SLAM
    runs plus a fitness distance beyond the gate (the second query of ``_finish``)."""
    config = CONFIGS[name]
    rng = np.random.default_rng(seed)
    pose = np.array([4.82, 17.53, 0.67])

    def scan(p):
        return scan_to_points(office_caster.scan(p, BEAMS, 20.0)[0] + rng.normal(0.0, 0.02, len(BEAMS)), BEAMS)

    for k in range(20):
        stacked = 2 if k % 2 else 8
        target = IcpTarget(np.vstack([scan(se2.compose(pose, [0.04 * i, 0.0, 0.01 * i])) for i in range(stacked)]),
                           config.normal_neighbours, config.target_voxel_m)
        offset = np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-0.15, 0.15)])
        native, python = _both(monkeypatch, scan(se2.compose(pose, offset)), target, np.zeros(3), config)
        _agree(native, python)


def test_kd_tree_nearest_equals_ckdtree():
    """Gated and ungated nearest neighbours of 2000 queries among 3000 points (a grid of exact
    duplicates and collinear rows among them): the same distances bit for bit and, where the
    nearest is unique, the same index (equidistant ones: one of them)."""
    rng = np.random.default_rng(7)
    grid = np.stack(np.meshgrid(np.arange(10) * 0.1, np.arange(10) * 0.1), -1).reshape(-1, 2)
    points = np.vstack([rng.normal(0.0, 3.0, (2700, 2)), grid, grid, grid[:100]])
    target = IcpTarget(points)
    assert len(target.points) == 3000
    ref = cKDTree(target.points)
    queries = np.vstack([rng.normal(0.0, 3.5, (1900, 2)), grid + 0.01])
    for bound in (0.05, 0.3, np.inf):
        dist, idx = target.nearest(queries, bound)
        rdist, ridx = ref.query(queries, k=1, distance_upper_bound=bound)
        np.testing.assert_array_equal(dist, rdist)
        hit = np.isfinite(rdist)
        assert np.all(idx[~hit] == len(points))
        np.testing.assert_array_equal(np.sqrt(np.sum((target.points[idx[hit]] - queries[hit]) ** 2, axis=1)),
                                      dist[hit])
        unique = hit.copy()
        unique[hit] = ref.query(queries[hit], k=2)[0][:, 1] > rdist[hit]
        np.testing.assert_array_equal(idx[unique], ridx[unique])
        assert 0 < np.count_nonzero(unique) < np.count_nonzero(hit) or bound == 0.05


def test_kernel_normals_equal_numpy_normals(office_caster):
    """PCA normals of 8 stacked scans from the kernel's k nearest neighbours: the numpy ones up to
    sign (measured |1 - |n . n_ref|| at most 2.2e-16)."""
    rng = np.random.default_rng(3)
    pose = np.array([4.82, 17.53, 0.67])
    pts = np.vstack([scan_to_points(office_caster.scan(se2.compose(pose, [0.05 * i, 0.0, 0.0]), BEAMS, 20.0)[0]
                                    + rng.normal(0.0, 0.01, len(BEAMS)), BEAMS) for i in range(8)])
    for k in (2, 6, 12):
        target = IcpTarget(pts, k)
        ref = estimate_normals(target.points, cKDTree(target.points), k)
        np.testing.assert_allclose(np.abs(np.sum(ref * target.normals, axis=1)), 1.0, atol=1e-12)


def test_python_fallback_without_the_kernel(monkeypatch, office_caster):
    """``SLAMKIT_NO_NATIVE=1`` when the target is prepared: scipy's tree and normals, the numpy
    loop (the reference); the compiled path is only taken for a target that has the kernel's
    tree, and never for point-to-point or the degeneracy-aware step."""
    pose = np.array([4.82, 17.53, 0.67])
    pts = scan_to_points(office_caster.scan(pose, BEAMS, 20.0)[0], BEAMS)
    monkeypatch.setenv("SLAMKIT_NO_NATIVE", "1")
    plain = IcpTarget(pts)
    assert plain._kd is None
    monkeypatch.delenv("SLAMKIT_NO_NATIVE")
    compiled = IcpTarget(pts)
    assert compiled._kd is not None
    source = se2.transform_points(se2.inverse(np.array([0.1, -0.05, 0.03])), pts)
    calls = []
    real = icp_module._icp_compiled
    monkeypatch.setattr(icp_module, "_icp_compiled", lambda *a: calls.append(1) or real(*a))
    a = icp(source, plain, np.zeros(3))
    assert calls == []
    b = icp(source, compiled, np.zeros(3))
    assert calls == [1]
    _agree(b, a)
    for config in (IcpConfig(method="point_to_point"), IcpConfig(degenerate_below=0.01)):
        icp(source, compiled, np.zeros(3), config)
    assert calls == [1]


def test_a_prepared_target_pickles(office_caster):
    """A target with the kernel's tree holds plain arrays: it pickles, and the copy matches as
    the original does."""
    import pickle
    pose = np.array([4.82, 17.53, 0.67])
    pts = scan_to_points(office_caster.scan(pose, BEAMS, 20.0)[0], BEAMS)
    target = IcpTarget(pts)
    copy = pickle.loads(pickle.dumps(target))
    source = se2.transform_points(se2.inverse(np.array([0.1, -0.05, 0.03])), pts)
    a, b = icp(source, target, np.zeros(3), LOGS), icp(source, copy, np.zeros(3), LOGS)
    assert np.array_equal(a.target_T_source, b.target_T_source) and a.iterations == b.iterations


@pytest.fixture(scope="module")
def fr079_scans():
    """Scans 200-359 of the FR079 log as points, with the odometry pose at each."""
    entry = registry.get("fr079-log")
    if not registry.is_available(entry):
        pytest.skip("fr079-log is not available locally (slamkit data fetch fr079-log)")
    seq = registry.load_recording("fr079-log")
    scans = [e for e in seq if isinstance(e, Scan)][200:360]
    return [scan_to_points(s.ranges_m, s.angles_rad, s.max_range_m) for s in scans]


def test_compiled_icp_equals_the_python_one_on_fr079(monkeypatch, fr079_scans):
    """Each scan against the submap of the 8 before it (stacked at the poses the compiled chain
    found), from the previous motion as the guess, with the logs pipeline's two frontend configs:
    the chain of 150 matches agrees match by match."""
    for config in (LOGS, CONFIGS["logs_lidar_only"]):
        poses = [np.zeros(3)]
        for j in range(1, len(fr079_scans)):
            members = range(max(0, j - 8), j)
            target = IcpTarget(np.vstack([se2.transform_points(poses[i], fr079_scans[i]) for i in members]),
                               config.normal_neighbours, config.target_voxel_m)
            guess = poses[-1] if len(poses) < 2 else se2.compose(poses[-1], se2.between(poses[-2], poses[-1]))
            native, python = _both(monkeypatch, fr079_scans[j], target, guess, config)
            _agree(native, python)
            poses.append(native.target_T_source)
