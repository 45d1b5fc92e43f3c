"""Monte Carlo localization on a landmark map: global initialisation, KLD-sampling and
augmented MCL (random-particle injection) for recovery from kidnapping.

* Dellaert, Fox, Burgard & Thrun (1999), "Monte Carlo Localization for Mobile Robots";
  Thrun et al., *Probabilistic Robotics*, Table 8.2.
* KLD-sampling: Fox (2003), "Adapting the Sample Size in Particle Filters Through KLD-Sampling",
  eq. (12): with k occupied histogram bins, the number of samples that keeps the K-L divergence
  between the sample-based and the true posterior below epsilon with probability 1 - delta is

      n = (k - 1) / (2 epsilon) * (1 - 2 / (9 (k - 1)) + sqrt(2 / (9 (k - 1))) z_{1-delta})^3

  (Wilson-Hilferty approximation of the chi-square quantile). Samples are drawn one by one
  until n exceeds that bound for the bins seen so far; here the draws are made as one i.i.d.
  batch of n_max and the stopping point is found with a prefix count of first bin occurrences,
  which selects exactly the sample the sequential algorithm would stop at.
* Augmented MCL: *Probabilistic Robotics*, Table 8.3. Short- and long-term averages of the
  measurement likelihood, w_slow += alpha_slow (w_avg - w_slow) and w_fast likewise with
  alpha_fast (0 <= alpha_slow << alpha_fast); each resampled particle is replaced by a uniform
  random pose with probability max(0, 1 - w_fast / w_slow).

Two deliberate changes to Table 8.3:

* w_avg is taken per measurement, exp(log(mean likelihood) / m) for m measurements, so that the
  number of landmarks in view (which changes the raw likelihood by orders of magnitude) is not
  mistaken for a change in how well the particles explain the data.
* w_avg averages over the particles that were *not* injected at the last resampling. Counted
  in, a fraction p of random particles lowers w_avg by the factor (1 - p), which holds w_fast at
  (1 - p) w_slow and so keeps the injection rate at p indefinitely after a recovery; left out,
  w_avg measures what it is meant to: how well the tracked belief explains the data.

Also used: roughening after resampling (Gordon et al. 1993) against sample impoverishment, and
an annealed likelihood for the first updates after a global initialisation (see MCLConfig).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np
from scipy.stats import norm

from slamkit.data.estimate import Prior
from slamkit.errors import ConfigError
from slamkit.estimation._common import NoiseParams, weighted_pose_mean_cov
from slamkit.estimation.particle_filter import (
    ParticleFilterLocalization,
    log_sum_exp,
    multinomial_resample,
    normalize_log_weights,
    roughen,
    roughening_sigma,
    sample_gaussian_poses,
)


def kld_sample_bound(k: np.ndarray | int, epsilon: float, delta: float) -> np.ndarray:
    """Fox (2003) eq. (12): samples needed for k occupied bins (1 for k <= 1)."""
    k = np.asarray(k, dtype=float)
    km1 = np.maximum(k - 1.0, 1.0)
    z = norm.ppf(1.0 - delta)
    a = 2.0 / (9.0 * km1)
    n = km1 / (2.0 * epsilon) * (1.0 - a + np.sqrt(a) * z) ** 3
    return np.where(k <= 1, 1.0, np.ceil(n))


def _bin_keys(poses: np.ndarray, bin_size: np.ndarray) -> np.ndarray:
    """One int64 per pose naming its (x, y, theta) histogram bin (21 bits per axis)."""
    b = np.floor(poses / bin_size).astype(np.int64) & ((1 << 21) - 1)
    return (b[:, 0] << 42) | (b[:, 1] << 21) | b[:, 2]


def kld_sample_count(poses: np.ndarray, bin_size: np.ndarray, epsilon: float, delta: float,
                     n_min: int) -> int:
    """Length of the prefix of i.i.d. samples ``poses`` (n, 3) that KLD-sampling keeps (all of
    them if the bound is not met within the prefix)."""
    _, first = np.unique(_bin_keys(poses, bin_size), return_index=True)
    is_new = np.zeros(len(poses), dtype=bool)
    is_new[first] = True
    k = np.cumsum(is_new)  # occupied bins after each draw
    n_drawn = np.arange(1, len(poses) + 1)
    done = (n_drawn >= kld_sample_bound(k, epsilon, delta)) & (n_drawn >= n_min)
    hits = np.flatnonzero(done)
    return int(hits[0] + 1) if len(hits) else len(poses)


@dataclass(frozen=True)
class MCLConfig:
    #: particles when KLD-sampling is off, and for a Gaussian (non-global) initialisation
    n_particles: int = 2000
    #: start from a uniform belief over the map bounds (plus margin) instead of the prior
    global_init: bool = True
    map_margin_m: float = 2.0
    kld: bool = True
    kld_epsilon: float = 0.05
    kld_delta: float = 0.01
    kld_bin_xy_m: float = 0.5
    kld_bin_theta_rad: float = np.deg2rad(10.0)
    n_min: int = 200
    n_max: int = 20000
    #: augmented MCL averaging rates (0 disables injection when both are 0)
    alpha_slow: float = 0.005
    alpha_fast: float = 0.2
    #: multiplies the sequence's measurement sigmas in the likelihood; > 1 makes the global
    #: search tolerant to the sparse sampling of a large pose space
    likelihood_sigma_scale: float = 1.0
    #: after a global initialisation, the likelihood sigmas start ``anneal_start_scale`` times
    #: larger and shrink geometrically to ``likelihood_sigma_scale`` over ``anneal_updates``
    #: updates (annealed importance weighting, Neal 2001 / Deutscher et al. 2000): the sparse
    #: uniform sample almost never holds a particle close enough to the truth to survive the
    #: sharp likelihood, but it does hold many under a flattened one.
    anneal_updates: int = 10
    anneal_start_scale: float = 10.0
    #: roughening constant K (Gordon et al. 1993) applied to the resampled, non-injected
    #: particles, with the spread E floored at one KLD bin
    roughening_k: float = 0.2

    def __post_init__(self) -> None:
        if not (0.0 <= self.alpha_slow <= self.alpha_fast <= 1.0):
            raise ConfigError("need 0 <= alpha_slow <= alpha_fast <= 1 "
                              f"(alpha_slow={self.alpha_slow}, alpha_fast={self.alpha_fast})")
        if not (1 <= self.n_min <= self.n_max):
            raise ConfigError(f"need 1 <= n_min <= n_max, got {self.n_min}, {self.n_max}")
        if not (0 < self.kld_epsilon < 1 and 0 < self.kld_delta < 1):
            raise ConfigError("kld_epsilon and kld_delta must lie in (0, 1)")


class MonteCarloLocalization(ParticleFilterLocalization):
    """MCL (registry name ``mcl``): resamples after every update, with KLD-sampling and augmented
    MCL recovery. ``extras`` report the particle count and injection probability per update."""

    name = "mcl"

    def __init__(self, world_p_landmarks: Mapping[int, np.ndarray], noise: NoiseParams = NoiseParams(),
                 config: MCLConfig = MCLConfig(), rng: np.random.Generator | None = None) -> None:
        scale = config.likelihood_sigma_scale
        likelihood_noise = NoiseParams(noise.sigma_v_mps, noise.sigma_omega_radps,
                                       noise.sigma_range_m * scale, noise.sigma_bearing_rad * scale)
        super().__init__(world_p_landmarks, likelihood_noise, rng=rng)
        self.mcl_config = config
        lo = self.landmarks.min(axis=0) - config.map_margin_m
        hi = self.landmarks.max(axis=0) + config.map_margin_m
        self.bounds_xy = np.stack([lo, hi])
        self._bin = np.array([config.kld_bin_xy_m, config.kld_bin_xy_m, config.kld_bin_theta_rad])

    def uniform_poses(self, n: int) -> np.ndarray:
        lo, hi = self.bounds_xy
        xy = lo + self.rng.random((n, 2)) * (hi - lo)
        theta = self.rng.uniform(-np.pi, np.pi, n)
        return np.column_stack([xy, theta])

    def _reset(self, prior: Prior) -> None:
        c = self.mcl_config
        if c.global_init:
            n = c.n_max if c.kld else c.n_particles
            self.particles = self.uniform_poses(n)
        else:
            self.particles = sample_gaussian_poses(prior.world_xytheta_body, prior.covariance,
                                                   c.n_particles, self.rng)
        self.log_w = np.full(len(self.particles), -np.log(len(self.particles)))
        self.n_resamples = 0
        self.w_slow = 0.0
        self.w_fast = 0.0
        self._posterior = None
        self._n_updates = 0
        self._injected = np.zeros(len(self.particles), dtype=bool)
        self.particle_counts: list[int] = []
        self.injection_probabilities: list[float] = []

    def _weigh_and_resample(self, loglik: np.ndarray, n_measurements: int) -> None:
        c = self.mcl_config
        k = self._n_updates
        self._n_updates += 1
        if c.global_init and k < c.anneal_updates:
            # the likelihood was computed with likelihood_sigma_scale; a Gaussian log-likelihood
            # scales (up to a constant) with 1 / sigma^2, so temper it by (base / current)^2
            current = c.anneal_start_scale * (c.likelihood_sigma_scale / c.anneal_start_scale) ** (
                k / max(c.anneal_updates, 1))
            loglik = loglik * (c.likelihood_sigma_scale / max(current, c.likelihood_sigma_scale)) ** 2
        # log of the (prior-weighted) mean likelihood, then per measurement (see module doc)
        keep = ~self._injected if not self._injected.all() else np.ones(len(loglik), dtype=bool)
        log_avg = log_sum_exp(self.log_w[keep] + loglik[keep]) - log_sum_exp(self.log_w[keep])
        w_avg = float(np.exp(log_avg / max(n_measurements, 1)))
        if self.w_slow == 0.0:
            self.w_slow = self.w_fast = w_avg
        else:
            self.w_slow += c.alpha_slow * (w_avg - self.w_slow)
            self.w_fast += c.alpha_fast * (w_avg - self.w_fast)
        p_inject = max(0.0, 1.0 - self.w_fast / self.w_slow) if self.w_slow > 0 else 0.0

        self.log_w = normalize_log_weights(self.log_w + loglik)
        w = np.exp(self.log_w)
        # the reported belief is the weighted set before resampling and injection: random
        # particles carry no evidence yet and would drag the mean across the map
        self._posterior = weighted_pose_mean_cov(self.particles, w)
        if not c.kld:
            new, injected = self._draw(w, c.n_particles, p_inject)
        else:
            # Draw i.i.d. batches (any prefix of an i.i.d. sequence is itself a valid sample, which
            # is what the sequential KLD stopping rule needs), doubling the batch until the bound
            # is met inside it or n_max is reached: the cost follows the answer, not n_max.
            size = min(c.n_max, max(c.n_min, 2 * len(self.particles)))
            while True:
                new, injected = self._draw(w, size, p_inject)
                n = kld_sample_count(new, self._bin, c.kld_epsilon, c.kld_delta, c.n_min)
                if n < size or size == c.n_max:
                    new, injected = new[:n], injected[:n]
                    break
                size = min(c.n_max, 2 * size)
        self.particles = new
        self._injected = injected
        # The belief carried forward is the roughened set: its covariance includes the
        # roughening kernel. Without it a weight collapsed onto one particle reports a zero
        # covariance (NEES ~1e90 in the first global-localization updates).
        mean, cov = self._posterior
        keep = ~injected if not injected.all() else np.ones(len(new), dtype=bool)
        h = roughening_sigma(new[keep], c.roughening_k, np.array([False, False, True]), self._bin)
        self._posterior = (mean, cov + np.diag(h**2))
        self.log_w = np.full(len(new), -np.log(len(new)))
        self.n_resamples += 1
        self.particle_counts.append(len(new))
        self.injection_probabilities.append(p_inject)

    def _draw(self, w: np.ndarray, n: int, p_inject: float) -> tuple[np.ndarray, np.ndarray]:
        """n i.i.d. draws from the weighted set, roughened, each replaced by a uniform random
        pose with probability p_inject (Table 8.3 lines 11-13); returns (poses, injected mask)."""
        new = self.particles[multinomial_resample(w, self.rng, n)]
        # spread floored at one KLD bin: after a weight collapse every draw is a copy of one
        # particle and spread-based roughening alone would stop (and report a zero covariance)
        new = roughen(new, self.mcl_config.roughening_k, self.rng, np.array([False, False, True]),
                      min_spread=self._bin)
        inject = self.rng.random(n) < p_inject
        if inject.any():
            new[inject] = self.uniform_poses(int(inject.sum()))
        return new, inject

    def _predict(self, odometry) -> None:
        super()._predict(odometry)
        self._posterior = None

    def _pose_and_covariance(self) -> tuple[np.ndarray, np.ndarray]:
        if self._posterior is not None:
            return self._posterior[0].copy(), self._posterior[1].copy()
        return super()._pose_and_covariance()

    def _extras(self) -> dict:
        return {
            "n_resamples": self.n_resamples,
            "particle_counts": np.array(self.particle_counts),
            "injection_probabilities": np.array(self.injection_probabilities),
        }
