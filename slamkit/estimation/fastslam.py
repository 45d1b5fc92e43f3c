"""FastSLAM 1.0: a particle filter over robot paths with one 2 x 2 EKF per landmark per
particle, vectorised over particles.

Montemerlo, Thrun, Koller & Wegbreit (2002), "FastSLAM: A Factored Solution to the
Simultaneous Localization and Mapping Problem"; Thrun, Burgard & Fox, *Probabilistic
Robotics*, Table 13.1 (known correspondences) and Table 13.2 (unknown correspondences:
per-particle maximum-likelihood association with a new-landmark threshold).

Rao-Blackwellisation: given a particle's path the landmarks are independent, so each particle
carries L small Gaussians instead of one 2L x 2L covariance. Arrays: poses (P, 3), landmark
means (P, L, 2), covariances (P, L, 2, 2), landmark counts (P,). One measurement is processed
for all particles at once:

    z_hat = h(x_p, mu_pj),  H = dh/dm,  S = H Sigma H^T + R,  K = Sigma H^T S^-1
    mu_pj += K nu,  Sigma_pj = (I - K H) Sigma (I - K H)^T + K R K^T   (Joseph form)
    log w_p += log N(nu; 0, S)                                        (importance weight)

New landmarks are initialised by the inverse model with Sigma = G_z R G_z^T, which equals
H^-1 R H^-T of Table 13.1 line 7. Resampling (systematic, when N_eff < threshold N) copies whole
maps by fancy indexing. Under unknown correspondences a particle associates a measurement with
its most likely landmark if that lies inside the chi-square gate and otherwise starts a new one;
the new-landmark importance weight is the likelihood at the gate boundary (the p_0 of Table
13.2 made continuous with the association branch).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.data.estimate import Prior
from slamkit.data.sequence import Odometry, RangeBearing
from slamkit.errors import ConfigError
from slamkit.estimation._common import (
    FilterBase,
    NoiseParams,
    chi2_gate,
    observation_rows,
    weighted_pose_mean_cov,
)
from slamkit.estimation.particle_filter import (
    RESAMPLERS,
    effective_sample_size,
    normalize_log_weights,
    resample,
    sample_gaussian_poses,
    sample_motion,
)
from slamkit.geometry.angles import wrap_angle
from slamkit.models import range_bearing


@dataclass(frozen=True)
class FastSLAMConfig:
    n_particles: int = 100
    known_correspondences: bool = True
    resampling: str = "systematic"
    ess_threshold: float = 0.5
    #: unknown correspondences: a particle associates a measurement with its most likely
    #: landmark when the NIS is below chi2_2(gate_probability), else starts a new landmark. Set
    #: high: the per-particle S ignores pose uncertainty, so a tight gate multiplies landmarks.
    gate_probability: float = 0.99999
    initial_capacity_landmarks: int = 32

    def __post_init__(self) -> None:
        if self.n_particles < 1:
            raise ConfigError(f"n_particles must be >= 1, got {self.n_particles}")
        if self.resampling not in RESAMPLERS:
            raise ConfigError(f"unknown resampling {self.resampling!r}; choose from {sorted(RESAMPLERS)}")


def _sandwich(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A B A^T for stacks of small matrices."""
    return A @ B @ np.swapaxes(A, -1, -2)


