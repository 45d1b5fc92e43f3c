"""2D lidar measurement models: the beam model and the likelihood-field model.

Both follow Thrun, Burgard & Fox, *Probabilistic Robotics* (2005):

Beam model (sec. 6.3, Table 6.1). A beam with expected range z* (from ray
casting, which lives in ``slamkit.maps``) measures z with the mixture

    p(z | z*) = z_hit p_hit + z_short p_short + z_max p_max + z_rand p_rand
    p_hit   = eta N(z; z*, sigma_hit^2) on [0, z_max], eta = 1 / (Phi((z_max - z*)/s) - Phi(-z*/s))
    p_short = eta lambda exp(-lambda z) on [0, z*],     eta = 1 / (1 - exp(-lambda z*))
    p_max   = 1 if z = z_max (a point mass: "no return")
    p_rand  = 1 / z_max on [0, z_max)

with z_hit + z_short + z_max + z_rand = 1. A NaN range (``Scan`` convention for no return) is a
max-range reading.

Likelihood field (sec. 6.4, Table 6.3). Each beam end point that is not a max-range reading
is scored by its distance d to the nearest obstacle, from a precomputed distance field:

    p = z_hit N(d; 0, sigma_hit^2) + z_rand / z_max

The field and the world -> cell function are passed in (``slamkit.maps`` computes them; models
may not import maps). Both models are vectorised over particles and beams: poses (P, 3),
ranges (B,), expected ranges (P, B); they return per-particle log-likelihoods (P,).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.special import ndtr, ndtri

from slamkit.errors import ConfigError
from slamkit.geometry import se2

__all__ = [
    "BeamModel",
    "LikelihoodFieldModel",
    "scan_endpoints",
    "scan_endpoints_jacobian",
]

_SQRT_2PI = np.sqrt(2.0 * np.pi)


def _check_weights(obj, names):
    weights = [getattr(obj, n) for n in names]
    if any(w < 0 for w in weights) or abs(sum(weights) - 1.0) > 1e-9:
        raise ConfigError(f"{type(obj).__name__} weights {dict(zip(names, weights))} must be >= 0 and sum to 1")


@dataclass(frozen=True)
class BeamModel:
    """Beam-model mixture parameters (weights sum to 1; sigma in m, lambda in 1/m)."""

    z_hit: float = 0.7
    z_short: float = 0.1
    z_max: float = 0.1
    z_rand: float = 0.1
    sigma_hit_m: float = 0.2
    lambda_short: float = 0.5

    def __post_init__(self) -> None:
        _check_weights(self, ("z_hit", "z_short", "z_max", "z_rand"))
        if not (self.sigma_hit_m > 0 and self.lambda_short > 0):
            raise ConfigError(f"BeamModel needs sigma_hit_m > 0 and lambda_short > 0, got {self}")

    def components(self, z_m, z_star_m, max_range_m: float) -> dict[str, np.ndarray]:
        """The four component values p_hit, p_short, p_max, p_rand (broadcast shapes)."""
        z = np.asarray(z_m, dtype=float)
        zs = np.asarray(z_star_m, dtype=float)
        is_max = np.isnan(z) | (z >= max_range_m)
        zc = np.where(np.isnan(z), max_range_m, np.minimum(z, max_range_m))
        s = self.sigma_hit_m
        inside = zc >= 0.0
        eta_hit = 1.0 / np.maximum(ndtr((max_range_m - zs) / s) - ndtr(-zs / s), 1e-300)
        p_hit = np.where(inside, eta_hit * np.exp(-0.5 * ((zc - zs) / s) ** 2) / (s * _SQRT_2PI), 0.0)
        lam = self.lambda_short
        # -expm1(-x) = 1 - exp(-x) without cancellation for small z*; z* = 0 leaves no room for
        # a short reading, so p_short is 0 there
        denom = -np.expm1(-lam * zs)
        p_short = np.where(inside & (zc <= zs) & (denom > 0),
                           lam * np.exp(-lam * zc) / np.where(denom > 0, denom, 1.0), 0.0)
        p_max = is_max.astype(float)
        p_rand = np.where(inside & ~is_max, 1.0 / max_range_m, 0.0)
        return {"hit": p_hit, "short": p_short, "max": p_max, "rand": p_rand}

    def probability(self, z_m, z_star_m, max_range_m: float) -> np.ndarray:
        """Per-beam p(z | z*) (density for z < z_max plus the point mass at z_max)."""
        c = self.components(z_m, z_star_m, max_range_m)
        return self.z_hit * c["hit"] + self.z_short * c["short"] + self.z_max * c["max"] + self.z_rand * c["rand"]

    def log_likelihood(self, ranges_m, expected_ranges_m, max_range_m: float) -> np.ndarray:
        """Sum over beams of log p: ranges (B,) or (P, B), expected (P, B) -> (P,)
        (beams assumed independent given the map, as in Table 6.1)."""
        p = self.probability(ranges_m, expected_ranges_m, max_range_m)
        return np.sum(np.log(np.maximum(p, 1e-300)), axis=-1)

    def fit(self, ranges_m, expected_ranges_m, max_range_m: float, iterations: int = 200,
            tol: float = 1e-7) -> "BeamModel":
        """Maximum-likelihood parameters for measured ranges given expected ranges, by EM.

        Probabilistic Robotics Table 6.2 computes the responsibilities e_hit, e_short, e_max,
        e_rand without the current mixture weights and iterates; we run the full EM (weights
        included), start from ``self``, and solve the lambda M-step exactly for the exponential
        truncated at z* (1/lambda - z - z* e^(-lambda z*) / (1 - e^(-lambda z*)), weighted by
        e_short, set to zero). sigma uses the untruncated Gaussian update of Table 6.2 line 11,
        accurate while z* lies several sigma inside [0, z_max].
        """
        from scipy.optimize import brentq

        z = np.asarray(ranges_m, dtype=float).ravel()
        zs = np.broadcast_to(np.asarray(expected_ranges_m, dtype=float), np.shape(ranges_m)).ravel()
        zc = np.where(np.isnan(z), max_range_m, np.minimum(z, max_range_m))
        model = self
        for _ in range(iterations):
            c = model.components(z, zs, max_range_m)
            parts = np.stack([model.z_hit * c["hit"], model.z_short * c["short"],
                              model.z_max * c["max"], model.z_rand * c["rand"]])
            e = parts / np.maximum(parts.sum(axis=0), 1e-300)
            weights = e.mean(axis=1)
            sigma = np.sqrt(np.sum(e[0] * (zc - zs) ** 2) / max(e[0].sum(), 1e-300))
            lam = model.lambda_short
            if e[1].sum() > 1e-9:
                def score(lmb):
                    tail = zs * np.exp(-lmb * zs) / np.maximum(-np.expm1(-lmb * zs), 1e-300)
                    return np.sum(e[1] * (1.0 / lmb - zc - tail))
                lo, hi = 1e-6, 1e4
                if score(lo) > 0 > score(hi):
                    lam = brentq(score, lo, hi, xtol=1e-12)
            w = weights / weights.sum()
            new = BeamModel(*(float(v) for v in w), sigma_hit_m=float(max(sigma, 1e-6)), lambda_short=float(lam))
            change = max(abs(a - b) for a, b in zip(new.__dict__.values(), model.__dict__.values()))
            model = new
            if change < tol:
                break
        return model

    def sample(self, rng: np.random.Generator, expected_ranges_m, max_range_m: float) -> np.ndarray:
        """Draw ranges from the mixture for expected ranges z* (any shape); max readings are
        returned as exactly ``max_range_m``. Draw order is fixed (component, then one uniform
        per beam per component) so a seed reproduces a scan."""
        zs = np.clip(np.asarray(expected_ranges_m, dtype=float), 0.0, max_range_m)
        shape = zs.shape
        pick = rng.random(shape)
        u = rng.random((3,) + shape)
        edges = np.cumsum([self.z_hit, self.z_short, self.z_max])
        s = self.sigma_hit_m
        # hit: truncated normal on [0, z_max] by inverse CDF
        lo, hi = ndtr(-zs / s), ndtr((max_range_m - zs) / s)
        hit = np.clip(zs + s * ndtri(np.clip(lo + u[0] * (hi - lo), 1e-16, 1 - 1e-16)), 0.0, max_range_m)
        # short: exponential truncated to [0, z*] by inverse CDF
        lam = self.lambda_short
        short = -np.log1p(u[1] * np.expm1(-lam * zs)) / lam
        rand = u[2] * max_range_m
        return np.where(pick < edges[0], hit,
                        np.where(pick < edges[1], short, np.where(pick < edges[2], max_range_m, rand)))


def scan_endpoints(world_xytheta_body, ranges_m, angles_rad, body_xytheta_sensor=(0.0, 0.0, 0.0)):
    """Beam end points in the world: poses (..., 3), ranges and angles (B,) -> (..., B, 2)."""
    x = np.asarray(world_xytheta_body, dtype=float)
    world_T_sensor = se2.compose(x, np.asarray(body_xytheta_sensor, dtype=float))
    r = np.asarray(ranges_m, dtype=float)
    a = np.asarray(angles_rad, dtype=float)
    sensor_p = np.stack([r * np.cos(a), r * np.sin(a)], axis=-1)  # (B, 2)
    return se2.transform_points(world_T_sensor[..., None, :], sensor_p)


def scan_endpoints_jacobian(world_xytheta_body, ranges_m, angles_rad, body_xytheta_sensor=(0.0, 0.0, 0.0)):
    """d(end point)/d(pose): (..., B, 2, 3) = [[1, 0, -(e_y - y)], [0, 1, e_x - x]]."""
    x = np.asarray(world_xytheta_body, dtype=float)
    e = scan_endpoints(x, ranges_m, angles_rad, body_xytheta_sensor)
    rel = e - x[..., None, :2]
    J = np.zeros(e.shape[:-1] + (2, 3))
    J[..., 0, 0] = J[..., 1, 1] = 1.0
    J[..., 0, 2] = -rel[..., 1]
    J[..., 1, 2] = rel[..., 0]
    return J


@dataclass(frozen=True)
class LikelihoodFieldModel:
    """Likelihood-field parameters (z_hit + z_rand = 1)."""

    z_hit: float = 0.9
    z_rand: float = 0.1
    sigma_hit_m: float = 0.2

    def __post_init__(self) -> None:
        _check_weights(self, ("z_hit", "z_rand"))
        if not self.sigma_hit_m > 0:
            raise ConfigError(f"LikelihoodFieldModel.sigma_hit_m must be positive, got {self.sigma_hit_m}")

    def log_likelihood(
        self,
        world_xytheta_body,
        ranges_m,
        angles_rad,
        max_range_m: float,
        distance_field_m: np.ndarray,
        world_to_cell: Callable[[np.ndarray], np.ndarray],
        body_xytheta_sensor=(0.0, 0.0, 0.0),
        outside_distance_m: float = np.inf,
        field_lookup: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> np.ndarray:
        """Per-particle log-likelihood (P,) of one scan for poses (P, 3) (or (3,) -> scalar).

        ``distance_field_m[iy, ix]`` is the distance to the nearest obstacle in metres;
        ``world_to_cell((N, 2) world xy) -> (N, 2) integer (ix, iy)`` (as
        ``OccupancyGrid.world_to_cell``). End points outside the field get
        ``outside_distance_m`` (default inf: only the random component explains them).
        Max-range and NaN beams are skipped (Table 6.3, line 4). ``field_lookup((N, 2) world
        xy) -> (N,)`` replaces the nearest-cell lookup (e.g. bilinear interpolation of the field,
        which removes the half-cell quantisation of the end points' distances).
        """
        x = np.asarray(world_xytheta_body, dtype=float)
        r = np.asarray(ranges_m, dtype=float)
        a = np.asarray(angles_rad, dtype=float)
        field = np.asarray(distance_field_m, dtype=float)
        if r.shape != a.shape or r.ndim != 1:
            raise ConfigError(f"ranges_m {r.shape} and angles_rad {a.shape} must be equal 1-D shapes")
        valid = np.isfinite(r) & (r < max_range_m)
        pts = scan_endpoints(x, r[valid], a[valid], body_xytheta_sensor)  # (..., Bv, 2)
        if field_lookup is not None:
            dist = np.asarray(field_lookup(pts.reshape(-1, 2)), float).reshape(pts.shape[:-1])
            return self._log_p(dist, max_range_m)
        cells = np.asarray(world_to_cell(pts.reshape(-1, 2))).reshape(pts.shape).astype(np.int64)
        h, w = field.shape
        ix, iy = cells[..., 0], cells[..., 1]
        inside = (ix >= 0) & (ix < w) & (iy >= 0) & (iy < h)
        dist = np.full(ix.shape, float(outside_distance_m))
        dist[inside] = field[iy[inside], ix[inside]]
        return self._log_p(dist, max_range_m)

    def _log_p(self, dist: np.ndarray, max_range_m: float) -> np.ndarray:
        s = self.sigma_hit_m
        p = self.z_hit * np.exp(-0.5 * (dist / s) ** 2) / (s * _SQRT_2PI) + self.z_rand / max_range_m
        return np.sum(np.log(p), axis=-1)
