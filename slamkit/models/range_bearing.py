"""Range-bearing observations of point landmarks from a planar robot.

Measurement model (Thrun, Burgard & Fox, *Probabilistic Robotics*, sec. 6.6 for the model and
Table 10.1, EKF SLAM, for the Jacobian): for pose (x, y, theta) and landmark (m_x, m_y),

    delta = m - (x, y),  q = |delta|^2
    h = [sqrt(q), atan2(delta_y, delta_x) - theta]          (bearing wrapped to [-pi, pi))

    H_pose     = [[-dx/r, -dy/r,  0],         H_landmark = [[ dx/r, dy/r],
                  [ dy/q, -dx/q, -1]]                       [-dy/q, dx/q]]

The inverse model (landmark initialisation in EKF-SLAM, FastSLAM) is
m = (x, y) + r (cos(theta + b), sin(theta + b)) with its Jacobians w.r.t. pose and z.

``RangeBearingSensor.measure`` simulates the sensor: landmarks outside the field of view or
beyond the maximum range are not seen, each seen one drops out with ``dropout_prob``, and
Gaussian noise is added. It returns plain arrays (ids, range_m, bearing_rad); the simulator
wraps them into ``slamkit.data.sequence.RangeBearing`` (models may not import data).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError
from slamkit.geometry.angles import wrap_angle

__all__ = [
    "observe",
    "observe_jacobians",
    "inverse_observe",
    "inverse_observe_jacobians",
    "RangeBearingSensor",
]


def _pose_landmark(world_xytheta_body, world_p_landmark):
    x = np.asarray(world_xytheta_body, dtype=float)
    m = np.asarray(world_p_landmark, dtype=float)
    if x.shape[-1:] != (3,):
        raise ConfigError(f"pose must have shape (..., 3), got {x.shape}")
    if m.shape[-1:] != (2,):
        raise ConfigError(f"landmark must have shape (..., 2), got {m.shape}")
    return x, m


def observe(world_xytheta_body, world_p_landmark):
    """h(x, m): (..., 3) poses and (..., 2) landmarks (broadcast) -> (..., 2) [range_m, bearing_rad]."""
    x, m = _pose_landmark(world_xytheta_body, world_p_landmark)
    dx = m[..., 0] - x[..., 0]
    dy = m[..., 1] - x[..., 1]
    out = np.empty(dx.shape + (2,))
    # sqrt of the sum of squares, not hypot: ranges are far from overflow and hypot's scaling
    # costs several times more on particle-sized arrays
    out[..., 0] = np.sqrt(dx * dx + dy * dy)
    out[..., 1] = wrap_angle(np.arctan2(dy, dx) - x[..., 2])
    return out


def observe_jacobians(world_xytheta_body, world_p_landmark):
    """(H_pose (..., 2, 3), H_landmark (..., 2, 2)) of :func:`observe`.

    Undefined when the landmark coincides with the robot (r = 0); returns inf/nan there as
    the maths does rather than inventing a value.
    """
    x, m = _pose_landmark(world_xytheta_body, world_p_landmark)
    dx = m[..., 0] - x[..., 0]
    dy = m[..., 1] - x[..., 1]
    q = dx * dx + dy * dy
    r = np.sqrt(q)
    H_lm = np.empty(dx.shape + (2, 2))
    with np.errstate(divide="ignore", invalid="ignore"):
        H_lm[..., 0, 0] = dx / r
        H_lm[..., 0, 1] = dy / r
        H_lm[..., 1, 0] = -dy / q
        H_lm[..., 1, 1] = dx / q
    H_pose = np.zeros(dx.shape + (2, 3))
    H_pose[..., :, :2] = -H_lm
    H_pose[..., 1, 2] = -1.0
    return H_pose, H_lm


def inverse_observe(world_xytheta_body, z):
    """g(x, z): (..., 3) poses and (..., 2) [range_m, bearing_rad] -> (..., 2) world landmark."""
    x = np.asarray(world_xytheta_body, dtype=float)
    z = np.asarray(z, dtype=float)
    ang = x[..., 2] + z[..., 1]
    return np.stack([x[..., 0] + z[..., 0] * np.cos(ang), x[..., 1] + z[..., 0] * np.sin(ang)], axis=-1)


def inverse_observe_jacobians(world_xytheta_body, z):
    """(G_pose (..., 2, 3), G_z (..., 2, 2)) of :func:`inverse_observe`."""
    x = np.asarray(world_xytheta_body, dtype=float)
    z = np.asarray(z, dtype=float)
    ang = x[..., 2] + z[..., 1]
    rng_m = z[..., 0]
    shape = np.broadcast_shapes(ang.shape, rng_m.shape)
    ang, rng_m = np.broadcast_to(ang, shape), np.broadcast_to(rng_m, shape)
    c, s = np.cos(ang), np.sin(ang)
    G_pose = np.zeros(shape + (2, 3))
    G_pose[..., 0, 0] = 1.0
    G_pose[..., 1, 1] = 1.0
    G_pose[..., 0, 2] = -rng_m * s
    G_pose[..., 1, 2] = rng_m * c
    G_z = np.empty(shape + (2, 2))
    G_z[..., 0, 0] = c
    G_z[..., 0, 1] = -rng_m * s
    G_z[..., 1, 0] = s
    G_z[..., 1, 1] = rng_m * c
    return G_pose, G_z


@dataclass(frozen=True)
class RangeBearingSensor:
    """A landmark detector: Gaussian range/bearing noise, field of view centred on the body
    x axis, maximum range, independent per-landmark dropout, sample rate."""

    sigma_range_m: float = 0.1
    sigma_bearing_rad: float = float(np.deg2rad(1.0))
    fov_rad: float = float(2.0 * np.pi)
    max_range_m: float = 20.0
    dropout_prob: float = 0.0
    rate_hz: float = 10.0

    def __post_init__(self) -> None:
        checks = {
            "sigma_range_m": self.sigma_range_m >= 0,
            "sigma_bearing_rad": self.sigma_bearing_rad >= 0,
            "fov_rad": 0 < self.fov_rad <= 2 * np.pi,
            "max_range_m": self.max_range_m > 0,
            "dropout_prob": 0 <= self.dropout_prob <= 1,
            "rate_hz": self.rate_hz > 0,
        }
        for name, ok in checks.items():
            if not ok:
                raise ConfigError(f"RangeBearingSensor.{name} is invalid: {getattr(self, name)}")

    @property
    def covariance(self) -> np.ndarray:
        """(2, 2) measurement noise R = diag(sigma_range^2, sigma_bearing^2)."""
        return np.diag([self.sigma_range_m**2, self.sigma_bearing_rad**2])

    def visible(self, world_xytheta_body, world_p_landmarks) -> np.ndarray:
        """(L,) True where a landmark is within range and field of view (noise-free test)."""
        z = observe(np.asarray(world_xytheta_body, float), np.asarray(world_p_landmarks, float).reshape(-1, 2))
        in_fov = np.abs(z[:, 1]) <= 0.5 * self.fov_rad if self.fov_rad < 2 * np.pi else np.ones(len(z), bool)
        return (z[:, 0] <= self.max_range_m) & in_fov

    def measure(self, rng: np.random.Generator, world_xytheta_body, world_p_landmarks, landmark_ids):
        """Simulate one reading: returns (landmark_ids (K,), range_m (K,), bearing_rad (K,)).

        Random draws are made for all L landmarks in a fixed order (dropout, then range and
        bearing noise) so a seed gives the same stream whatever is visible. Noisy ranges are
        clipped at 0; bearings wrapped to [-pi, pi).
        """
        pose = np.asarray(world_xytheta_body, dtype=float).reshape(3)
        lms = np.asarray(world_p_landmarks, dtype=float).reshape(-1, 2)
        ids = np.asarray(landmark_ids).reshape(-1)
        if len(ids) != len(lms):
            raise ConfigError(f"landmark_ids has {len(ids)} entries but there are {len(lms)} landmarks")
        n = len(lms)
        keep_draw = rng.random(n) >= self.dropout_prob
        noise = rng.standard_normal((n, 2)) * np.array([self.sigma_range_m, self.sigma_bearing_rad])
        z = observe(pose, lms)
        keep = self.visible(pose, lms) & keep_draw
        zn = z[keep] + noise[keep]
        return (
            ids[keep].astype(np.int64),
            np.maximum(zn[:, 0], 0.0),
            wrap_angle(zn[:, 1]),
        )
