"""Particle filter: log weights, four resampling schemes, adaptive resampling on the effective
sample size, and particle-filter localization on a landmark map -- vectorised over particles.

* Gordon, Salmond & Smith (1993), "Novel approach to nonlinear/non-Gaussian Bayesian state
  estimation" (bootstrap filter); Thrun et al., *Probabilistic Robotics*, Table 4.3.
* Resampling: Douc, Cappe & Moulines (2005), "Comparison of resampling schemes for particle
  filtering" -- multinomial, stratified (one uniform per stratum), systematic (one uniform for
  all strata, Table 4.4 of Probabilistic Robotics) and residual (Liu & Chen 1998: floor(N w)
  deterministic copies, the remainder drawn multinomially from the residual weights).
* Adaptive resampling: resample only when N_eff = 1 / sum w_i^2 drops below a fraction of N
  (Liu & Chen 1995; Doucet, Godsill & Andrieu 2000).

Weights are kept as log weights normalised with log-sum-exp, so many landmarks or a kidnapped
robot underflow nothing. No per-particle Python: motion sampling, likelihoods, statistics and
resampling are all array operations over the particle axis.

Speed: numpy is near its floor on this step (~15 N x m temporaries per update), so the hot path
-- exact-arc motion with the rng's draws, the known-correspondence range-bearing likelihood and
residuals, the predictive innovations and their NIS, the posterior mean/covariance and
systematic resampling -- runs in fused C loops (``_pfkernel.c``, compiled when slamkit is
installed, loaded through :mod:`slamkit._native`).

Architecture note (issue 18): the five steps are two classes with one interface,
:class:`NumpyKernels` (the numpy expressions, the reference) and :class:`NativeKernels` (the C
loops), and :data:`KERNELS` is chosen once when the module is imported (``SLAMKIT_NO_NATIVE=1``
or no compiler: numpy), so the algorithm reads straight through instead of forking on every
call. The ML-association path is numpy always. The two draw the same random numbers and agree to
~1e-15 (the kernel's atan2 is Cephes' rational approximation, a few ulp from numpy's;
tests/estimation/test_pf_kernel.py runs both by swapping :data:`KERNELS`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import ModuleType
from typing import Callable, Mapping

import numpy as np

from slamkit._native import load_extension
from slamkit.data.estimate import Prior
from slamkit.data.sequence import Gps, Odometry, Range, RangeBearing
from slamkit.errors import ConfigError
from slamkit.estimation._common import (
    range_rows,
    FilterBase,
    NoiseParams,
    landmark_array,
    nis_values,
    observation_rows,
    weighted_pose_mean_cov,
)
from slamkit.geometry.angles import wrap_angle
from slamkit.models import diff_drive, range_bearing, range_only

PFKERNEL_MODULE = "slamkit.estimation._pfkernel"


def _f64(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=float)


# --------------------------------------------------------------------------------------------
# weights
# --------------------------------------------------------------------------------------------
def log_sum_exp(a: np.ndarray) -> float:
    """log(sum(exp(a))) shifted by the maximum (scipy's logsumexp costs ~0.1 ms of overhead
    per call, which is most of a 1000-particle step)."""
    top = float(np.max(a))
    if not np.isfinite(top):
        return top
    return top + float(np.log(np.sum(np.exp(a - top))))


def normalize_log_weights(log_w: np.ndarray) -> np.ndarray:
    """Shift log weights so that sum(exp(log_w)) == 1."""
    return log_w - log_sum_exp(log_w)


def effective_sample_size(weights: np.ndarray) -> float:
    """N_eff = 1 / sum w_i^2 for normalised weights."""
    w = np.asarray(weights, dtype=float)
    w = w / w.sum()
    return float(1.0 / np.sum(w * w))


# --------------------------------------------------------------------------------------------
# resampling: every function returns (n,) indices into the weighted set
# --------------------------------------------------------------------------------------------
def _cumulative(weights: np.ndarray) -> np.ndarray:
    c = np.cumsum(np.asarray(weights, dtype=float))
    c /= c[-1]
    c[-1] = 1.0  # no index beyond the last particle through round-off
    return c


def _pick(cumulative: np.ndarray, positions: np.ndarray) -> np.ndarray:
    # index i with c[i-1] <= u < c[i]
    return np.minimum(np.searchsorted(cumulative, positions, side="right"), len(cumulative) - 1)


def multinomial_resample(weights: np.ndarray, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    """n i.i.d. draws from the categorical distribution of ``weights``."""
    n = len(weights) if n is None else n
    return _pick(_cumulative(weights), rng.random(n))


def stratified_resample(weights: np.ndarray, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    """One uniform draw in each stratum [i/n, (i+1)/n)."""
    n = len(weights) if n is None else n
    return _pick(_cumulative(weights), (np.arange(n) + rng.random(n)) / n)


def systematic_resample(weights: np.ndarray, rng: np.random.Generator | None = None,
                        n: int | None = None, offset: float | None = None) -> np.ndarray:
    """Positions offset + i/n with a single offset ~ U[0, 1/n) (low-variance sampler, Probabilistic
    Robotics Table 4.4). ``offset`` fixes it (it must lie in [0, 1/n))."""
    n = len(weights) if n is None else n
    if offset is None:
        if rng is None:
            raise ConfigError("systematic_resample needs rng or offset")
        offset = rng.random() / n
    if not 0.0 <= offset < 1.0 / n:
        raise ConfigError(f"systematic_resample offset must lie in [0, 1/n) = [0, {1.0 / n}), got {offset}")
    return KERNELS.systematic(weights, float(offset), n)


def residual_resample(weights: np.ndarray, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    """floor(n w_i) copies of particle i, the remaining draws multinomial on the residuals."""
    w = np.asarray(weights, dtype=float)
    w = w / w.sum()
    n = len(w) if n is None else n
    counts = np.floor(n * w).astype(np.int64)
    kept = np.repeat(np.arange(len(w)), counts)
    rest = n - len(kept)
    if rest == 0:
        return kept
    residual = n * w - counts
    return np.concatenate([kept, _pick(_cumulative(residual), rng.random(rest))])


RESAMPLERS: dict[str, Callable[..., np.ndarray]] = {
    "multinomial": multinomial_resample,
    "stratified": stratified_resample,
    "systematic": systematic_resample,
    "residual": residual_resample,
}


def resample(scheme: str, weights: np.ndarray, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    try:
        fn = RESAMPLERS[scheme]
    except KeyError:
        raise ConfigError(f"unknown resampling scheme {scheme!r}; choose from {sorted(RESAMPLERS)}") from None
    return fn(weights, rng, n)


def roughening_sigma(particles: np.ndarray, k: float, angle_mask: np.ndarray | None = None,
                     min_spread: np.ndarray | None = None) -> np.ndarray:
    """Per-dimension standard deviation K E N^(-1/d) that :func:`roughen` applies; E is floored
    at ``min_spread`` (a set of identical copies would otherwise never be roughened again)."""
    n, d = particles.shape
    if k <= 0 or n < 1:
        return np.zeros(d)
    spread = particles.max(axis=0) - particles.min(axis=0)
    if min_spread is not None:
        spread = np.maximum(spread, min_spread)
    if angle_mask is not None and np.any(angle_mask):
        spread[angle_mask] = np.minimum(spread[angle_mask], np.pi)
    return k * spread * n ** (-1.0 / d)


def roughen(particles: np.ndarray, k: float, rng: np.random.Generator,
            angle_mask: np.ndarray | None = None, min_spread: np.ndarray | None = None) -> np.ndarray:
    """Roughening (Gordon, Salmond & Smith 1993, section 4.1): jitter resampled particles with
    zero-mean Gaussian noise of standard deviation K E N^(-1/d) per dimension, E the spread
    (max - min) of that dimension. It counters sample impoverishment when the process noise is
    small compared with the likelihood's width."""
    n, d = particles.shape
    if k <= 0 or n < 1:
        return particles
    out = particles + rng.standard_normal((n, d)) * roughening_sigma(particles, k, angle_mask, min_spread)
    if angle_mask is not None and np.any(angle_mask):
        out[:, angle_mask] = wrap_angle(out[:, angle_mask])
    return out


