"""The particle filter's fused C kernels (``_pfkernel.c``) against the numpy expressions they
replace: a worked example on both paths, random inputs compared path against path (to ~1e-12),
the awkward geometries of atan2 (axes, a particle on its landmark, every quadrant), and a whole
filter run seeded the same way on both paths."""

from __future__ import annotations

import importlib
import math

import numpy as np
import pytest

from slamkit import _native
from slamkit.data.estimate import Prior
from slamkit.data.sequence import Odometry, RangeBearing
from slamkit.estimation._common import NoiseParams, weighted_pose_mean_cov
from slamkit.estimation import particle_filter as pf
from slamkit.models import range_bearing



def _built_kernel():
    """The compiled module, even when the run has SLAMKIT_NO_NATIVE=1 set (each test below picks
    its implementation itself)."""
    try:
        return importlib.import_module(pf.PFKERNEL_MODULE)
    except ImportError:
        return None


KERNEL_MODULE = _built_kernel()
KERNEL_AVAILABLE = KERNEL_MODULE is not None
IMPLEMENTATIONS = {"native": pf.NativeKernels(KERNEL_MODULE) if KERNEL_AVAILABLE else None,
                   "numpy": pf.NumpyKernels()}
PATHS = [
    pytest.param("native", marks=pytest.mark.skipif(
        not KERNEL_AVAILABLE, reason=f"no compiled kernel: {_native.unavailable_reason(pf.PFKERNEL_MODULE)}")),
    "numpy",
]
needs_native = pytest.mark.skipif(not KERNEL_AVAILABLE, reason="no compiled kernel")


def _use(monkeypatch, path: str) -> None:
    """Every particle-filter function calls pf.KERNELS, chosen at import: swap it."""
    monkeypatch.setattr(pf, "KERNELS", IMPLEMENTATIONS[path])


def _both(monkeypatch, fn):
    """fn() on the native path, then on the numpy path."""
    _use(monkeypatch, "native")
    a = fn()
    _use(monkeypatch, "numpy")
    b = fn()
    monkeypatch.undo()
    return a, b


