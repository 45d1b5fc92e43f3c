"""Place recognition for 2D scans by Scan Context: loop-closure candidates that do not depend on
the current estimate, so a revisit is found however far the estimate has drifted.

Kim & Kim, "Scan Context: Egocentric spatial descriptor for place recognition within 3D point
cloud map", IROS 2018 (and the authors' reference implementation, irapkaist/scancontext,
``Scancontext.cpp``), for a planar scan:

* **Descriptor** (paper sec. III-A): the points (body frame) within ``max_radius_m`` are binned
  by range into ``num_rings`` rings and by bearing into ``num_sectors`` sectors (sector 0 starts
  at bearing 0, counter-clockwise). The paper keeps the maximum height per bin; a planar scan has
  none, so a bin holds its occupancy (1 when some point falls in it: the bins a wall crosses),
  blurred along the rings by a Gaussian of ``ring_blur_m``. Why the blur: a revisit is seen from
  a keyframe up to a few decimetres off the first visit's, and a wall 0.5 m nearer moves to the
  next ring. Measured on simulated offices (four 40 m x 40 m worlds, 40 poses each, 360 deg
  scans; "same place": 0.5 m away at any heading, "different": > 5 m apart), the probability
  that a same-place pair is nearer than a different-place pair (AUC): occupancy 0.86, per-sector
  free space up to the nearest / farthest point 0.89 / 0.92, point counts 0.86, blurred over
  sigma 0.42 / 0.72 / 1.2 m 0.96 / 0.98 / 0.97.
* **Distance** (eq. 5-6): the mean, over the sectors non-empty in both descriptors, of the
  cosine distance between corresponding columns, minimised over every circular column shift
  (all ``num_sectors`` of them; the reference searches 10% around the sector key's best shift,
  a shortcut not needed at this size). The best shift k is the yaw: the query's heading in the
  candidate's frame is k * 2 pi / num_sectors, within one sector of the truth.
* **Ring key** (sec. III-C): the row means (the occupied fraction of each ring) -- invariant to
  the heading; the candidates are the ``num_candidates`` nearest ring keys (L2), then ranked by
  the full distance and kept below ``max_distance``.

Each candidate is a (place, yaw) hypothesis only: the loop closure verifies it by the global
matcher and ICP (``slamkit.systems.lidar_slam``). A 2D laser sees 180-270 deg, so one scan
seen from the opposite heading shares little with the first visit; the system describes a
keyframe by the scans of the last few keyframes stacked in its frame (a local submap), which
covers the full circle once the robot has moved a little.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError
from slamkit.geometry.angles import wrap_angle


@dataclass(frozen=True)
class ScanContextConfig:
    #: rings (range bins) and sectors (bearing bins; 60 = 6 deg, the paper's 20 x 60)
    num_rings: int = 20
    num_sectors: int = 60
    #: points beyond this range are ignored (the paper: 80 m outdoors; indoors the walls are near)
    max_radius_m: float = 12.0
    #: the occupancy is blurred along the rings by a Gaussian of this standard deviation (0: off)
    ring_blur_m: float = 0.72
    #: nearest ring keys compared by the full distance (the paper: 10)
    num_candidates: int = 10
    #: candidates above this distance are not places revisited (the reference: 0.13 alone,
    #: 0.4-0.6 when a geometric check follows). 0.2: on the hospital log (odometry, with the drift
    #: region's filter) 321 candidates, the 3 that fit (ICP fitness 0.81-0.87) at 0.07-0.20
    max_distance: float = 0.2
    #: as a loop-closure candidate source (``slamkit.systems.lidar_slam``): a keyframe is described
    #: by the scans of the keyframes within its last ``submap_path_m`` of travel (at most
    #: ``submap_max_keyframes`` of them, evenly spread) stacked in its frame at their chained
    #: scan-match poses -- a 2D laser sees half the circle at once, and a corridor travelled the
    #: other way is seen from behind; the best ``max_candidates_per_keyframe`` matches are tried,
    #: each by branch and bound within +-``window_xy_m`` of the matched place and
    #: +-``window_theta_rad`` of the descriptor's yaw (two sectors: the yaw is within one)
    submap_path_m: float = 6.0
    submap_max_keyframes: int = 16
    max_candidates_per_keyframe: int = 1
    window_xy_m: float = 2.0
    window_theta_rad: float = float(np.deg2rad(12.0))
    #: a candidate must lie inside this probability's drift region (``DriftRegion``, uncapped)
    region_probability: float = 0.99

    def __post_init__(self) -> None:
        # bounded above too: every keyframe keeps a num_rings x num_sectors descriptor
        if not (1 <= self.num_rings <= 500 and 4 <= self.num_sectors <= 3600):
            raise ConfigError(f"ScanContextConfig: num_rings must lie in 1..500 and num_sectors in 4..3600, "
                              f"got {self.num_rings}, {self.num_sectors}")
        if not self.ring_blur_m >= 0:
            raise ConfigError(f"ScanContextConfig.ring_blur_m must be >= 0, got {self.ring_blur_m}")
        if not self.max_radius_m > 0:
            raise ConfigError(f"ScanContextConfig.max_radius_m must be > 0, got {self.max_radius_m}")
        if self.num_candidates < 1:
            raise ConfigError("ScanContextConfig.num_candidates must be >= 1")
        if not self.submap_path_m >= 0 or self.submap_max_keyframes < 1 or self.max_candidates_per_keyframe < 0:
            raise ConfigError("ScanContextConfig: submap_path_m must be >= 0, submap_max_keyframes >= 1 and "
                              "max_candidates_per_keyframe >= 0")
        if not 0 < self.region_probability < 1:
            raise ConfigError(f"ScanContextConfig.region_probability must lie in (0, 1), got {self.region_probability}")
        if not (self.window_xy_m >= 0 and 0 <= self.window_theta_rad <= np.pi):
            raise ConfigError("ScanContextConfig: window_xy_m must be >= 0 and window_theta_rad in [0, pi]")
        if not 0 < self.max_distance <= 1:
            raise ConfigError(f"ScanContextConfig.max_distance must lie in (0, 1], got {self.max_distance}")

    @property
    def sector_rad(self) -> float:
        return 2.0 * np.pi / self.num_sectors


def scan_context(body_xy_points: np.ndarray, config: ScanContextConfig = ScanContextConfig()) -> np.ndarray:
    """(num_rings, num_sectors) occupancy descriptor of points (N, 2) in the sensor's frame
    (non-finite points ignored)."""
    p = np.asarray(body_xy_points, dtype=float).reshape(-1, 2)
    p = p[np.all(np.isfinite(p), axis=1)]
    r = np.hypot(p[:, 0], p[:, 1])
    keep = r < config.max_radius_m
    r, p = r[keep], p[keep]
    bearing = np.mod(np.arctan2(p[:, 1], p[:, 0]), 2.0 * np.pi)
    ring = np.minimum((r / config.max_radius_m * config.num_rings).astype(np.int64), config.num_rings - 1)
    sector = np.minimum((bearing / config.sector_rad).astype(np.int64), config.num_sectors - 1)
    desc = np.zeros((config.num_rings, config.num_sectors))
    desc[ring, sector] = 1.0
    return _blur_rings(desc, config.ring_blur_m / (config.max_radius_m / config.num_rings))


def _blur_rings(desc: np.ndarray, sigma_rings: float) -> np.ndarray:
    """``desc`` convolved along the rings (axis 0) with a Gaussian of ``sigma_rings`` (truncated
    at 3 sigma, zero beyond the first and last ring)."""
    if sigma_rings <= 0:
        return desc
    half = int(np.ceil(3.0 * sigma_rings))
    x = np.arange(-half, half + 1)
    kernel = np.exp(-0.5 * (x / sigma_rings) ** 2)
    R = desc.shape[0]
    # (R, R) band matrix: out[r] = sum_s kernel[s - r + half] desc[s]
    d = np.arange(R)[None, :] - np.arange(R)[:, None]
    band = np.where(np.abs(d) <= half, kernel[np.clip(d + half, 0, 2 * half)], 0.0)
    return band @ desc


def ring_key(descriptor: np.ndarray) -> np.ndarray:
    """The heading-invariant key: the mean of each ring (row) over the sectors, (num_rings,)."""
    return np.asarray(descriptor, dtype=float).mean(axis=-1)


def _unit_columns(desc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    norm = np.linalg.norm(desc, axis=-2, keepdims=True)
    nonzero = norm[..., 0, :] > 0
    return np.divide(desc, norm, out=np.zeros_like(desc), where=norm > 0), nonzero


def distances(query: np.ndarray, candidates: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Scan Context distance (eq. 6) of ``query`` (R, S) to each of ``candidates`` (M, R, S):
    (distance (M,) in [0, 1], best shift (M,) in 0..S-1), the shift k such that the candidate
    is most like the query's columns moved by k (``np.roll(query, k, axis=1)``). Distance 1 when
    no sector is non-empty in both at any shift."""
    q = np.asarray(query, dtype=float)
    c = np.asarray(candidates, dtype=float).reshape(-1, *q.shape)
    S = q.shape[1]
    qn, qz = _unit_columns(q)
    cn, cz = _unit_columns(c)
    # rolled[k][:, col] = query[:, col - k] for every shift k at once: (S, R, S)
    idx = (np.arange(S)[None, :] - np.arange(S)[:, None]) % S
    rolled, rolled_nz = qn[:, idx].transpose(1, 0, 2), qz[idx]
    dots = np.einsum("krc,mrc->mkc", rolled, cn)                     # (M, shifts, sectors)
    both = rolled_nz[None, :, :] & cz[:, None, :]
    count = both.sum(axis=2)
    sim = np.where(count > 0, (dots * both).sum(axis=2) / np.maximum(count, 1), 0.0)
    dist = 1.0 - sim
    best = np.argmin(dist, axis=1)
    return dist[np.arange(len(c)), best], best


