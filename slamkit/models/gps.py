"""GNSS position fixes for a planar robot: noise presets, rate, antenna lever arm, and
time-correlated error.

h(x) = (x, y) + R(theta) body_p_antenna: the antenna sits at a lever arm from the body origin,
so the fix depends on heading, and

    H = dh/dx = [[1, 0, -sin(theta) l_x - cos(theta) l_y],
                 [0, 1,  cos(theta) l_x - sin(theta) l_y]]

GNSS errors are not white: multipath and atmosphere drift slowly. ``simulate_fixes`` models the
horizontal error per axis as a first-order Gauss-Markov process with correlation time tau
(Grewal, Andrews & Bartone, *Global Navigation Satellite Systems, Inertial Navigation, and
Integration*, 4th ed., sec. 10.2.1): e_k = exp(-dt/tau) e_{k-1} + sqrt(1 - exp(-2 dt/tau)) sigma w_k,
stationary standard deviation sigma; tau = 0 gives white noise.

Preset sigmas are per-axis horizontal 1-sigma figures typical of each class (consumer
single-frequency receiver ~ 2.5 m, SBAS/DGPS ~ 0.5 m, RTK fixed ~ 2 cm), not one product's
datasheet.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from slamkit.errors import ConfigError

__all__ = ["Gps", "GPS_PRESETS", "observe", "observe_jacobian"]


def observe(world_xytheta_body, body_p_antenna=(0.0, 0.0)):
    """(..., 3) poses -> (..., 2) world antenna positions."""
    x = np.asarray(world_xytheta_body, dtype=float)
    l = np.asarray(body_p_antenna, dtype=float)
    c, s = np.cos(x[..., 2]), np.sin(x[..., 2])
    return np.stack([x[..., 0] + c * l[0] - s * l[1], x[..., 1] + s * l[0] + c * l[1]], axis=-1)


def observe_jacobian(world_xytheta_body, body_p_antenna=(0.0, 0.0)):
    """(..., 2, 3) H = dh/dx of :func:`observe`."""
    x = np.asarray(world_xytheta_body, dtype=float)
    l = np.asarray(body_p_antenna, dtype=float)
    c, s = np.cos(x[..., 2]), np.sin(x[..., 2])
    H = np.zeros(x.shape[:-1] + (2, 3))
    H[..., 0, 0] = H[..., 1, 1] = 1.0
    H[..., 0, 2] = -s * l[0] - c * l[1]
    H[..., 1, 2] = c * l[0] - s * l[1]
    return H


@dataclass(frozen=True)
class Gps:
    """GNSS receiver: per-axis horizontal sigma, fix rate, lever arm, error correlation time."""

    sigma_m: float = 2.5
    rate_hz: float = 1.0
    body_p_antenna: tuple[float, float] = (0.0, 0.0)
    correlation_time_s: float = 0.0

    def __post_init__(self) -> None:
        if not (self.sigma_m >= 0 and self.rate_hz > 0 and self.correlation_time_s >= 0):
            raise ConfigError(f"Gps needs sigma_m >= 0, rate_hz > 0, correlation_time_s >= 0; got {self}")
        object.__setattr__(self, "body_p_antenna", tuple(float(v) for v in self.body_p_antenna))

    @classmethod
    def preset(cls, name: str, **overrides) -> "Gps":
        try:
            base = GPS_PRESETS[name]
        except KeyError:
            raise ConfigError(f"unknown GPS preset {name!r}; known: {sorted(GPS_PRESETS)}") from None
        return cls(**{**base.__dict__, **overrides})

    @property
    def covariance(self) -> np.ndarray:
        return np.eye(2) * self.sigma_m**2

    def measure(self, rng: np.random.Generator, world_xytheta_body) -> np.ndarray:
        """One independent fix (2,) (white error; use :meth:`simulate_fixes` for a series)."""
        return observe(world_xytheta_body, self.body_p_antenna) + rng.standard_normal(2) * self.sigma_m

    def simulate_fixes(self, rng: np.random.Generator, world_xytheta_body, stamps_s) -> np.ndarray:
        """(N, 3) true poses at (N,) increasing stamps -> (N, 2) fixes with Gauss-Markov error."""
        x = np.asarray(world_xytheta_body, dtype=float).reshape(-1, 3)
        t = np.asarray(stamps_s, dtype=float).reshape(-1)
        if len(t) != len(x):
            raise ConfigError(f"simulate_fixes: {len(x)} poses but {len(t)} stamps")
        w = rng.standard_normal((len(x), 2))
        err = np.empty_like(w)
        if self.correlation_time_s == 0.0 or len(x) == 0:
            err = w * self.sigma_m
        else:
            phi = np.exp(-np.diff(t, prepend=t[0]) / self.correlation_time_s)
            drive = np.sqrt(1.0 - phi**2) * self.sigma_m
            err[0] = w[0] * self.sigma_m  # start in the stationary distribution
            if len(x) > 1 and np.allclose(phi[1:], phi[1]):
                # uniform rate: the recursion is a first-order IIR filter, run in C by lfilter
                err[1:] = lfilter([drive[1]], [1.0, -phi[1]], w[1:], axis=0, zi=phi[1] * err[:1])[0]
            else:
                for k in range(1, len(x)):  # irregular stamps: a recursion in time, not per particle
                    err[k] = phi[k] * err[k - 1] + drive[k] * w[k]
        return observe(x, self.body_p_antenna) + err


GPS_PRESETS: dict[str, Gps] = {
    "consumer": Gps(sigma_m=2.5, rate_hz=1.0, correlation_time_s=60.0),
    "dgps": Gps(sigma_m=0.5, rate_hz=1.0, correlation_time_s=30.0),
    "rtk": Gps(sigma_m=0.02, rate_hz=10.0),
}
