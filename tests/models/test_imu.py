"""IMU noise model: Monte-Carlo growth laws and the discrete noise scaling."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.errors import ConfigError
from slamkit.models.imu import IMU_PRESETS, ImuNoise, simulate_imu

RUNS = 400
DT = 0.05
T_END = 100.0
N = int(T_END / DT)


def _times():
    return np.arange(1, N + 1) * DT


def test_velocity_error_from_accel_white_noise_grows_like_sqrt_t():
    """Integrating accelerometer white noise of density sigma gives sigma sqrt(t) velocity error.

    400 runs, 20 Hz, 100 s: log-log fit of the across-run standard deviation over
    t = 1 ... 100 s has exponent 0.5 +- 0.05 and prefactor sigma within 10 %."""
    sigma = 0.02  # m/s^2/sqrt(Hz)
    noise = ImuNoise(0.0, 0.0, sigma, 0.0)
    rng = np.random.default_rng(7)
    zeros = np.zeros((RUNS, N, 1))
    out = simulate_imu(rng, zeros, zeros, DT, noise)
    vel_err = np.cumsum(out.accel_mps2[..., 0], axis=-1) * DT  # (RUNS, N)
    t = _times()
    idx = np.unique(np.round(np.logspace(np.log10(1.0), np.log10(T_END), 12) / DT).astype(int) - 1)
    std = vel_err[:, idx].std(axis=0)
    exponent, log_pref = np.polyfit(np.log(t[idx]), np.log(std), 1)
    assert exponent == pytest.approx(0.5, abs=0.05)
    assert np.exp(log_pref) == pytest.approx(sigma, rel=0.10)
    # a constant-rate check at 100 s: sigma sqrt(100) = 0.2 m/s
    assert std[-1] == pytest.approx(0.2, rel=0.10)


def test_heading_error_from_constant_gyro_bias_grows_like_bt():
    b = 0.01  # rad/s
    rng = np.random.default_rng(8)
    zeros = np.zeros((RUNS, N, 1))
    # bias only: heading error is exactly b t
    clean = simulate_imu(rng, zeros[:1], zeros[:1], DT, ImuNoise(0.0, 0.0, 0.0, 0.0), gyro_bias0_radps=[b])
    heading = np.cumsum(clean.gyro_radps[0, :, 0]) * DT
    np.testing.assert_allclose(heading, b * _times(), rtol=1e-12)
    # bias plus white gyro noise (1e-3 rad/s/sqrt(Hz)): the run mean still grows like b t,
    # fitted slope within 2 % of b, while the spread is only sigma sqrt(t) = 0.01 rad at 100 s
    noisy = simulate_imu(rng, zeros, zeros, DT, ImuNoise(1e-3, 0.0, 0.0, 0.0), gyro_bias0_radps=[b])
    heading = np.cumsum(noisy.gyro_radps[..., 0], axis=-1) * DT
    slope = np.polyfit(_times(), heading.mean(axis=0), 1)[0]
    assert slope == pytest.approx(b, rel=0.02)
    assert heading[:, -1].std() == pytest.approx(1e-3 * np.sqrt(T_END), rel=0.10)


def test_bias_random_walk_spread():
    # bias after t has std sigma_b sqrt(t): 1e-3 * sqrt(100 - 0.05) ~ 0.01 rad/s
    rng = np.random.default_rng(9)
    zeros = np.zeros((RUNS, N, 1))
    out = simulate_imu(rng, zeros, zeros, DT, ImuNoise(0.0, 1e-3, 0.0, 0.0))
    assert out.gyro_bias_radps[:, -1, 0].std() == pytest.approx(1e-3 * np.sqrt(T_END - DT), rel=0.10)
    np.testing.assert_array_equal(out.gyro_bias_radps[:, 0, 0], 0.0)  # starts at the initial bias


def test_discrete_sigmas_and_presets():
    s = ImuNoise(0.01, 0.001, 0.1, 0.01).discrete_sigmas(0.01)  # 100 Hz
    assert s == pytest.approx({"gyro_white": 0.1, "gyro_bias_step": 1e-4, "accel_white": 1.0,
                               "accel_bias_step": 1e-3})
    assert ImuNoise.preset("euroc_adis16448").gyro_noise_density == 1.6968e-4
    # the grades are ordered: navigation < tactical < consumer in gyro white noise
    dens = [IMU_PRESETS[k].gyro_noise_density for k in ("navigation", "tactical", "consumer_mems")]
    assert dens == sorted(dens)
    with pytest.raises(ConfigError, match="unknown IMU preset"):
        ImuNoise.preset("nope")
    with pytest.raises(ConfigError):
        ImuNoise(gyro_noise_density=-1.0)


def test_same_seed_same_samples():
    true_g = np.tile([0.0, 0.0, 0.3], (50, 1))
    true_a = np.tile([0.0, 0.0, 9.81], (50, 1))
    noise = IMU_PRESETS["consumer_mems"]
    a = simulate_imu(np.random.default_rng(1), true_g, true_a, 0.005, noise)
    b = simulate_imu(np.random.default_rng(1), true_g, true_a, 0.005, noise)
    np.testing.assert_array_equal(a.gyro_radps, b.gyro_radps)
    np.testing.assert_array_equal(a.accel_mps2, b.accel_mps2)
    assert a.gyro_radps.shape == (50, 3)