def _inv2(S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form inverse and determinant of a stack of 2 x 2 matrices (..., 2, 2)."""
    a, b, c, d = S[..., 0, 0], S[..., 0, 1], S[..., 1, 0], S[..., 1, 1]
    det = a * d - b * c
    inv = np.stack([np.stack([d, -b], -1), np.stack([-c, a], -1)], -2) / det[..., None, None]
    return inv, det


class FastSLAM(FilterBase):
    """FastSLAM 1.0 (registry name ``fastslam``)."""

    name = "fastslam"

    def __init__(self, noise: NoiseParams = NoiseParams(), config: FastSLAMConfig = FastSLAMConfig(),
                 rng: np.random.Generator | None = None) -> None:
        super().__init__()
        self.noise, self.config = noise, config
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self._gate = chi2_gate(config.gate_probability, 2)

    # -- storage -------------------------------------------------------------------------------
    def _reset(self, prior: Prior) -> None:
        P, cap = self.config.n_particles, max(self.config.initial_capacity_landmarks, 1)
        self.poses = sample_gaussian_poses(prior.world_xytheta_body, prior.covariance, P, self.rng)
        self.log_w = np.full(P, -np.log(P))
        self.mu = np.zeros((P, cap, 2))
        self.sigma = np.tile(np.eye(2), (P, cap, 1, 1))
        self.count = np.zeros(P, dtype=np.int64)
        self._slot_of: dict[int, int] = {}   # known correspondences: id -> slot (shared)
        self.n_resamples = 0
        self._dropped = 0

    def _ensure_capacity(self, needed: int) -> None:
        cap = self.mu.shape[1]
        if needed <= cap:
            return
        new_cap = max(needed, 2 * cap)
        P = len(self.poses)
        mu = np.zeros((P, new_cap, 2))
        sigma = np.tile(np.eye(2), (P, new_cap, 1, 1))
        mu[:, :cap], sigma[:, :cap] = self.mu, self.sigma
        self.mu, self.sigma = mu, sigma

    # -- filter steps --------------------------------------------------------------------------
    def _predict(self, odometry: Odometry) -> None:
        u = np.array([odometry.v_mps, odometry.omega_radps])
        self.poses = sample_motion(self.poses, u, odometry.dt_s, self.noise.control_cov, self.rng)

    def _update(self, observation: RangeBearing) -> None:
        ids, zs = observation_rows(observation)
        if len(ids) == 0:
            return
        for lid, z in zip(ids.tolist(), zs):
            if not self.config.known_correspondences:
                self._update_unknown(z)
            elif lid >= 0:
                self._update_known(lid, z)
            else:
                # known-correspondence mode keeps one shared slot layout, which a per-particle
                # association would break: unlabelled measurements are dropped (and counted)
                self._dropped += 1
        self.log_w = normalize_log_weights(self.log_w)
        w = np.exp(self.log_w)
        if effective_sample_size(w) < self.config.ess_threshold * len(w):
            idx = resample(self.config.resampling, w, self.rng)
            self.poses, self.mu, self.sigma, self.count = (
                self.poses[idx], self.mu[idx], self.sigma[idx], self.count[idx])
            self.log_w = np.full(len(idx), -np.log(len(idx)))
            self.n_resamples += 1

    def _initialise(self, rows: np.ndarray, slots: np.ndarray, z: np.ndarray) -> None:
        """Start landmark ``slots`` (k,) of particles ``rows`` (k,) from measurement z."""
        poses = self.poses[rows]
        self.mu[rows, slots] = range_bearing.inverse_observe(poses, np.broadcast_to(z, (len(rows), 2)))
        _, Gz = range_bearing.inverse_observe_jacobians(poses, np.broadcast_to(z, (len(rows), 2)))
        self.sigma[rows, slots] = Gz @ self.noise.range_bearing_cov @ Gz.transpose(0, 2, 1)

    def _ekf_update(self, rows: np.ndarray, slots: np.ndarray, z: np.ndarray,
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per-particle landmark EKF update; returns (log-likelihood (k,), nu (k, 2), S (k, 2, 2))."""
        R = self.noise.range_bearing_cov
        poses, m, Sig = self.poses[rows], self.mu[rows, slots], self.sigma[rows, slots]
        z_hat = range_bearing.observe(poses, m)
        _, H = range_bearing.observe_jacobians(poses, m)
        S = _sandwich(H, Sig) + R
        S_inv, S_det = _inv2(S)
        K = Sig @ H.transpose(0, 2, 1) @ S_inv          # Sigma H^T S^-1
        nu = z - z_hat
        nu[:, 1] = wrap_angle(nu[:, 1])
        self.mu[rows, slots] = m + np.einsum("kij,kj->ki", K, nu)
        I_KH = np.eye(2) - K @ H
        self.sigma[rows, slots] = _sandwich(I_KH, Sig) + _sandwich(K, R)
        maha = np.einsum("ki,kij,kj->k", nu, S_inv, nu)
        return -0.5 * maha - 0.5 * np.log(S_det) - np.log(2 * np.pi), nu, S

    def _update_known(self, lid: int, z: np.ndarray) -> None:
        P = len(self.poses)
        rows = np.arange(P)
        slot = self._slot_of.get(lid)
        if slot is None:
            slot = len(self._slot_of)
            self._slot_of[lid] = slot
            self._ensure_capacity(slot + 1)
            self._initialise(rows, np.full(P, slot), z)
            self.count[:] = len(self._slot_of)
            return
        w = np.exp(self.log_w - self.log_w.max())
        w /= w.sum()
        loglik, nu, S = self._ekf_update(rows, np.full(P, slot), z)
        self.log_w = self.log_w + loglik
        # NIS of the particle mixture's predictive distribution of z (moment-matched)
        nu_bar = w @ nu
        d = nu - nu_bar
        S_bar = np.einsum("p,pij->ij", w, S) + np.einsum("p,pi,pj->ij", w, d, d)
        self._record_nis(nu_bar, S_bar)

    def _update_unknown(self, z: np.ndarray) -> None:
        P = len(self.poses)
        rows = np.arange(P)
        L = int(self.count.max())
        R = self.noise.range_bearing_cov
        if L > 0:
            m, Sig = self.mu[:, :L], self.sigma[:, :L]
            z_hat = range_bearing.observe(self.poses[:, None, :], m)                 # (P, L, 2)
            _, H = range_bearing.observe_jacobians(self.poses[:, None, :], m)
            S = _sandwich(H, Sig) + R
            S_inv, S_det = _inv2(S)
            nu = z - z_hat
            nu[..., 1] = wrap_angle(nu[..., 1])
            d2 = (nu[..., None, :] @ S_inv @ nu[..., :, None])[..., 0, 0]
            d2 = np.where(np.arange(L)[None] < self.count[:, None], d2, np.inf)
            cost = d2 + np.log(S_det)
            best = np.argmin(cost, axis=1)
            best_d2 = d2[rows, best]
            associate = best_d2 < self._gate
        else:
            best = np.zeros(P, dtype=np.int64)
            associate = np.zeros(P, dtype=bool)
        loglik = np.zeros(P)
        if associate.any():
            r = rows[associate]
            loglik[associate], _, _ = self._ekf_update(r, best[associate], z)
        new = ~associate
        if new.any():
            r = rows[new]
            if L > 0:
                # likelihood at the gate boundary with the best candidate's S (p_0, see module doc)
                loglik[new] = (-0.5 * self._gate - 0.5 * np.log(S_det[r, best[new]]) - np.log(2 * np.pi))
            self._ensure_capacity(int(self.count[r].max()) + 1)
            self._initialise(r, self.count[r], z)
            self.count[r] += 1
        self.log_w = self.log_w + loglik

    # -- outputs -------------------------------------------------------------------------------
    def _pose_and_covariance(self) -> tuple[np.ndarray, np.ndarray]:
        return weighted_pose_mean_cov(self.poses, np.exp(self.log_w))

    def _landmarks(self) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
        w = np.exp(self.log_w - self.log_w.max())
        w /= w.sum()
        pos, cov = {}, {}
        if self._slot_of:
            # known correspondences: moments of the particle mixture of each landmark
            for lid, slot in self._slot_of.items():
                m = self.mu[:, slot]
                mean = w @ m
                d = m - mean
                pos[lid] = mean
                cov[lid] = np.einsum("p,pij->ij", w, self.sigma[:, slot]) + (d * w[:, None]).T @ d
        else:
            # unknown correspondences: slots differ between particles; report the map of the
            # most probable particle, keyed by slot
            best = int(np.argmax(w))
            for k in range(int(self.count[best])):
                pos[k] = self.mu[best, k].copy()
                cov[k] = self.sigma[best, k].copy()
        return pos, cov

    def _extras(self) -> dict:
        return {"n_resamples": self.n_resamples, "num_landmarks_max": int(self.count.max()),
                "dropped_unlabelled_measurements": self._dropped}
