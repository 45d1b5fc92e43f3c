"""EKF-SLAM with range-bearing landmarks: O(n^2) updates that exploit the sparsity of H,
Mahalanobis gating, maximum-likelihood data association and landmark initialisation with the
full cross-covariance.

Smith, Self & Cheeseman (1990), "Estimating Uncertain Spatial Relationships in Robotics";
Thrun, Burgard & Fox, *Probabilistic Robotics*, Table 10.1 (known correspondences) and
Table 10.2 (maximum-likelihood correspondences, Mahalanobis gate with a new-landmark threshold).

State: x = (x_r, y_r, theta_r, m_1x, m_1y, ..., m_Lx, m_Ly), covariance P (n x n, n = 3 + 2L).
When the sequence declares its ranges' scale unknown (``NoiseParams.range_scale_sigma`` > 0, range-only
beacons: r = s |m - p|), s joins the state after the robot, x = (x_r, y_r, theta_r, s, m_1, ...),
starting at 1 with that sigma; it is static in the prediction and correlated with everything by the
range updates.

Cost per step (why it is not the textbook form):

* Predict touches only the robot block and the robot-landmark cross-covariances,
  P_rr <- F P_rr F^T + L M L^T and P_rm <- F P_rm: O(n), not the O(n^3) of F_full P F_full^T.
* A measurement of landmark j has H non-zero in 5 columns only (robot 3, landmark j 2), so
  P H^T = P[:, r] H_r^T + P[:, j] H_j^T is O(n), S = H P H^T + R is O(1), and the update
  x += K nu, P -= K S K^T = P H^T S^-1 (P H^T)^T is a rank-2 O(n^2) update. The naive
  (I - K H) P with a dense 2 x n H costs O(n^3); ``slamkit bench filters`` measures both.
* Landmark initialisation (m = g(x_r, z)) with G_r, G_z the Jacobians of g:
  P_mm = G_r P_rr G_r^T + G_z R G_z^T and P_m,: = G_r P_r,: -- the new landmark is correlated
  with the robot and, through it, with every landmark already in the map.

Storage grows by doubling, so adding landmarks costs amortised O(n^2) per landmark.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.data.estimate import Prior
from slamkit.data.sequence import Odometry, Range, RangeBearing
from slamkit.errors import ConfigError
from slamkit.estimation._common import (
    FilterBase,
    NoiseParams,
    chi2_gate,
    observation_rows,
    range_bearing_residual,
    range_rows,
)
from slamkit.geometry.angles import wrap_angle
from slamkit.models import diff_drive, range_bearing, range_only
from slamkit.models.range_only import BeaconInitialiser, DelayedInitConfig


@dataclass(frozen=True)
class EKFSLAMConfig:
    #: use RangeBearing.landmark_ids when >= 0; False ignores them and associates by maximum
    #: likelihood (measurements with id -1 are always associated by maximum likelihood)
    known_correspondences: bool = True
    #: a measurement may be associated with a landmark if its NIS is below chi2_2(gate_probability)
    gate_probability: float = 0.99
    #: ... and starts a new landmark only if its NIS to every landmark exceeds chi2_2(new_landmark_probability);
    #: in between it is ambiguous and dropped
    new_landmark_probability: float = 0.9999
    initial_capacity_landmarks: int = 32
    #: range-only beacons: when one is initialised from its buffered ranges (delayed
    #: initialisation, the rule every range-only estimator shares)
    range_init: DelayedInitConfig = DelayedInitConfig()

    def __post_init__(self) -> None:
        if not 0 < self.gate_probability <= self.new_landmark_probability < 1:
            raise ConfigError("need 0 < gate_probability <= new_landmark_probability < 1, got "
                              f"{self.gate_probability}, {self.new_landmark_probability}")


def _rank1_downdate(A: np.ndarray, w: np.ndarray) -> None:
    """A -= w w^T in place (one elementwise pass, exactly symmetric). Plain numpy on purpose:
    BLAS dger is as fast single-threaded but collapses under thread oversubscription on a busy
    machine (measured 0.16 ms vs 15 ms at n = 1003), while this stays at ~1-2 ms."""
    np.subtract(A, w[:, None] * w[None, :], out=A)


def sparse_update(x: np.ndarray, P: np.ndarray, n: int, j: int, z: np.ndarray, R: np.ndarray,
                  ) -> tuple[np.ndarray, np.ndarray]:
    """In-place EKF update of x[:n], P[:n, :n] with one range-bearing measurement z of the landmark
    whose state starts at index j. O(n^2). Returns (nu, S) for NIS."""
    xr, m = x[:3], x[j:j + 2]
    z_hat = range_bearing.observe(xr, m)
    Hr, Hm = range_bearing.observe_jacobians(xr, m)
    PHt = P[:n, :3] @ Hr.T + P[:n, j:j + 2] @ Hm.T          # (n, 2), O(n)
    S = Hr @ PHt[:3] + Hm @ PHt[j:j + 2] + R                # (2, 2)
    nu = range_bearing_residual(z, z_hat)
    # K S K^T = P H^T S^-1 H P = W W^T with W = P H^T L^-T, S = L L^T: two symmetric rank-1
    # downdates, each exactly symmetric, done in place (no n x n temporary, no clean-up pass).
    L = np.linalg.cholesky(S)
    W = np.linalg.solve(L, PHt.T).T                          # (n, 2)
    x[:n] += W @ np.linalg.solve(L, nu)                      # K nu = W L^-1 nu
    x[2] = wrap_angle(x[2])
    _rank1_downdate(P[:n, :n], W[:, 0])                      # O(n^2)
    _rank1_downdate(P[:n, :n], W[:, 1])
    return nu, S


def sparse_range_update(x: np.ndarray, P: np.ndarray, n: int, j: int, r: float, variance: float,
                        scale_index: int | None = None) -> tuple[float, float]:
    """In-place EKF update of x[:n], P[:n, :n] with one range r to the landmark at index j:
    H is non-zero in the robot's (x, y) and the landmark's 2 columns (and the range scale's,
    r = s |m - p|, when ``scale_index`` holds s), so it is the same O(n^2) rank-1 update as
    :func:`sparse_update`. Returns (nu, S) for NIS."""
    s = 1.0 if scale_index is None else float(x[scale_index])
    Hp, Hm, distance = range_only.observe_scaled_jacobians(x[:2], x[j:j + 2], s)
    PHt = P[:n, :2] @ Hp + P[:n, j:j + 2] @ Hm               # (n,)
    if scale_index is not None:
        PHt += P[:n, scale_index] * distance
    S = float(Hp @ PHt[:2] + Hm @ PHt[j:j + 2] + variance)
    if scale_index is not None:
        S += float(distance * PHt[scale_index])
    nu = float(r - s * distance)
    W = PHt / np.sqrt(S)
    x[:n] += W * (nu / np.sqrt(S))
    x[2] = wrap_angle(x[2])
    _rank1_downdate(P[:n, :n], W)
    return nu, S


def dense_update(x: np.ndarray, P: np.ndarray, j: int, z: np.ndarray, R: np.ndarray,
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The naive textbook update on the full state (dense 2 x n H, P <- (I - K H) P): O(n^3).
    Kept as the reference the benchmark and the tests compare :func:`sparse_update` against."""
    n = len(x)
    xr, m = x[:3], x[j:j + 2]
    z_hat = range_bearing.observe(xr, m)
    Hr, Hm = range_bearing.observe_jacobians(xr, m)
    H = np.zeros((2, n))
    H[:, :3], H[:, j:j + 2] = Hr, Hm
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    x_new = x + K @ range_bearing_residual(z, z_hat)
    x_new[2] = wrap_angle(x_new[2])
    return x_new, (np.eye(n) - K @ H) @ P