def _angle_gap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a - b| modulo 2 pi (a residual of exactly +-pi may wrap either way on either path)."""
    d = np.abs(np.asarray(a) - np.asarray(b))
    return np.minimum(d, np.abs(d - 2.0 * np.pi))


# --------------------------------------------------------------------------------------------
# worked example, on both paths
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("path", PATHS)
def test_range_bearing_worked_example(monkeypatch, path):
    # robot at the origin facing +x, landmark at (3, 4): h = (5, atan2(4, 3)); the measurement
    # is off by (0.1 m, 0.02 rad), so with R = diag(0.1^2, 0.02^2) the Mahalanobis sum is 2
    _use(monkeypatch, path)
    particles = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.5]])
    lm = np.array([[3.0, 4.0]])
    z = np.array([[5.1, math.atan2(4.0, 3.0) + 0.02]])
    R = np.diag([0.01, 0.0004])
    ll, nu = pf.range_bearing_log_likelihood(particles, lm, z, R)
    const = math.log(2 * math.pi) + 0.5 * math.log(0.01 * 0.0004)
    assert nu[0, 0] == pytest.approx([0.1, 0.02], abs=1e-12)
    assert ll[0] == pytest.approx(-1.0 - const, abs=1e-12)
    # heading 0.5 rad: the predicted bearing drops by 0.5, so the residual grows by 0.5
    assert nu[1, 0] == pytest.approx([0.1, 0.52], abs=1e-12)
    assert ll[1] == pytest.approx(-0.5 * (1.0 + 0.52**2 / 0.0004) - const, abs=1e-9)


@pytest.mark.parametrize("path", PATHS)
def test_innovations_worked_example(monkeypatch, path):
    # two particles with weights 0.25 / 0.75 and residuals (0, 0) / (0.4, -0.2): mean (0.3, -0.15),
    # covariance w1 w2 (d d^T) = 0.1875 [[0.16, -0.08], [-0.08, 0.04]], plus R
    _use(monkeypatch, path)
    residuals = np.array([[[0.0, 0.0]], [[0.4, -0.2]]])
    R = np.diag([0.01, 0.0004])
    nu, S = pf.predictive_innovations(residuals, np.array([0.25, 0.75]), R)
    assert nu == pytest.approx(np.array([[0.3, -0.15]]), abs=1e-15)
    assert S[0] == pytest.approx(0.1875 * np.array([[0.16, -0.08], [-0.08, 0.04]]) + R, abs=1e-15)


@pytest.mark.parametrize("path", PATHS)
def test_pose_mean_cov_worked_example(monkeypatch, path):
    # headings +-(pi - 0.1) straddle the wrap: the circular mean is pi (reported as +-pi) and the
    # spread 0.1 rad each side, not 2 pi - 0.2
    _use(monkeypatch, path)
    poses = np.array([[1.0, 0.0, math.pi - 0.1], [3.0, 2.0, -math.pi + 0.1]])
    mean, cov = pf.pose_mean_cov(poses, np.array([1.0, 1.0]))
    assert mean[:2] == pytest.approx([2.0, 1.0], abs=1e-12)
    assert abs(mean[2]) == pytest.approx(math.pi, abs=1e-12)
    # heading residuals -0.1 / +0.1 go with position residuals (-1, -1) / (1, 1)
    assert cov == pytest.approx(np.array([[1.0, 1.0, 0.1], [1.0, 1.0, 0.1], [0.1, 0.1, 0.01]]), abs=1e-12)


# --------------------------------------------------------------------------------------------
# native == numpy on random inputs
# --------------------------------------------------------------------------------------------
def _random_problem(seed: int, n: int, m: int):
    rng = np.random.default_rng(seed)
    particles = np.column_stack([rng.uniform(-15, 15, n), rng.uniform(-15, 15, n), rng.uniform(-np.pi, np.pi, n)])
    lm = rng.uniform(-10, 10, (m, 2))
    z = np.column_stack([rng.uniform(0.0, 20.0, m), rng.uniform(-np.pi, np.pi, m)])
    A = rng.standard_normal((2, 2)) * [0.3, 0.05]
    R = A @ A.T + np.diag([1e-3, 1e-4])
    return particles, lm, z, R


@needs_native
@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("n, m", [(1, 1), (7, 3), (1000, 5), (257, 12)])
def test_likelihood_native_matches_numpy(monkeypatch, seed, n, m):
    particles, lm, z, R = _random_problem(seed, n, m)
    (ll_c, nu_c), (ll_n, nu_n) = _both(monkeypatch, lambda: pf.range_bearing_log_likelihood(particles, lm, z, R))
    assert ll_c.shape == ll_n.shape == (n,) and nu_c.shape == nu_n.shape == (n, m, 2)
    assert np.max(np.abs(ll_c - ll_n) / np.maximum(1.0, np.abs(ll_n))) < 1e-12
    assert np.max(np.abs(nu_c[..., 0] - nu_n[..., 0])) < 1e-12
    assert np.max(_angle_gap(nu_c[..., 1], nu_n[..., 1])) < 1e-12

    w = np.random.default_rng(seed + 100).random(n)
    w /= w.sum()
    (mu_c, S_c), (mu_n, S_n) = _both(monkeypatch, lambda: pf.predictive_innovations(nu_n, w, R))
    assert np.max(np.abs(mu_c - mu_n)) < 1e-12
    assert np.max(np.abs(S_c - S_n)) < 1e-12


@needs_native
def test_bearing_geometry_native_matches_numpy(monkeypatch):
    # every quadrant, both axes, the +-pi seam, a particle exactly on its landmark (atan2(0, 0)),
    # tiny and huge offsets
    offsets = [(1, 0), (-1, 0), (0, 1), (0, -1), (0, 0), (1, 1), (-1, 1), (-1, -1), (1, -1),
               (-1, 1e-300), (-1, -1e-300), (1e-200, 1), (3, 1e-17), (1e8, 1), (0.66, 1), (2.4142135, 1),
               (-2.4142136, 1), (1, 2.414213562373095), (1, 0.66), (-1, 0.6600000000000001)]
    lm = np.array([[2.0, -1.0]])
    particles = np.array([[2.0 - ox, -1.0 - oy, th] for ox, oy in offsets for th in (0.0, 3.0, -np.pi)])
    z = np.array([[1.0, 0.3]])
    R = np.diag([0.01, 0.0004])
    (ll_c, nu_c), (ll_n, nu_n) = _both(monkeypatch, lambda: pf.range_bearing_log_likelihood(particles, lm, z, R))
    assert np.all(np.isfinite(nu_c)) and np.all(np.isfinite(ll_c))
    assert np.max(_angle_gap(nu_c[..., 1], nu_n[..., 1])) < 1e-12
    assert np.max(np.abs(nu_c[..., 0] - nu_n[..., 0]) / np.maximum(1.0, np.abs(nu_n[..., 0]))) < 1e-12


@needs_native
@pytest.mark.parametrize("seed", range(4))
def test_motion_native_matches_numpy_with_the_same_draws(monkeypatch, seed):
    particles, _, _, _ = _random_problem(seed, 500, 1)
    particles[:5, 2] = [np.pi - 1e-9, -np.pi, 0.0, 1e-300, -3.0]
    u = np.array([0.7, [0.0, 0.3, -2.0, 1e-14][seed]])  # straight, turning, fast turn, ~0 rate
    M = np.diag([0.05**2, [0.0, 0.02, 0.1, 1e-7][seed] ** 2])

    def run():
        rng = np.random.default_rng(seed)
        out = pf.sample_motion(particles, u, 0.1, M, rng)
        return out, rng.random()  # the rng must have advanced the same way

    (x_c, after_c), (x_n, after_n) = _both(monkeypatch, run)
    assert after_c == after_n
    assert np.max(np.abs(x_c[:, :2] - x_n[:, :2])) < 1e-12
    assert np.max(_angle_gap(x_c[:, 2], x_n[:, 2])) < 1e-12
    assert np.all((x_c[:, 2] >= -np.pi) & (x_c[:, 2] < np.pi))


@needs_native
@pytest.mark.parametrize("seed", range(4))
def test_pose_mean_cov_and_systematic_native_match_numpy(monkeypatch, seed):
    rng = np.random.default_rng(seed)
    poses = np.column_stack([rng.normal(3, 1, 2000), rng.normal(-1, 2, 2000),
                             rng.normal([0.0, 3.0, -3.0, 1.0][seed], 0.4, 2000)])
    poses[:, 2] = (poses[:, 2] + np.pi) % (2 * np.pi) - np.pi
    w = rng.random(2000) ** 4
    (m_c, P_c), (m_n, P_n) = _both(monkeypatch, lambda: pf.pose_mean_cov(poses, w))
    m_ref, P_ref = weighted_pose_mean_cov(poses, w)
    assert np.array_equal(m_n, m_ref) and np.array_equal(P_n, P_ref)
    assert np.max(np.abs(m_c[:2] - m_n[:2])) < 1e-12 and _angle_gap(m_c[2], m_n[2]) < 1e-12
    assert np.max(np.abs(P_c - P_n)) < 1e-12
    assert np.array_equal(P_c, P_c.T)

    offset = rng.random() / 2000
    idx_c, idx_n = _both(monkeypatch, lambda: pf.systematic_resample(w, offset=offset))
    assert idx_c.dtype == idx_n.dtype == np.int64
    assert np.array_equal(idx_c, idx_n)  # same cumulative sum, same comparisons: identical


@needs_native
def test_whole_filter_native_matches_numpy(monkeypatch):
    landmarks = {i: np.array([4.0 * math.cos(i), 4.0 * math.sin(i)]) for i in range(8)}

    def run():
        filt = pf.ParticleFilterLocalization(landmarks, NoiseParams(),
                                             pf.ParticleFilterConfig(n_particles=2000, ess_threshold=0.7),
                                             rng=np.random.default_rng(11))
        filt.reset(Prior(np.zeros(3), np.diag([0.05, 0.05, 0.01])))
        truth = np.zeros(3)
        obs_rng = np.random.default_rng(3)
        for k in range(1, 30):
            t = 0.1 * k
            filt.step(Odometry(t, 0.1, 0.5, 0.2))
            truth = np.array([truth[0] + 0.05 * math.cos(truth[2]), truth[1] + 0.05 * math.sin(truth[2]),
                              truth[2] + 0.02])
            ids = np.array([k % 8, (k + 3) % 8])
            lm = np.array([landmarks[i] for i in ids])
            zz = range_bearing.observe(truth, lm) + obs_rng.normal(0, [0.1, 0.02], (2, 2))
            filt.step(RangeBearing(t, ids, zz[:, 0], zz[:, 1]))
        est = filt.estimate()
        return (np.column_stack([est.trajectory.world_t_body, est.pose_covariances.reshape(-1, 9)]),
                filt.n_resamples, np.asarray(est.nis))

    (poses_c, res_c, nis_c), (poses_n, res_n, nis_n) = _both(monkeypatch, run)
    assert res_c == res_n > 0
    assert np.max(np.abs(poses_c - poses_n)) < 1e-9
    assert np.max(np.abs(nis_c - nis_n) / np.maximum(1.0, nis_n)) < 1e-9