def kernel_bandwidth(n: int, d: int) -> float:
    """The optimal Gaussian-kernel bandwidth h_opt = A N^(-1/(d+4)), A = (4/(d+2))^(1/(d+4))
    (Musso, Oudjane & Le Gland 2001, eq. 12.13; Silverman's rule)."""
    return (4.0 / (d + 2.0)) ** (1.0 / (d + 4.0)) * n ** (-1.0 / (d + 4.0))


def regularize(particles: np.ndarray, cov: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Draw each (N, 3) pose particle from N(x_i, h_opt^2 cov) (heading wrapped)."""
    n, d = particles.shape
    h = kernel_bandwidth(n, d)
    S = 0.5 * (cov + cov.T) * h * h
    try:
        L = np.linalg.cholesky(S + 1e-12 * np.eye(d))
    except np.linalg.LinAlgError:
        return particles
    out = particles + rng.standard_normal((n, d)) @ L.T
    out[:, 2] = wrap_angle(out[:, 2])
    return out


# --------------------------------------------------------------------------------------------
# planar robot helpers shared with MCL
# --------------------------------------------------------------------------------------------
def sample_motion(particles: np.ndarray, u: np.ndarray, dt_s: float, control_cov: np.ndarray,
                  rng: np.random.Generator) -> np.ndarray:
    """Propagate (N, 3) particles through the exact-arc model with per-particle noisy (v, omega)
    (Probabilistic Robotics, Table 5.3, with the Gaussian velocity noise of the sequence)."""
    draws = rng.standard_normal((len(particles), 2))
    return KERNELS.motion(particles, np.asarray(u, dtype=float), dt_s, draws,
                          np.sqrt(np.diag(np.asarray(control_cov, dtype=float))))


def sample_gaussian_poses(mean: np.ndarray, cov: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) poses from N(mean, cov); tolerates a singular covariance (eigen square root)."""
    vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
    root = vecs * np.sqrt(np.clip(vals, 0.0, None))
    poses = mean + rng.standard_normal((n, 3)) @ root.T
    poses[:, 2] = wrap_angle(poses[:, 2])
    return poses


_TWO_PI = 2.0 * np.pi


def _wrap_for_square(a: np.ndarray) -> np.ndarray:
    """Wrap to [-pi, pi] with one floor (3x cheaper than the canonical half-open wrap). Only
    used where the value is squared or fed to sin/cos, so the +-pi boundary does not matter."""
    return a - _TWO_PI * np.floor((a + np.pi) / _TWO_PI)


def _gaussian_log_constant(R: np.ndarray, m: int) -> float:
    """m log(2 pi) + m/2 log det R: the normaliser of m independent 2-D Gaussians of covariance R
    (determinant written out: np.linalg.det costs ~5 us per call)."""
    r00, r01, r10, r11 = R.ravel().tolist()
    return m * (math.log(2.0 * math.pi) + 0.5 * math.log(r00 * r11 - r01 * r10))


def _maha_2d(nu: np.ndarray, R: np.ndarray) -> np.ndarray:
    """nu^T R^-1 nu over the last axis for one 2 x 2 R, written out (einsum with three operands
    is several times slower at this size)."""
    det = R[0, 0] * R[1, 1] - R[0, 1] * R[1, 0]
    a, b, c = R[1, 1] / det, -R[0, 1] / det, R[0, 0] / det
    r, t = nu[..., 0], nu[..., 1]
    return a * r * r + 2.0 * b * r * t + c * t * t


def range_bearing_log_likelihood(particles: np.ndarray, landmarks: np.ndarray, z: np.ndarray,
                                 R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Log-likelihood (N,) of m measurements z (m, 2) of known landmarks (m, 2) for every particle,
    and the residuals z - h(x_p, m) (N, m, 2), bearing wrapped."""
    return KERNELS.rb_loglik(particles, landmarks, z, np.asarray(R, dtype=float))


def range_bearing_log_likelihood_ml(particles: np.ndarray, landmarks: np.ndarray, z: np.ndarray,
                                    R: np.ndarray) -> np.ndarray:
    """Log-likelihood (N,) of measurements with unknown correspondence: for each particle and
    measurement the most likely map landmark is used (maximum-likelihood association)."""
    n, L = len(particles), len(landmarks)
    z_hat = np.asarray(range_bearing.observe(np.broadcast_to(particles[:, None, :], (n, L, 3)),
                                             np.broadcast_to(landmarks[None], (n, L, 2))), dtype=float)
    nu = z[None, :, None, :] - z_hat[:, None, :, :]  # (N, m, L, 2)
    nu[..., 1] = _wrap_for_square(nu[..., 1])
    maha = _maha_2d(nu, R)
    const = np.log(2.0 * np.pi) + 0.5 * np.log(np.linalg.det(R))
    return np.sum(-0.5 * maha.min(axis=2) - const, axis=1)


def predictive_innovations(residuals: np.ndarray, weights: np.ndarray,
                           R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Innovation nu (m, 2) and covariance S (m, 2, 2) of the particles' predictive distribution
    of each measurement, from the per-particle residuals z - h(x_p) (N, m, 2): nu is their
    weighted mean and S their weighted covariance plus R. Working with wrapped residuals (small
    for a tracking filter) instead of predicted bearings avoids a circular mean."""
    nu, S, _ = KERNELS.innovations(residuals, weights, np.asarray(R, dtype=float))
    return nu, S


def pose_mean_cov(poses: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`slamkit.estimation._common.weighted_pose_mean_cov` (circular heading mean, wrapped
    heading residuals), in one C pass over the particles when the kernel is available."""
    return KERNELS.pose_mean_cov(poses, weights)


# --------------------------------------------------------------------------------------------
# the five hot steps: numpy reference and fused C kernels, one of them chosen at import
# --------------------------------------------------------------------------------------------
class NumpyKernels:
    """The numpy expressions of the hot steps: the reference the C kernels are tested against
    and what runs without them (``SLAMKIT_NO_NATIVE=1`` at import, or no compiler at install)."""

    name = "numpy"

    def systematic(self, weights: np.ndarray, offset: float, n: int) -> np.ndarray:
        return _pick(_cumulative(weights), offset + np.arange(n) / n)

    def motion(self, particles: np.ndarray, u: np.ndarray, dt_s, draws: np.ndarray,
               sigma_u: np.ndarray) -> np.ndarray:
        return np.asarray(diff_drive.motion(particles, u + draws * sigma_u, dt_s), dtype=float)

    def rb_loglik(self, particles: np.ndarray, landmarks: np.ndarray, z: np.ndarray,
                  R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        z_hat = np.asarray(range_bearing.observe(particles[:, None, :], landmarks[None]), dtype=float)
        nu = z[None] - z_hat
        nu[..., 1] = _wrap_for_square(nu[..., 1])
        maha = _maha_2d(nu, R).sum(axis=1)
        return -0.5 * maha - _gaussian_log_constant(R, len(landmarks)), nu

    def innovations(self, residuals: np.ndarray, weights: np.ndarray,
                    R: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        n, m = residuals.shape[:2]
        flat = residuals.reshape(n, 2 * m)
        nu = weights @ flat
        d = flat - nu
        # all 2m x 2m weighted second moments in one BLAS product; the diagonal 2 x 2 blocks are
        # the per-measurement covariances
        M = (d * weights[:, None]).T @ d
        k = np.arange(m)
        nu, S = nu.reshape(m, 2), M.reshape(m, 2, m, 2)[k, :, k, :] + R
        return nu, S, nis_values(nu, S)

    def pose_mean_cov(self, poses: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return weighted_pose_mean_cov(poses, weights)


class NativeKernels(NumpyKernels):
    """The same steps fused in C (``_pfkernel.c``): one pass over the particles instead of ~15
    N x m numpy temporaries. Shapes the kernels do not take (an empty set, per-particle controls)
    go to the numpy expressions."""

    name = "native"

    def __init__(self, module: ModuleType):
        self.module = module

    def systematic(self, weights, offset, n):
        if n != len(weights) or n == 0:
            return super().systematic(weights, offset, n)
        # the same cumulative sum and merge as _cumulative/_pick, in one pass over sorted positions
        idx = np.empty(n, dtype=np.int64)
        self.module.systematic(_f64(weights), offset, idx)
        return idx

    def motion(self, particles, u, dt_s, draws, sigma_u):
        n = len(particles)
        if np.shape(u) != (2,) or np.ndim(dt_s) != 0 or np.shape(particles) != (n, 3):
            return super().motion(particles, u, dt_s, draws, sigma_u)
        out = np.empty((n, 3))
        self.module.motion(_f64(particles), draws, out, float(u[0]), float(u[1]), float(sigma_u[0]),
                           float(sigma_u[1]), float(dt_s))
        return out

    def rb_loglik(self, particles, landmarks, z, R):
        m = len(landmarks)
        if m == 0 or np.shape(particles)[1:] != (3,) or np.shape(z) != (m, 2) or np.shape(landmarks) != (m, 2):
            return super().rb_loglik(particles, landmarks, z, R)
        r00, r01, r10, r11 = R.ravel().tolist()
        det = r00 * r11 - r01 * r10
        n = len(particles)
        loglik, nu = np.empty(n), np.empty((n, m, 2))
        self.module.rb_loglik(_f64(particles), _f64(landmarks), _f64(z), r11 / det, -r01 / det, r00 / det,
                              _gaussian_log_constant(R, m), loglik, nu)
        return loglik, nu

    def innovations(self, residuals, weights, R):
        n, m = residuals.shape[:2]
        if n == 0 or m == 0 or residuals.shape[2:] != (2,) or np.shape(weights) != (n,):
            return super().innovations(residuals, weights, R)
        r00, r01, r10, r11 = R.ravel().tolist()
        nu, S, nis = np.empty((m, 2)), np.empty((m, 2, 2)), np.empty(m)
        # NIS from the written-out 2 x 2 inverse (np.linalg.solve on m tiny systems costs ~10 us
        # per update, a twentieth of a 1000-particle step)
        self.module.innovations(_f64(residuals), _f64(weights), m, r00, r01, r10, r11, nu, S, nis)
        return nu, S, nis

    def pose_mean_cov(self, poses, weights):
        n = len(poses)
        if n == 0 or np.shape(poses) != (n, 3) or np.shape(weights) != (n,):
            return super().pose_mean_cov(poses, weights)
        out = np.empty(12)
        self.module.pose_mean_cov(_f64(poses), _f64(weights), out)
        return out[:3].copy(), out[3:].reshape(3, 3)


def select_kernels() -> NumpyKernels:
    """The C kernels when this installation has them (and ``SLAMKIT_NO_NATIVE`` is unset), else
    the numpy expressions; both draw the same random numbers and agree to ~1e-15."""
    module = load_extension(PFKERNEL_MODULE)
    return NumpyKernels() if module is None else NativeKernels(module)


#: the implementation every function above calls, chosen once when the module is imported
KERNELS: NumpyKernels = select_kernels()


_POSE_ANGLES = np.array([False, False, True])


# --------------------------------------------------------------------------------------------
# the estimator
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ParticleFilterConfig:
    n_particles: int = 1000
    resampling: str = "systematic"
    #: resample when N_eff < ess_threshold * N (1.0 resamples after every update)
    ess_threshold: float = 0.5
    #: roughening constant K after resampling (0 disables; Gordon et al. use 0.2)
    roughening_k: float = 0.0
    #: regularised resampling (Musso, Oudjane & Le Gland 2001): resampled particles are drawn
    #: from a Gaussian kernel of covariance h_opt^2 Sigma around each copy, Sigma the covariance
    #: of the cloud before the measurement. Without it a measurement much sharper than the cloud
    #: puts all weight on one particle, the set collapses to copies of it and the reported
    #: covariance to ~0 (NEES 1e13 on the README's strong scenario).
    regularize: bool = True

    def __post_init__(self) -> None:
        if self.n_particles < 1:
            raise ConfigError(f"n_particles must be >= 1, got {self.n_particles}")
        if self.resampling not in RESAMPLERS:
            raise ConfigError(f"unknown resampling {self.resampling!r}; choose from {sorted(RESAMPLERS)}")
        if not 0.0 <= self.ess_threshold <= 1.0:
            raise ConfigError(f"ess_threshold must lie in [0, 1], got {self.ess_threshold}")


class ParticleFilterLocalization(FilterBase):
    """Bootstrap particle filter localization (registry name ``pf``) on a known landmark map.

    Measurements with an id use that landmark; id -1 uses per-particle maximum-likelihood
    association over the whole map."""

    name = "pf"
    #: per-particle range scale when it is estimated (None: ranges calibrated; MCL never sets it)
    scales: np.ndarray | None = None

    def __init__(self, world_p_landmarks: Mapping[int, np.ndarray], noise: NoiseParams = NoiseParams(),
                 config: ParticleFilterConfig = ParticleFilterConfig(),
                 rng: np.random.Generator | None = None) -> None:
        super().__init__()
        self.landmark_ids, self.landmarks = landmark_array(world_p_landmarks)
        if len(self.landmark_ids) == 0:
            raise ConfigError(f"{self.name} needs a non-empty landmark map")
        self._index = {int(i): k for k, i in enumerate(self.landmark_ids)}
        self.noise, self.config = noise, config
        self.rng = rng if rng is not None else np.random.default_rng(0)

    # -- filter steps ------------------------------------------------------------------------
    def _reset(self, prior: Prior) -> None:
        n = self.config.n_particles
        self.particles = sample_gaussian_poses(prior.world_xytheta_body, prior.covariance, n, self.rng)
        self.log_w = np.full(n, -np.log(n))
        self.n_resamples = 0
        self._rejected_ranges = 0
        # an unknown range scale (r = s |m - p|, NoiseParams.range_scale_sigma > 0): each particle
        # carries its own s, drawn from the prior N(1, sigma^2) and resampled with its pose
        sigma_s = self.noise.range_scale_sigma
        self.scales = 1.0 + sigma_s * self.rng.standard_normal(n) if sigma_s > 0 else None

    def _predict(self, odometry: Odometry) -> None:
        u = np.array([odometry.v_mps, odometry.omega_radps])
        self.particles = sample_motion(self.particles, u, odometry.dt_s, self.noise.control_cov, self.rng)

    def _measurement_log_likelihood(self, observation: RangeBearing) -> tuple[np.ndarray, int] | None:
        """(log-likelihood (N,), number of measurements used), recording NIS on the way."""
        ids, zs = observation_rows(observation)
        R = self.noise.range_bearing_cov
        # plain-Python bookkeeping over the m ids: at N = 1000 a handful of tiny numpy calls here
        # cost as much as the likelihood itself
        id_list = ids.tolist()
        rows = [k for k, i in enumerate(id_list) if i in self._index]
        n_unknown = sum(1 for i in id_list if i < 0)
        loglik = None
        if rows:
            lm = self.landmarks[[self._index[id_list[k]] for k in rows]]
            ll, residuals = range_bearing_log_likelihood(self.particles, lm,
                                                         zs if len(rows) == len(id_list) else zs[rows], R)
            loglik = ll
            weights = np.exp(self.log_w)
            self._record_nis_values(KERNELS.innovations(residuals, weights, R)[2], dof=2)
        if n_unknown:
            ml = range_bearing_log_likelihood_ml(self.particles, self.landmarks, zs[ids < 0], R)
            loglik = ml if loglik is None else loglik + ml
        used = len(rows) + n_unknown
        return (loglik, used) if used else None

    def _update(self, observation: RangeBearing) -> None:
        result = self._measurement_log_likelihood(observation)
        if result is None:
            return
        self._weigh_and_resample(*result)

    def _update_range(self, event: Range) -> None:
        """Range-only likelihood N(r; |m - p_i|, sigma_r^2) per particle i; a range is gated
        on its residual against the weighted mean pose (the rule every estimator applies)."""
        ids, ranges = range_rows(event)
        mean = self._pose_and_covariance()[0]
        scale = 1.0 if self.scales is None else float(np.exp(self.log_w) @ self.scales)
        rows = [(self._index[i], r) for i, r in zip(ids.tolist(), ranges.tolist()) if i in self._index
                and not self.noise.range_rejected(
                    r - scale * range_only.observe(mean[:2], self.landmarks[self._index[i]]))]
        self._rejected_ranges += len(ids) - len(rows)
        if not rows:
            return
        lm = self.landmarks[[k for k, _ in rows]]
        z = np.array([r for _, r in rows])
        predicted = range_only.observe(self.particles[:, None, :2], lm[None])           # (N, m)
        residual = z[None, :] - (predicted if self.scales is None else self.scales[:, None] * predicted)
        var = self.noise.sigma_range_m**2
        w = np.exp(self.log_w)
        nu = w @ residual                                       # predictive innovation (m,)
        S = w @ (residual - nu) ** 2 + var                      # its variance (m,)
        self._record_nis_values(nu**2 / S, dof=1)
        loglik = -0.5 * np.sum(residual**2, axis=1) / var - 0.5 * len(rows) * np.log(2 * np.pi * var)
        self._weigh_and_resample(loglik, len(rows))

    def _update_gps(self, gps: Gps) -> None:
        z = np.asarray(gps.world_p_body, dtype=float).reshape(-1)[:2]
        d = self.particles[:, :2] - z
        R = np.eye(2) * gps.sigma_m**2
        nu, S = predictive_innovations(-d[:, None, :], np.exp(self.log_w), R)
        self._record_nis(nu, S)
        loglik = -0.5 * np.sum(d * d, axis=1) / gps.sigma_m**2 - np.log(2 * np.pi * gps.sigma_m**2)
        self._weigh_and_resample(loglik, 1)

    def _weigh_and_resample(self, loglik: np.ndarray, n_measurements: int) -> None:
        prior_cov = pose_mean_cov(self.particles, np.exp(self.log_w))[1] if self.config.regularize else None
        self.log_w = normalize_log_weights(self.log_w + loglik)
        w = np.exp(self.log_w)
        if effective_sample_size(w) < self.config.ess_threshold * len(w):
            idx = resample(self.config.resampling, w, self.rng)
            if self.scales is not None:
                # copies of one scale stay apart by a jitter of 1% of the prior sigma
                self.scales = self.scales[idx] + (0.01 * self.noise.range_scale_sigma
                                                  * self.rng.standard_normal(len(idx)))
            self.particles = roughen(self.particles[idx], self.config.roughening_k, self.rng, _POSE_ANGLES)
            if prior_cov is not None:
                self.particles = regularize(self.particles, prior_cov, self.rng)
            self.log_w = np.full(len(idx), -np.log(len(idx)))
            self.n_resamples += 1

    def _pose_and_covariance(self) -> tuple[np.ndarray, np.ndarray]:
        return pose_mean_cov(self.particles, np.exp(self.log_w))

    def _extras(self) -> dict:
        return {"n_resamples": self.n_resamples, "n_particles_final": len(self.particles),
                "rejected_ranges": self._rejected_ranges,
                **({} if self.scales is None else {"range_scale": float(np.exp(self.log_w) @ self.scales)})}
