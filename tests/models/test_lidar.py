"""Lidar beam model (Probabilistic Robotics Table 6.1) and likelihood field (Table 6.3)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from slamkit.errors import ConfigError
from slamkit.models import lidar

BEAM = lidar.BeamModel(z_hit=0.7, z_short=0.1, z_max=0.1, z_rand=0.1, sigma_hit_m=0.2, lambda_short=0.5)


def test_beam_worked_value():
    # z = z* = 5 m, z_max = 10 m: eta_hit = 1 to 1e-15 (both tails are 25 sigma away)
    p_hit = 1.0 / (0.2 * np.sqrt(2 * np.pi))  # 1.99471140
    p_short = 0.5 * np.exp(-2.5) / (1 - np.exp(-2.5))  # 0.04471256
    expected = 0.7 * p_hit + 0.1 * p_short + 0.1 * 0.1
    assert expected == pytest.approx(1.4107692, abs=1e-7)
    assert BEAM.probability(5.0, 5.0, 10.0) == pytest.approx(expected, rel=1e-12)
    # a reading 1 m beyond z*: only the random part is left (hit is 5 sigma out: 7e-6 of its peak)
    assert BEAM.probability(6.0, 5.0, 10.0) == pytest.approx(0.01 + 0.7 * p_hit * np.exp(-12.5), rel=1e-12)
    # no return (NaN) and z >= z_max are the max-range point mass plus the hit density there
    nan_p = BEAM.probability(np.nan, 9.9, 10.0)
    assert nan_p == pytest.approx(BEAM.probability(10.0, 9.9, 10.0))
    eta = 1 / (0.5 - 0.0)  # z* = z_max: half of the Gaussian lies inside [0, z_max]
    short_at_10 = 0.5 * np.exp(-5.0) / (1 - np.exp(-5.0))  # z = z* is still a (just) short reading
    assert BEAM.probability(10.0, 10.0, 10.0) == pytest.approx(0.1 + 0.7 * eta * p_hit + 0.1 * short_at_10,
                                                               rel=1e-9)


@pytest.mark.parametrize("z_star", [0.3, 4.0, 9.95])
def test_beam_density_integrates_to_one(z_star):
    """The continuous part integrates to z_hit + z_short + z_rand; the point mass adds z_max."""
    z_max = 10.0
    cont, _ = quad(lambda z: float(BEAM.probability(z, z_star, z_max)), 0.0, z_max,
                   points=[z_star], limit=200, epsabs=1e-11)
    assert cont + BEAM.z_max == pytest.approx(1.0, abs=1e-8)


def test_beam_sampling_matches_density():
    rng = np.random.default_rng(4)
    z_star, z_max = 4.0, 10.0
    samples = BEAM.sample(rng, np.full(200000, z_star), z_max)
    assert np.mean(samples == z_max) == pytest.approx(0.1, abs=0.004)  # binomial sd 6.7e-4
    edges = np.linspace(0.0, z_max, 41)
    counts, _ = np.histogram(samples[samples < z_max], bins=edges)
    expected = [quad(lambda z: float(BEAM.probability(z, z_star, z_max)), a, b, points=[z_star] if a < z_star < b else None)[0]
                for a, b in zip(edges[:-1], edges[1:])]
    np.testing.assert_allclose(counts / len(samples), expected, atol=0.004)
    again = BEAM.sample(np.random.default_rng(4), np.full(200000, z_star), z_max)
    np.testing.assert_array_equal(again, samples)


def test_beam_log_likelihood_is_vectorised_over_particles():
    rng = np.random.default_rng(5)
    expected = rng.uniform(0.5, 9.0, size=(6, 90))
    z = BEAM.sample(rng, expected[0], 10.0)
    batch = BEAM.log_likelihood(z, expected, 10.0)
    loop = [np.sum(np.log(BEAM.probability(z, e, 10.0))) for e in expected]
    np.testing.assert_allclose(batch, loop, rtol=1e-12)
    assert np.argmax(batch) == 0  # the particle whose expected ranges generated the scan


def _circle_room(radius=5.0, resolution=0.02):
    """Distance field of a circular wall of the given radius around the origin."""
    n = int(2 * (radius + 1) / resolution)
    origin = -(radius + 1)
    centres = origin + (np.arange(n) + 0.5) * resolution
    X, Y = np.meshgrid(centres, centres)  # field[iy, ix]
    field = np.abs(np.hypot(X, Y) - radius)

    def world_to_cell(xy):
        return np.floor((np.asarray(xy) - origin) / resolution).astype(np.int64)

    return field, world_to_cell


def test_likelihood_field_prefers_the_true_pose():
    field, to_cell = _circle_room()
    angles = np.linspace(-np.pi, np.pi, 180, endpoint=False)
    truth = np.array([1.0, -0.5, 0.3])
    # exact ranges to the wall x^2 + y^2 = 25 from the true pose
    d = np.stack([np.cos(angles + truth[2]), np.sin(angles + truth[2])], -1)
    b = d @ truth[:2]
    ranges = -b + np.sqrt(b**2 - (truth[:2] @ truth[:2] - 25.0))
    ranges[::10] = np.nan  # some lost returns are skipped
    model = lidar.LikelihoodFieldModel(z_hit=0.9, z_rand=0.1, sigma_hit_m=0.1)
    poses = truth + np.array([[0, 0, 0], [0.2, 0, 0], [0, -0.2, 0], [0, 0, 0.05]])
    ll = model.log_likelihood(poses, ranges, angles, 8.0, field, to_cell)
    assert ll.shape == (4,) and np.argmax(ll) == 0
    # at the truth every end point is within half a cell diagonal (0.0141 m) of the wall, so
    # each of the 162 valid beams scores between p(0.0141) and p(0)
    p = lambda dist: 0.9 * np.exp(-0.5 * (dist / 0.1) ** 2) / (0.1 * np.sqrt(2 * np.pi)) + 0.1 / 8.0
    assert 162 * np.log(p(0.0142)) <= ll[0] <= 162 * np.log(p(0.0))
    single = model.log_likelihood(truth, ranges, angles, 8.0, field, to_cell)
    assert single == pytest.approx(ll[0])
    # all end points off the map: only z_rand / z_max is left for each beam
    far = model.log_likelihood([100.0, 100.0, 0.0], ranges, angles, 8.0, field, to_cell)
    assert far == pytest.approx(162 * np.log(0.1 / 8.0))


def test_scan_endpoints_with_sensor_offset():
    # lidar 0.2 m ahead of the body origin, robot at (1, 1) facing +y, beam straight ahead, 3 m
    e = lidar.scan_endpoints([1.0, 1.0, np.pi / 2], [3.0], [0.0], (0.2, 0.0, 0.0))
    np.testing.assert_allclose(e, [[1.0, 4.2]], atol=1e-14)


def test_bad_parameters():
    with pytest.raises(ConfigError, match="sum to 1"):
        lidar.BeamModel(z_hit=0.9)
    with pytest.raises(ConfigError):
        lidar.LikelihoodFieldModel(sigma_hit_m=0.0)


def test_beam_model_fit_recovers_parameters():
    """EM on 40 000 beams sampled from known parameters (expected ranges 2..8 m, z_max 10 m),
    started from a different model, recovers the weights to 0.01, sigma to 3 % and lambda to 10 %."""
    truth = lidar.BeamModel(z_hit=0.6, z_short=0.2, z_max=0.05, z_rand=0.15, sigma_hit_m=0.1, lambda_short=0.8)
    rng = np.random.default_rng(12)
    z_star = rng.uniform(2.0, 8.0, 40000)
    z = truth.sample(rng, z_star, 10.0)
    fitted = lidar.BeamModel().fit(z, z_star, 10.0)
    for name in ("z_hit", "z_short", "z_max", "z_rand"):
        assert getattr(fitted, name) == pytest.approx(getattr(truth, name), abs=0.01), name
    assert fitted.sigma_hit_m == pytest.approx(0.1, rel=0.03)
    assert fitted.lambda_short == pytest.approx(0.8, rel=0.10)
    # the fitted model explains the data at least as well as the truth (it is the MLE)
    assert fitted.log_likelihood(z, z_star, 10.0) >= truth.log_likelihood(z, z_star, 10.0) - 1e-6
