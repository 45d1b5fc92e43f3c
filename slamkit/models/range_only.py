"""Range-only sensor (ranging radios, UWB beacons): r = |m - p| from the body origin p to a
beacon m, its Jacobians, the same with an unknown scale s (r = s |m - p|: a radio whose ranges
are a few percent long, as Plaza's are 7%; :func:`observe_scaled_jacobians`), and trilateration of an unknown beacon from ranges taken over a
baseline.

Trilateration (delayed landmark initialisation, Djugash & Singh, "Range-only SLAM for robots
operating cooperatively with sensor networks", ICRA 2006; Kantor & Singh 2002): subtracting
the first range equation from the others, |m - p_k|^2 - |m - p_0|^2 = r_k^2 - r_0^2, gives the
linear system 2 (p_k - p_0)^T m = |p_k|^2 - |p_0|^2 - r_k^2 + r_0^2. Its least-squares solution
is exact for noise-free ranges from positions that are not collinear. Along a nearly straight
baseline the system is ill-conditioned and the beacon's mirror image across the baseline fits
the ranges equally well: :func:`trilaterate` returns both candidates (the linear solution
refined by Gauss-Newton on the ranges, and its reflection across the baseline's principal
axis, refined the same way; one when both converge to the same point) with their RMS range
residuals, best first; the caller picks the
one later ranges confirm (or the best when they differ clearly).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from slamkit.errors import ConfigError


def observe(world_p_body: np.ndarray, world_p_landmark: np.ndarray) -> np.ndarray:
    """Range (...,) from positions (..., 2) to landmarks (..., 2) (broadcast)."""
    d = np.asarray(world_p_landmark, dtype=float) - np.asarray(world_p_body, dtype=float)
    return np.hypot(d[..., 0], d[..., 1])


def observe_jacobians(world_p_body: np.ndarray, world_p_landmark: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """(dr/dp (..., 2), dr/dm (..., 2)); the unit vector from the body to the landmark (zero
    when they coincide)."""
    d = np.asarray(world_p_landmark, dtype=float) - np.asarray(world_p_body, dtype=float)
    r = np.hypot(d[..., 0], d[..., 1])[..., None]
    u = np.divide(d, r, out=np.zeros_like(d), where=r > 0)
    return -u, u


def observe_scaled_jacobians(world_p_body: np.ndarray, world_p_landmark: np.ndarray, scale: float
                             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Jacobians of the scaled range r = s |m - p|: (dr/dp (..., 2), dr/dm (..., 2),
    dr/ds (...,)) = (-s u, s u, |m - p|) with u the unit vector from the body to the landmark."""
    Jp, Jm = observe_jacobians(world_p_body, world_p_landmark)
    return scale * Jp, scale * Jm, observe(world_p_body, world_p_landmark)


class Trilateration(NamedTuple):
    """One candidate beacon position with the RMS of its range residuals (m)."""

    world_p_landmark: np.ndarray
    rms_m: float


def _refine(m: np.ndarray, positions: np.ndarray, ranges: np.ndarray, iterations: int = 10
            ) -> np.ndarray:
    """Gauss-Newton on sum (|m - p_k| - r_k)^2 from ``m``."""
    for _ in range(iterations):
        r_hat = observe(positions, m)
        _, J = observe_jacobians(positions, m)
        step, *_ = np.linalg.lstsq(J, ranges - r_hat, rcond=None)
        m = m + step
        if np.linalg.norm(step) < 1e-9:
            break
    return m


def trilaterate(world_p_body: np.ndarray, range_m: np.ndarray) -> list[Trilateration]:
    """Candidate beacon positions from ranges (K,) taken at positions (K, 2), K >= 3, best
    (smallest RMS residual) first: the linear least-squares solution and its mirror image
    across the baseline's principal axis, each refined by Gauss-Newton (see module docstring).
    Empty when the positions do not span a baseline (all within 1 mm of each other)."""
    p = np.asarray(world_p_body, dtype=float).reshape(-1, 2)
    r = np.asarray(range_m, dtype=float).reshape(-1)
    if len(p) < 3 or len(p) != len(r):
        return []
    centre = p.mean(axis=0)
    q = p - centre
    _, s, vt = np.linalg.svd(q, full_matrices=False)
    if s[0] < 1e-3:
        return []
    A = 2.0 * (q[1:] - q[0])
    b = np.sum(q[1:] ** 2, axis=1) - np.sum(q[0] ** 2) - r[1:] ** 2 + r[0] ** 2
    m, *_ = np.linalg.lstsq(A, b, rcond=None)
    if s[1] < 1e-3 * s[0]:
        # collinear positions: the linear system fixes only the along-baseline coordinate; the
        # cross-baseline offset follows from the mean squared range
        along = vt[0] @ m
        cross2 = np.mean(r**2 - np.sum((q - along * vt[0]) ** 2, axis=1))
        m = along * vt[0] + np.sqrt(max(cross2, 0.0)) * vt[1]
    axis = vt[0]
    mirror = 2.0 * (m @ axis) * axis - m          # reflection across the line through the centre
    out = []
    for guess in (m, mirror):
        refined = _refine(guess, q, r)
        rms = float(np.sqrt(np.mean((observe(q, refined) - r) ** 2)))
        if not any(np.linalg.norm(refined + centre - c.world_p_landmark) < 1e-2 for c in out):
            out.append(Trilateration(refined + centre, rms))
    return sorted(out, key=lambda c: c.rms_m)


