"""IMU noise model: white noise plus bias random walk for gyroscope and accelerometer.

The continuous-time model (IEEE Std 952-1997; Furgale et al., Kalibr "IMU Noise Model" wiki;
Forster et al., "On-Manifold Preintegration", T-RO 2017, sec. IV) for each axis is

    measured(t) = true(t) + b(t) + n(t),     b_dot(t) = n_b(t)

with white noise n of density sigma (rad/s/sqrt(Hz) or m/s^2/sqrt(Hz)) and bias driven by
white noise of density sigma_b (rad/s^2/sqrt(Hz), m/s^3/sqrt(Hz)). Sampled at dt:

    n_k ~ N(0, sigma^2 / dt),        b_k = b_{k-1} + sigma_b sqrt(dt) w_k,  w_k ~ N(0, 1)

Consequences the tests check by Monte Carlo: integrating accelerometer white noise gives a
velocity error with standard deviation sigma sqrt(t) (velocity random walk); a constant gyro
bias b gives a heading error b t.

Measurements are h(x) = true + bias, so the Jacobian with respect to the bias is the identity
and with respect to the true rate also the identity; no function is needed for that.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError

__all__ = ["ImuNoise", "ImuSamples", "IMU_PRESETS", "simulate_imu"]

_DEG = np.pi / 180.0
_HOUR = 3600.0


@dataclass(frozen=True)
class ImuNoise:
    """Continuous-time noise densities (per axis, SI) and turn-on bias standard deviations."""

    gyro_noise_density: float = 1.6968e-4  # rad/s/sqrt(Hz)
    gyro_bias_random_walk: float = 1.9393e-5  # rad/s^2/sqrt(Hz)
    accel_noise_density: float = 2.0e-3  # m/s^2/sqrt(Hz)
    accel_bias_random_walk: float = 3.0e-3  # m/s^3/sqrt(Hz)
    gyro_bias_sigma: float = 0.0  # rad/s, spread of the initial bias
    accel_bias_sigma: float = 0.0  # m/s^2

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not (np.isfinite(value) and value >= 0):
                raise ConfigError(f"ImuNoise.{name} must be finite and >= 0, got {value}")

    @classmethod
    def preset(cls, name: str) -> "ImuNoise":
        try:
            return IMU_PRESETS[name]
        except KeyError:
            raise ConfigError(f"unknown IMU preset {name!r}; known: {sorted(IMU_PRESETS)}") from None

    def discrete_sigmas(self, dt_s: float) -> dict[str, float]:
        """Per-sample standard deviations at sample period dt (white: sigma/sqrt(dt); bias
        step: sigma_b sqrt(dt))."""
        if not dt_s > 0:
            raise ConfigError(f"dt_s must be positive, got {dt_s}")
        return {
            "gyro_white": self.gyro_noise_density / np.sqrt(dt_s),
            "gyro_bias_step": self.gyro_bias_random_walk * np.sqrt(dt_s),
            "accel_white": self.accel_noise_density / np.sqrt(dt_s),
            "accel_bias_step": self.accel_bias_random_walk * np.sqrt(dt_s),
        }


IMU_PRESETS: dict[str, ImuNoise] = {
    # no noise: for tests and for isolating other error sources
    "ideal": ImuNoise(0.0, 0.0, 0.0, 0.0),
    # ADIS16448 as calibrated for the EuRoC MAV dataset (its imu0/sensor.yaml)
    "euroc_adis16448": ImuNoise(1.6968e-4, 1.9393e-5, 2.0e-3, 3.0e-3),
    # consumer MEMS (MPU-9250 datasheet: 0.01 deg/s/sqrt(Hz), 300 ug/sqrt(Hz)); the random
    # walks are typical values for this class, not datasheet numbers
    "consumer_mems": ImuNoise(0.01 * _DEG, 1e-4, 300e-6 * 9.81, 1e-3,
                              gyro_bias_sigma=0.5 * _DEG, accel_bias_sigma=0.05),
    # tactical grade (fibre-optic gyro class): ARW 0.07 deg/sqrt(h), VRW 0.05 m/s/sqrt(h)
    "tactical": ImuNoise(0.07 * _DEG / 60.0, 1e-6, 0.05 / 60.0, 1e-5,
                         gyro_bias_sigma=1.0 * _DEG / _HOUR, accel_bias_sigma=1e-3 * 9.81),
    # navigation grade (ring-laser gyro class): ARW 0.002 deg/sqrt(h), VRW 0.005 m/s/sqrt(h)
    "navigation": ImuNoise(0.002 * _DEG / 60.0, 1e-8, 0.005 / 60.0, 1e-6,
                           gyro_bias_sigma=0.01 * _DEG / _HOUR, accel_bias_sigma=25e-6 * 9.81),
}


@dataclass(frozen=True)
class ImuSamples:
    """Simulated readings and the true biases that corrupted them; arrays (..., N, D)."""

    gyro_radps: np.ndarray
    accel_mps2: np.ndarray
    gyro_bias_radps: np.ndarray
    accel_bias_mps2: np.ndarray


def _bias_walk(rng, shape, step_sigma, initial):
    # b_0 = initial, b_k = b_{k-1} + step_sigma w_k: a cumulative sum along the time axis
    steps = rng.standard_normal(shape) * step_sigma
    steps[..., 0, :] = 0.0
    return initial[..., None, :] + np.cumsum(steps, axis=-2)


def simulate_imu(rng: np.random.Generator, gyro_true_radps, accel_true_mps2, dt_s: float,
                 noise: ImuNoise, gyro_bias0_radps=None, accel_bias0_mps2=None) -> ImuSamples:
    """Corrupt true body-frame rates (..., N, D) sampled every dt with ``noise``.

    Time runs along axis -2 and D is usually 3 (a planar robot may pass D = 1 for its yaw
    gyro). Leading axes are independent runs (Monte Carlo). Initial biases default to draws
    with the preset's turn-on sigmas; pass them to fix them (e.g. a known constant gyro bias).
    Random draws happen in a fixed order: initial biases, gyro bias steps, gyro white, accel
    bias steps, accel white.
    """
    g = np.asarray(gyro_true_radps, dtype=float)
    a = np.asarray(accel_true_mps2, dtype=float)
    if g.ndim < 2 or a.ndim < 2:
        raise ConfigError(f"IMU inputs need shape (..., N, D), got {g.shape} and {a.shape}")
    s = noise.discrete_sigmas(dt_s)
    lead_g, lead_a = g.shape[:-2] + g.shape[-1:], a.shape[:-2] + a.shape[-1:]
    bg0 = rng.standard_normal(lead_g) * noise.gyro_bias_sigma
    ba0 = rng.standard_normal(lead_a) * noise.accel_bias_sigma
    if gyro_bias0_radps is not None:
        bg0 = np.broadcast_to(np.asarray(gyro_bias0_radps, dtype=float), lead_g)
    if accel_bias0_mps2 is not None:
        ba0 = np.broadcast_to(np.asarray(accel_bias0_mps2, dtype=float), lead_a)
    bg = _bias_walk(rng, g.shape, s["gyro_bias_step"], bg0)
    gyro = g + bg + rng.standard_normal(g.shape) * s["gyro_white"]
    ba = _bias_walk(rng, a.shape, s["accel_bias_step"], ba0)
    accel = a + ba + rng.standard_normal(a.shape) * s["accel_white"]
    return ImuSamples(gyro, accel, bg, ba)
