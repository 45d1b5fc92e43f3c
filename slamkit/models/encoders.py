"""Wheel encoders: quantisation of a wheel angle to integer ticks.

An incremental encoder with N pulses per revolution (counted on every edge, N includes any
quadrature factor) reports floor(phi N / 2 pi) for cumulative wheel angle phi. Differencing two
readings gives the ticks per interval; the quantisation error of one reading lies in
[0, 2 pi / N) and, for angles uniformly spread within a tick, has variance (2 pi / N)^2 / 12
(Widrow & Kollar, *Quantization Noise*, ch. 4). Because the counter is cumulative, errors do
not accumulate: the sum of interval ticks always equals the last reading.

``slamkit.models.diff_drive.odometry_from_ticks`` turns tick increments into odometry.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError

__all__ = ["Encoder", "ticks_from_angle", "angle_from_ticks"]


def ticks_from_angle(wheel_angle_rad, ticks_per_rev: int) -> np.ndarray:
    """Cumulative wheel angle (any shape) -> int64 cumulative tick count (floor)."""
    if not ticks_per_rev > 0:
        raise ConfigError(f"ticks_per_rev must be positive, got {ticks_per_rev}")
    # a tiny relative epsilon keeps exact multiples of a tick (e.g. 1 rev) from flooring down
    ratio = np.asarray(wheel_angle_rad, dtype=float) * ticks_per_rev / (2.0 * np.pi)
    return np.floor(ratio + 1e-9 * np.maximum(1.0, np.abs(ratio))).astype(np.int64)


def angle_from_ticks(ticks, ticks_per_rev: int) -> np.ndarray:
    """Tick count -> wheel angle at the lower edge of that tick."""
    if not ticks_per_rev > 0:
        raise ConfigError(f"ticks_per_rev must be positive, got {ticks_per_rev}")
    return np.asarray(ticks, dtype=float) * (2.0 * np.pi / ticks_per_rev)


@dataclass(frozen=True)
class Encoder:
    """Incremental wheel encoder: resolution, read-out rate, optional random missed/extra ticks."""

    ticks_per_rev: int = 1024
    rate_hz: float = 500.0
    tick_noise_sigma: float = 0.0  # extra white noise on each interval count, in ticks

    def __post_init__(self) -> None:
        if not (int(self.ticks_per_rev) == self.ticks_per_rev and self.ticks_per_rev > 0):
            raise ConfigError(f"Encoder.ticks_per_rev must be a positive integer, got {self.ticks_per_rev}")
        if not (self.rate_hz > 0 and self.tick_noise_sigma >= 0):
            raise ConfigError(f"Encoder needs rate_hz > 0 and tick_noise_sigma >= 0, got {self}")

    @property
    def resolution_rad(self) -> float:
        return 2.0 * np.pi / self.ticks_per_rev

    @property
    def quantisation_variance_rad2(self) -> float:
        return self.resolution_rad**2 / 12.0

    def interval_ticks(self, rng: np.random.Generator | None, wheel_angle_rad) -> np.ndarray:
        """(N, ...) cumulative true wheel angles at successive reads -> (N-1, ...) tick
        increments, optionally with rounded Gaussian count noise (needs ``rng``)."""
        counts = ticks_from_angle(wheel_angle_rad, self.ticks_per_rev)
        inc = np.diff(counts, axis=0)
        if self.tick_noise_sigma > 0:
            if rng is None:
                raise ConfigError("Encoder.tick_noise_sigma > 0 needs an rng")
            inc = inc + np.rint(rng.standard_normal(inc.shape) * self.tick_noise_sigma).astype(np.int64)
        return inc