def distance(query: np.ndarray, candidate: np.ndarray) -> tuple[float, int]:
    """``distances`` for one pair: (distance, shift)."""
    d, k = distances(query, np.asarray(candidate)[None])
    return float(d[0]), int(k[0])


def yaw_of_shift(shift: int, config: ScanContextConfig = ScanContextConfig()) -> float:
    """The query's heading in the candidate's frame for a best ``shift`` (rad, wrapped)."""
    return float(wrap_angle(shift * config.sector_rad))


@dataclass(frozen=True)
class PlaceMatch:
    """A candidate place: the stored entry ``index``, its Scan Context ``distance`` and the
    query's heading in its frame ``yaw_rad`` (within one sector)."""

    index: int
    distance: float
    yaw_rad: float


class ScanContextDatabase:
    """Descriptors of the places seen so far: ``add(index, descriptor)``, then ``query(descriptor,
    allowed)`` -- the nearest ring keys among the entries ``allowed`` admits (index and path gaps
    are the caller's), ranked by the full distance, those within ``max_distance``. The ring keys
    are searched exhaustively (K x num_rings floats: 7000 keyframes are 0.1 ms, below a k-d
    tree's rebuilds)."""

    def __init__(self, config: ScanContextConfig = ScanContextConfig()):
        self.config = config
        self._index: list[int] = []
        self._desc: list[np.ndarray] = []
        self._keys = np.zeros((64, config.num_rings))

    def __len__(self) -> int:
        return len(self._index)

    def add(self, index: int, descriptor: np.ndarray) -> None:
        n = len(self._index)
        if n == len(self._keys):
            self._keys = np.concatenate([self._keys, np.zeros_like(self._keys)])
        self._keys[n] = ring_key(descriptor)
        self._index.append(int(index))
        self._desc.append(np.asarray(descriptor, dtype=float))

    def query(self, descriptor: np.ndarray, allowed: np.ndarray | None = None) -> list[PlaceMatch]:
        """Matches within ``max_distance``, best first; ``allowed`` (len(self),) bool masks the
        entries that may be returned (in the order added)."""
        n = len(self._index)
        if n == 0:
            return []
        cfg = self.config
        d_key = np.linalg.norm(self._keys[:n] - ring_key(descriptor)[None, :], axis=1)
        if allowed is not None:
            d_key = np.where(np.asarray(allowed, dtype=bool)[:n], d_key, np.inf)
        m = min(cfg.num_candidates, int(np.isfinite(d_key).sum()))
        if m == 0:
            return []
        near = np.argpartition(d_key, m - 1)[:m]
        dist, shift = distances(descriptor, np.stack([self._desc[k] for k in near]))
        order = np.argsort(dist, kind="stable")
        return [PlaceMatch(self._index[near[k]], float(dist[k]), yaw_of_shift(int(shift[k]), cfg))
                for k in order if dist[k] <= cfg.max_distance]
