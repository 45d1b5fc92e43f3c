"""Error-state extended Kalman filter for GPS-aided inertial navigation (15 states).

The filter keeps a nominal navigation state (position, velocity, attitude, accelerometer and gyro
biases) integrated with the IMU by :func:`slamkit.models.strapdown.propagate`, and a Gaussian on
the 15-dimensional error state dx = (dp, dv, dtheta, dba, dbg) with a world-frame attitude error
R_true = Exp(dtheta) R (Sola, "Quaternion kinematics for the error-state Kalman filter",
arXiv:1711.02508, 2017, sec. 6-7; Farrell, *Aided Navigation*, 2008, ch. 11). Per IMU event:

    nominal step (strapdown.propagate), P <- F P F^T + Q_d     (strapdown.error_transition,
                                                                  strapdown.process_noise)

Per GPS fix z (world position, sigma per axis): h(x) = p, H = [I 0 0 0 0], a Joseph-form update,
injection of dx into the nominal state (attitude R <- Exp(dtheta) R), and the reset P <- G P G^T
with G = I + hat(dtheta / 2) on the attitude block (Sola eq. 287, global error).

Time: an Imu event holds its reading over the interval that ends at its stamp
(:mod:`slamkit.data.inertial`); a GPS fix stamped after the last IMU event is applied after
holding the last reading up to the fix (and the next IMU interval starts there), a late fix is
applied at the current time and counted in ``extras["late_gps"]``.

The start state, its covariance and the noise are the sequence's
:class:`~slamkit.data.inertial.InertialSetup` (the planar ``Prior`` of ``reset`` has no velocity
or biases and is not used). ``estimate()`` returns the filtered pose at every
IMU event with its (6, 6) covariance in the runner's convention (position, then the world-frame
rotation error), and in ``extras`` the velocity, the bias estimates and their sigmas.

The hot loop avoids general 15 x 15 products: F = I + dF has non-zero off-diagonal blocks in the
first nine rows only, so F P F^T is two thin products, (9, 15) x (15, 15) and (15, 15) x (15, 9),
and Q_d is added on its diagonal blocks. That step runs fused in C (``_eskfkernel.c``, compiled
when slamkit is installed, loaded through :mod:`slamkit._native`); :meth:`ErrorStateEKF._propagate_numpy`
is the same arithmetic in numpy, used without the kernel (``SLAMKIT_NO_NATIVE=1``) and checked
against it in the tests. The nominal state lives in one flat array ``x`` = (p, v, R row-major,
b_a, b_g) so the kernel can update it in place.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from slamkit._native import load_extension
from slamkit.data.estimate import Estimate, Prior, check_covariance
from slamkit.data.inertial import InertialEventLoop, InertialSetup, setup_of
from slamkit.data.sequence import Sequence
from slamkit.data.trajectory import Trajectory
from slamkit.errors import ConfigError, EstimationError
from slamkit.geometry import so3
from slamkit.models import strapdown

_I3 = np.eye(3)
#: the compiled IMU step (``_eskfkernel.c``)
KERNEL_MODULE = "slamkit.estimation._eskfkernel"
#: rows and columns of the pose (position, attitude) inside the error state
_POSE = np.ix_(np.r_[0:3, 6:9], np.r_[0:3, 6:9])
#: what _record keeps of P, as flat indices: the 6 x 6 pose block, then the 6 bias variances
_RECORD = np.concatenate([(np.r_[0:3, 6:9][:, None] * 15 + np.r_[0:3, 6:9][None, :]).ravel(),
                          np.arange(9, 15) * 16])


@dataclass(frozen=True)
class ErrorStateEKFConfig:
    """``imu_noise`` (fields of :class:`~slamkit.models.imu.ImuNoise`) and ``gps_sigma_m``
    override what the sequence declares (None: the sequence's). ``max_imu_gap_s``: longer gaps
    between IMU events are still integrated but counted (``extras["imu_gaps"]``)."""

    imu_noise: Mapping[str, float] | None = None
    gps_sigma_m: float | None = None
    max_imu_gap_s: float = 0.1
    #: record the pose covariance at every IMU event (the NEES needs it)
    record_covariances: bool = True

    def __post_init__(self) -> None:
        if self.gps_sigma_m is not None and not (np.isfinite(self.gps_sigma_m) and self.gps_sigma_m > 0):
            raise ConfigError(f"gps_sigma_m must be positive, got {self.gps_sigma_m}")
        if not self.max_imu_gap_s > 0:
            raise ConfigError(f"max_imu_gap_s must be positive, got {self.max_imu_gap_s}")


def _exp_so3(phi: np.ndarray) -> np.ndarray:
    """Rodrigues for one vector with scalar math (so3.exp is batch-first and ~10x slower here)."""
    x, y, z = float(phi[0]), float(phi[1]), float(phi[2])
    t2 = x * x + y * y + z * z
    if t2 < 1e-8:
        a, b = 1.0 - t2 / 6.0, 0.5 - t2 / 24.0
    else:
        t = math.sqrt(t2)
        a, b = math.sin(t) / t, (1.0 - math.cos(t)) / t2
    return np.array([[1.0 - b * (y * y + z * z), b * x * y - a * z, b * x * z + a * y],
                     [b * x * y + a * z, 1.0 - b * (x * x + z * z), b * y * z - a * x],
                     [b * x * z - a * y, b * y * z + a * x, 1.0 - b * (x * x + y * y)]])


def _hat(v: np.ndarray) -> np.ndarray:
    x, y, z = float(v[0]), float(v[1]), float(v[2])
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


class ErrorStateEKF(InertialEventLoop):
    """The 15-state ES-EKF (registry name ``es_ekf``); see the module docstring. ``step`` is
    :class:`~slamkit.data.inertial.InertialEventLoop`'s: IMU readings go to :meth:`_integrate`,
    fixes to :meth:`_fix`."""

    name = "es_ekf"

    def __init__(self, setup: InertialSetup, config: ErrorStateEKFConfig | None = None) -> None:
        self.setup = setup
        self.config = config or ErrorStateEKFConfig()
        self.max_imu_gap_s = self.config.max_imu_gap_s
        self._ready = False

    @classmethod
    def from_sequence(cls, sequence: Sequence, config: ErrorStateEKFConfig | None = None) -> "ErrorStateEKF":
        config = config or ErrorStateEKFConfig()
        return cls(setup_of(sequence, imu_noise=config.imu_noise, gps_sigma_m=config.gps_sigma_m), config)

    # the nominal state as views into x (x is updated in place, by the kernel or numpy)
    @property
    def p(self) -> np.ndarray:
        return self._x[0:3]

    @property
    def v(self) -> np.ndarray:
        return self._x[3:6]

    @property
    def R(self) -> np.ndarray:
        return self._x[6:15].reshape(3, 3)

    @property
    def ba(self) -> np.ndarray:
        return self._x[15:18]

    @property
    def bg(self) -> np.ndarray:
        return self._x[18:21]

    # -- protocol --------------------------------------------------------------------------------
    def reset(self, prior: Prior | None = None) -> None:
        s = self.setup.initial
        self._start_loop(s.stamp_s)
        self._x = np.concatenate([s.world_p_body, s.world_v_body, s.world_R_body.reshape(9),
                                  s.accel_bias_mps2, s.gyro_bias_radps])
        self.P = np.ascontiguousarray(self.setup.initial_covariance)
        check_covariance(self.P, f"{self.name}: initial covariance")
        self.g = self.setup.gravity_mps2
        n = self.setup.imu_noise
        self._q = (n.accel_noise_density**2, n.gyro_noise_density**2, n.accel_bias_random_walk**2,
                   n.gyro_bias_random_walk**2)
        self._kernel = load_extension(KERNEL_MODULE)
        # one row per recorded state (copies: x and P change in place); estimate() stacks them
        self._stamps: list[float] = []
        self._xs: list[np.ndarray] = []
        self._ps: list[np.ndarray] = []
        self._record()
        self._nis: list[float] = []
        self._ready = True

    def estimate(self) -> Estimate:
        if not self._ready:
            raise EstimationError(f"{self.name}: estimate() called before reset(prior)")
        stamps = np.array(self._stamps)
        x = np.array(self._xs)
        kept = np.array(self._ps)
        traj = Trajectory(stamps, x[:, 0:3], so3.to_quat_wxyz(x[:, 6:15].reshape(-1, 3, 3)))
        return Estimate(
            trajectory=traj,
            pose_covariances=kept[:, :36].reshape(-1, 6, 6) if self.config.record_covariances else None,
            nis=np.array(self._nis), nis_dof=np.full(len(self._nis), 3),
            step_latency_s=np.array(self._latency),
            extras={**self._counts, "bias": x[:, 15:21],
                    "bias_sigma": np.sqrt(np.clip(kept[:, -6:], 0.0, None)),
                    "world_v_body": x[:, 3:6], "bias_stamps_s": stamps})

    def latest_estimate(self) -> Estimate:
        """The newest pose and its covariance alone (constant cost; for observers)."""
        traj = Trajectory([self.t], self.p[None], so3.to_quat_wxyz(self.R)[None])
        return Estimate(trajectory=traj, pose_covariances=self.P[_POSE][None])

    # -- internals -------------------------------------------------------------------------------
    def _after_imu(self) -> None:
        self._record()

    def _record(self) -> None:
        """Keep the state at ``t``: x and (one take) the pose covariance and bias variances."""
        self._stamps.append(self.t)
        self._xs.append(self._x.copy())
        self._ps.append(self.P.take(_RECORD) if self.config.record_covariances else self.P.take(_RECORD[36:]))

    def _integrate(self, accel_m: np.ndarray, gyro_m: np.ndarray, dt: float) -> None:
        kernel = self._kernel
        if kernel is not None and type(accel_m) is np.ndarray and accel_m.dtype == np.float64 \
                and accel_m.flags.c_contiguous and type(gyro_m) is np.ndarray and gyro_m.dtype == np.float64 \
                and gyro_m.flags.c_contiguous:
            g = self.g
            if not kernel.propagate(self._x, self.P, accel_m, gyro_m, dt, g[0], g[1], g[2], *self._q):
                raise EstimationError(f"{self.name}: Imu at t={self.t + dt}: a reading is not finite")
            return
        accel_m = np.asarray(accel_m, dtype=float).reshape(3)
        gyro_m = np.asarray(gyro_m, dtype=float).reshape(3)
        if not (np.isfinite(accel_m).all() and np.isfinite(gyro_m).all()):
            raise EstimationError(f"{self.name}: Imu at t={self.t + dt}: a reading is not finite")
        self._propagate_numpy(accel_m, gyro_m, dt)

    def _propagate_numpy(self, accel_m: np.ndarray, gyro_m: np.ndarray, dt: float) -> None:
        """The kernel's arithmetic in numpy (updates x and P in place)."""
        a = accel_m - self.ba
        w = gyro_m - self.bg
        R = self.R.copy()
        Ra = R @ a
        world_a = Ra + self.g
        R_next = R @ _exp_so3(w * dt)
        # J_r(w dt) ~ I - hat(w dt)/2 to second order is enough for one IMU interval
        RJr = R_next @ (_I3 - 0.5 * _hat(w * dt))
        # dF: the off-identity part of F (strapdown.error_transition), rows 0..8 only
        dF = np.zeros((9, 15))
        hRa = _hat(Ra)
        h2 = 0.5 * dt * dt
        dF[0:3, 3:6] = _I3 * dt
        dF[0:3, 6:9] = -h2 * hRa
        dF[0:3, 9:12] = -h2 * R
        dF[3:6, 6:9] = -dt * hRa
        dF[3:6, 9:12] = -dt * R
        dF[6:9, 12:15] = -dt * RJr
        P = self.P
        A = P.copy()
        A[:9] += dF @ P                      # F P
        A[:, :9] += A @ dF.T                 # (F P) F^T
        qa, qg, qba, qbg = self._q
        # Q_d = G diag(...) G^T with G = strapdown.noise_jacobian; R R^T = I keeps it diagonal
        # in the accel terms, RJr RJr^T ~ I to second order in the gyro term
        idx = np.arange(3)
        A[idx, idx] += qa / dt * h2 * h2
        A[idx, idx + 3] += qa / dt * h2 * dt
        A[idx + 3, idx] += qa / dt * h2 * dt
        A[idx + 3, idx + 3] += qa * dt
        A[idx + 6, idx + 6] += qg * dt
        A[idx + 9, idx + 9] += qba * dt
        A[idx + 12, idx + 12] += qbg * dt
        self.P[...] = A
        x = self._x
        x[0:3] += x[3:6] * dt + h2 * world_a
        x[3:6] += world_a * dt
        x[6:15] = R_next.reshape(9)

    def _fix(self, z: np.ndarray, sigma_m: float) -> None:
        sigma = sigma_m if self.config.gps_sigma_m is None else self.config.gps_sigma_m
        P = self.P
        nu = z - self.p
        S = P[:3, :3] + np.eye(3) * sigma**2
        PHt = P[:, :3]
        K = np.linalg.solve(S, PHt.T).T
        self._nis.append(float(nu @ np.linalg.solve(S, nu)))
        IKH = np.eye(15)
        IKH[:, :3] -= K
        P = IKH @ P @ IKH.T + (K * sigma**2) @ K.T
        dx = K @ nu
        x = self._x
        x[0:6] += dx[0:6]
        x[6:15] = (_exp_so3(dx[6:9]) @ self.R).reshape(9)
        x[15:21] += dx[9:15]
        G = np.eye(15)
        G[6:9, 6:9] += 0.5 * _hat(dx[6:9])
        P = G @ P @ G.T
        self.P[...] = 0.5 * (P + P.T)
        if self._stamps and self._stamps[-1] == self.t:
            # the fix shares the last IMU stamp: the recorded state there is the updated one
            for rows in (self._stamps, self._xs, self._ps):
                rows.pop()
        self._record()