class EKFSLAM(FilterBase):
    """EKF-SLAM (registry name ``ekf_slam``)."""

    name = "ekf_slam"

    def __init__(self, noise: NoiseParams = NoiseParams(), config: EKFSLAMConfig = EKFSLAMConfig()) -> None:
        super().__init__()
        self.noise, self.config = noise, config
        self._gate = chi2_gate(config.gate_probability, 2)
        self._new = chi2_gate(config.new_landmark_probability, 2)

    # -- state storage ---------------------------------------------------------------------
    def _reset(self, prior: Prior) -> None:
        cap = 4 + 2 * max(self.config.initial_capacity_landmarks, 1)
        self.x = np.zeros(cap)
        self.P = np.zeros((cap, cap))
        self.x[:3] = prior.world_xytheta_body
        self.P[:3, :3] = prior.covariance
        # the unknown range scale (when declared) sits after the robot; landmarks from _m0 on
        self._scale_index = 3 if self.noise.range_scale_sigma > 0 else None
        self._m0 = 3 if self._scale_index is None else 4
        if self._scale_index is not None:
            self.x[3], self.P[3, 3] = 1.0, self.noise.range_scale_sigma**2
        self.n = self._m0
        self.slot_ids: list[int] = []        # landmark id of each slot
        self._slot_of: dict[int, int] = {}   # known id -> slot
        # ids for landmarks found by association; clear of the sequence's ids when those are used
        self._next_id = 1_000_000 if self.config.known_correspondences else 0
        self._rejected = 0
        self._ambiguous = 0
        self._rejected_ranges = 0
        self._beacons = BeaconInitialiser(self.config.range_init, self.noise.sigma_range_m)

    def _grow(self) -> None:
        cap = len(self.x)
        if self.n + 2 <= cap:
            return
        new_cap = self._m0 + 2 * (2 * ((cap - self._m0) // 2))
        x = np.zeros(new_cap)
        P = np.zeros((new_cap, new_cap))
        x[:self.n] = self.x[:self.n]
        P[:self.n, :self.n] = self.P[:self.n, :self.n]
        self.x, self.P = x, P

    @property
    def num_landmarks(self) -> int:
        return (self.n - self._m0) // 2

    # -- filter steps ------------------------------------------------------------------------
    def _predict(self, odometry: Odometry) -> None:
        u = np.array([odometry.v_mps, odometry.omega_radps])
        n = self.n
        F, L = diff_drive.motion_jacobians(self.x[:3], u, odometry.dt_s)
        self.x[:3] = diff_drive.motion(self.x[:3], u, odometry.dt_s)
        P = self.P
        P[:3, :3] = F @ P[:3, :3] @ F.T + L @ self.noise.control_cov @ L.T
        if n > 3:
            P[:3, 3:n] = F @ P[:3, 3:n]
            P[3:n, :3] = P[:3, 3:n].T

    def _add_landmark(self, z: np.ndarray, landmark_id: int) -> None:
        self._grow()
        n, xr = self.n, self.x[:3]
        m = range_bearing.inverse_observe(xr, z)
        Gr, Gz = range_bearing.inverse_observe_jacobians(xr, z)
        P = self.P
        cross = Gr @ P[:3, :n]                                            # (2, n)
        P[n:n + 2, :n] = cross
        P[:n, n:n + 2] = cross.T
        P[n:n + 2, n:n + 2] = Gr @ P[:3, :3] @ Gr.T + Gz @ self.noise.range_bearing_cov @ Gz.T
        self.x[n:n + 2] = m
        self.n = n + 2
        self.slot_ids.append(landmark_id)

    def association_distances(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Squared Mahalanobis distance (L,) of measurement z to every landmark in the map, and
        log|S| (L,), vectorised over landmarks from the 2 x 2 and 3 x 2 covariance blocks."""
        L = self.num_landmarks
        n, xr = self.n, self.x[:3]
        m0 = self._m0
        lm = self.x[m0:n].reshape(L, 2)
        z_hat = range_bearing.observe(np.broadcast_to(xr, (L, 3)), lm)
        Hr, Hm = range_bearing.observe_jacobians(np.broadcast_to(xr, (L, 3)), lm)
        P = self.P
        Prr = P[:3, :3]
        Prm = P[:3, m0:n].reshape(3, L, 2).transpose(1, 0, 2)              # (L, 3, 2)
        k = np.arange(L)
        Pmm = P[m0:n, m0:n].reshape(L, 2, L, 2)[k, :, k, :]                 # (L, 2, 2)
        cross = Hr @ Prm @ Hm.transpose(0, 2, 1)
        S = (Hr @ Prr @ Hr.transpose(0, 2, 1) + cross + cross.transpose(0, 2, 1)
             + Hm @ Pmm @ Hm.transpose(0, 2, 1) + self.noise.range_bearing_cov)
        nu = range_bearing_residual(np.broadcast_to(z, z_hat.shape).copy(), z_hat)
        d2 = np.einsum("li,li->l", nu, np.linalg.solve(S, nu[..., None])[..., 0])
        return d2, np.log(np.linalg.det(S))

    def _update(self, observation: RangeBearing) -> None:
        ids, zs = observation_rows(observation)
        R = self.noise.range_bearing_cov
        for lid, z in zip(ids.tolist(), zs):
            if self.config.known_correspondences and lid >= 0:
                slot = self._slot_of.get(lid)
                if slot is None:
                    self._slot_of[lid] = self.num_landmarks
                    self._add_landmark(z, lid)
                    continue
            else:
                slot = self._associate(z)
                if slot is None:
                    continue
            nu, S = sparse_update(self.x, self.P, self.n, self._m0 + 2 * slot, z, R)
            self._record_nis(nu, S)

    def _update_range(self, event: Range) -> None:
        """Range-only beacons (known ids): a mapped beacon updates the state after the range
        gate; an unmapped one buffers the range until :class:`BeaconInitialiser` trilaterates
        it, then enters the state with the trilateration's covariance plus the robot's position
        covariance (its cross-covariances start at zero: the buffered ranges came from past
        poses the filter no longer holds)."""
        ids, ranges = range_rows(event)
        var = self.noise.sigma_range_m**2
        scale = 1.0 if self._scale_index is None else float(self.x[self._scale_index])
        for lid, r in zip(ids.tolist(), ranges.tolist()):
            if lid < 0:
                # range-only needs the beacon's identity (no association from a range alone)
                self._rejected_ranges += 1
                continue
            slot = self._slot_of.get(lid)
            if slot is None:
                fix = self._beacons.add(lid, self.x[:2], r / scale)
                if fix is not None:
                    self._add_beacon(lid, fix)
                continue
            j = self._m0 + 2 * slot
            if self.noise.range_rejected(r - scale * range_only.observe(self.x[:2], self.x[j:j + 2])):
                self._rejected_ranges += 1
                continue
            nu, S = sparse_range_update(self.x, self.P, self.n, j, r, var, self._scale_index)
            scale = 1.0 if self._scale_index is None else float(self.x[self._scale_index])
            self._record_nis(np.array([nu]), np.array([[S]]))

    def _add_beacon(self, lid: int, fix) -> None:
        """A trilaterated beacon enters the state (see :meth:`_update_range`). With an estimated
        range scale s the trilateration used the ranges divided by s, m = g(s): the beacon is
        correlated with s (and through it with the rest) by G_s = dm/ds = (J^T J)^-1 J^T d(r/s)/ds,
        J the range Jacobians at the beacon, d(r/s)/ds = -(r/s)/s."""
        self._grow()
        n = self.n
        world_p = fix.trilateration.world_p_landmark
        self.P[n:n + 2, :n] = 0.0
        self.P[:n, n:n + 2] = 0.0
        self.P[n:n + 2, n:n + 2] = fix.covariance + self.P[:2, :2]
        si = self._scale_index
        if si is not None:
            J = range_only.observe_jacobians(fix.world_p_body, world_p)[1]          # (K, 2)
            G_s = np.linalg.pinv(J) @ (-fix.range_m / self.x[si])                  # (2,)
            cross = G_s[:, None] * self.P[si, :n][None, :]                          # (2, n)
            self.P[n:n + 2, :n] = cross
            self.P[:n, n:n + 2] = cross.T
            self.P[n:n + 2, n:n + 2] += np.outer(G_s, G_s) * self.P[si, si]
        self.x[n:n + 2] = world_p
        self.n = n + 2
        self._slot_of[lid] = len(self.slot_ids)
        self.slot_ids.append(lid)

    def _associate(self, z: np.ndarray) -> int | None:
        """Maximum-likelihood landmark for z inside the gate; creates a new landmark (returns
        None) when z is far from all; drops it (None) when ambiguous."""
        if self.num_landmarks:
            d2, log_det = self.association_distances(z)
            inside = d2 < self._gate
            if inside.any():
                cost = np.where(inside, d2 + log_det, np.inf)
                return int(np.argmin(cost))
            if d2.min() < self._new:
                self._ambiguous += 1
                return None
        self._add_landmark(z, self._next_id)
        self._next_id += 1
        return None

    # -- outputs ---------------------------------------------------------------------------
    def _pose_and_covariance(self) -> tuple[np.ndarray, np.ndarray]:
        return self.x[:3].copy(), self.P[:3, :3].copy()

    def _landmarks(self) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
        pos, cov = {}, {}
        for k, lid in enumerate(self.slot_ids):
            j = self._m0 + 2 * k
            pos[int(lid)] = self.x[j:j + 2].copy()
            cov[int(lid)] = self.P[j:j + 2, j:j + 2].copy()
        return pos, cov

    def _extras(self) -> dict:
        return {"num_landmarks": self.num_landmarks, "ambiguous_measurements": self._ambiguous,
                "rejected_ranges": self._rejected_ranges,
                "uninitialised_beacons": len(self._beacons.pending()),
                **({} if self._scale_index is None else {"range_scale": float(self.x[self._scale_index])})}