@dataclass(frozen=True)
class DelayedInitConfig:
    """When a beacon seen only by range is initialised (:class:`BeaconInitialiser`): after at
    least ``min_ranges`` ranges taken over a baseline of ``min_baseline_m`` (the extent of the
    ranging positions along their principal axis), when the best trilateration fits the
    buffered ranges to ``max_rms_m`` RMS and its mirror candidate (if any) fits worse by at
    least ``min_rms_gap_m``. The buffer keeps the newest ``max_ranges`` ranges."""

    min_ranges: int = 15
    min_baseline_m: float = 10.0
    max_rms_m: float = 2.0
    min_rms_gap_m: float = 0.5
    max_ranges: int = 300

    def __post_init__(self) -> None:
        if self.min_ranges < 3 or self.max_ranges < self.min_ranges:
            raise ConfigError(f"need 3 <= min_ranges <= max_ranges, got {self.min_ranges}, {self.max_ranges}")
        for name in ("min_baseline_m", "max_rms_m", "min_rms_gap_m"):
            if not getattr(self, name) >= 0:
                raise ConfigError(f"DelayedInitConfig.{name} must be >= 0, got {getattr(self, name)}")


class BeaconFix(NamedTuple):
    """An initialised beacon: the chosen trilateration, its covariance (the least-squares
    fit's, with the larger of the fit's RMS and the assumed range sigma), and the buffered
    ranges it came from with their positions and the callers' tags."""

    trilateration: Trilateration
    covariance: np.ndarray
    world_p_body: np.ndarray
    range_m: np.ndarray
    tags: list


class BeaconInitialiser:
    """Delayed initialisation of range-only beacons, the one rule every estimator uses: ranges
    to a beacon not yet in the map are buffered with the position they were taken from (and a
    caller's tag, e.g. a pose index); :meth:`add` returns the chosen trilateration and the
    buffered ranges (a :class:`BeaconFix`) once :class:`DelayedInitConfig` is satisfied, and
    forgets the beacon."""

    def __init__(self, config: DelayedInitConfig | None = None, sigma_range_m: float = 0.0) -> None:
        self.config = config or DelayedInitConfig()
        self.sigma_range_m = float(sigma_range_m)
        self._buffer: dict[int, list[tuple[np.ndarray, float, object]]] = {}

    def pending(self) -> dict[int, int]:
        """Buffered ranges per beacon not yet initialised."""
        return {k: len(v) for k, v in self._buffer.items()}

    def add(self, beacon_id: int, world_p_body: np.ndarray, range_m: float, tag: object = None
            ) -> BeaconFix | None:
        c = self.config
        buf = self._buffer.setdefault(int(beacon_id), [])
        buf.append((np.asarray(world_p_body, dtype=float).reshape(2).copy(), float(range_m), tag))
        if len(buf) > c.max_ranges:
            del buf[0]
        if len(buf) < c.min_ranges:
            return None
        p = np.array([b[0] for b in buf])
        q = p - p.mean(axis=0)
        axis = np.linalg.svd(q, full_matrices=False)[2][0]
        along = q @ axis
        if along.max() - along.min() < c.min_baseline_m:
            return None
        r = np.array([b[1] for b in buf])
        candidates = trilaterate(p, r)
        if not candidates or candidates[0].rms_m > c.max_rms_m:
            return None
        if len(candidates) > 1 and candidates[1].rms_m - candidates[0].rms_m < c.min_rms_gap_m:
            return None
        del self._buffer[int(beacon_id)]
        best = candidates[0]
        cov = trilateration_covariance(p, best.world_p_landmark, max(best.rms_m, self.sigma_range_m))
        return BeaconFix(best, cov, p, r, [b[2] for b in buf])


def trilateration_covariance(world_p_body: np.ndarray, world_p_landmark: np.ndarray,
                             sigma_m: float) -> np.ndarray:
    """(2, 2) covariance of a least-squares trilateration: sigma^2 (J^T J)^-1 with J (K, 2) the
    range Jacobians with respect to the beacon at the ranging positions."""
    _, J = observe_jacobians(np.asarray(world_p_body, dtype=float).reshape(-1, 2),
                             np.asarray(world_p_landmark, dtype=float).reshape(2))
    return sigma_m**2 * np.linalg.pinv(J.T @ J)
