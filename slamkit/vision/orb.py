"""ORB features (OpenCV) and Hamming matching (brute force, or guided within a pixel window) with
the ratio test and cross-check.

Rublee, Rabaud, Konolige & Bradski, "ORB: an efficient alternative to SIFT or SURF", ICCV 2011:
FAST corners on a scale pyramid ranked by the Harris response, an intensity-centroid
orientation and a rotated 256-bit BRIEF descriptor. ORB is the field's standard detector and
descriptor (ORB-SLAM), so slamkit uses OpenCV's implementation behind this small interface;
this is the only slamkit module that imports ``cv2`` (``tests/test_layers.py``).

Matching (Lowe, "Distinctive image features from scale-invariant keypoints", IJCV 2004, sec. 7.1):
for every descriptor of the first set the two nearest of the second by Hamming distance; a match
is kept when nearest < ``ratio`` x second nearest (ratio test), when it is also the first set's
nearest to its partner (cross-check), and when its distance is at most ``max_distance`` bits.
The distance table is computed with numpy (popcount of XOR over a 256-entry table).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError

__all__ = ["OrbConfig", "Features", "detect_orb", "match_descriptors", "match_descriptors_windowed",
           "hamming_distances"]


@dataclass(frozen=True)
class OrbConfig:
    num_features: int = 2000
    scale_factor: float = 1.2
    levels: int = 8
    fast_threshold: int = 20
    #: cells of a grid over the image; each detects num_features / cells on its own crop, which
    #: spreads the features over the image (far-field corners otherwise take most of them)
    grid_cols: int = 1
    grid_rows: int = 1

    def __post_init__(self) -> None:
        if self.num_features < 1 or self.levels < 1 or not self.scale_factor > 1.0:
            raise ConfigError("OrbConfig needs num_features >= 1, levels >= 1, scale_factor > 1")
        if self.grid_cols < 1 or self.grid_rows < 1:
            raise ConfigError("OrbConfig grid_cols and grid_rows must be >= 1")


@dataclass(frozen=True)
class Features:
    """Keypoints of one image: ``uv`` (N, 2) pixels, ``descriptors`` (N, 32) uint8, ``size`` and
    ``octave`` (N,) from the pyramid (octave k is scaled by scale_factor^-k)."""

    uv: np.ndarray
    descriptors: np.ndarray
    octave: np.ndarray
    response: np.ndarray

    def __len__(self) -> int:
        return len(self.uv)

    def subset(self, index) -> "Features":
        return Features(self.uv[index], self.descriptors[index], self.octave[index], self.response[index])


def _to_uint8(image) -> np.ndarray:
    a = np.asarray(image)
    if a.ndim != 2:
        raise ConfigError(f"an image is a (H, W) array, got shape {a.shape}")
    if a.dtype == np.uint8:
        return a
    return np.clip(np.rint(a), 0, 255).astype(np.uint8)


def detect_orb(image, config: OrbConfig = OrbConfig(), mask=None) -> Features:
    """ORB keypoints and descriptors of a (H, W) grey image (0..255)."""
    import cv2

    img = _to_uint8(image)
    H, W = img.shape
    cells = config.grid_cols * config.grid_rows
    orb = cv2.ORB_create(nfeatures=max(1, config.num_features // cells), scaleFactor=config.scale_factor,
                         nlevels=config.levels, fastThreshold=config.fast_threshold)
    parts: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
    us = np.linspace(0, W, config.grid_cols + 1).astype(int)
    vs = np.linspace(0, H, config.grid_rows + 1).astype(int)
    m = _EDGE_MARGIN_PX if cells > 1 else 0
    for i in range(config.grid_rows):
        for j in range(config.grid_cols):
            # each cell is detected on its own crop (plus the descriptor's margin) and keeps the
            # keypoints inside the cell: the cost stays that of one whole-image detection
            u0, u1 = max(0, us[j] - m), min(W, us[j + 1] + m)
            v0, v1 = max(0, vs[i] - m), min(H, vs[i + 1] + m)
            crop_mask = None
            if mask is not None:
                crop_mask = np.where(np.asarray(mask, bool)[v0:v1, u0:u1], 255, 0).astype(np.uint8)
            kp, des = orb.detectAndCompute(np.ascontiguousarray(img[v0:v1, u0:u1]), crop_mask)
            if des is None or not kp:
                continue
            uv = np.array([k.pt for k in kp], dtype=float) + (u0, v0)
            inside = (uv[:, 0] >= us[j]) & (uv[:, 0] < us[j + 1]) & (uv[:, 1] >= vs[i]) & (uv[:, 1] < vs[i + 1])
            octave = np.array([k.octave for k in kp], dtype=int)
            response = np.array([k.response for k in kp], dtype=float)
            parts.append((uv[inside], des[inside], octave[inside], response[inside]))
    if not parts:
        return Features(np.empty((0, 2)), np.empty((0, 32), np.uint8), np.empty(0, int), np.empty(0))
    return Features(*(np.concatenate(column) for column in zip(*parts)))


#: ORB's edgeThreshold / patch size (31 px): the margin a grid cell's crop gets on every side
_EDGE_MARGIN_PX = 31

_POPCOUNT = np.array([bin(i).count("1") for i in range(256)], dtype=np.uint16)


def hamming_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(Na, Nb) Hamming distances between uint8 descriptor rows (bits), in numpy (the reference
    that ``match_descriptors``' OpenCV brute-force search is tested against)."""
    a = np.asarray(a, dtype=np.uint8)
    b = np.asarray(b, dtype=np.uint8)
    out = np.zeros((len(a), len(b)), dtype=np.uint16)
    for k in range(a.shape[1]):  # byte by byte keeps memory at Na x Nb
        out += _POPCOUNT[np.bitwise_xor(a[:, k, None], b[None, :, k])]
    return out


def _two_nearest(desc_a: np.ndarray, desc_b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For every row of a: (index of the nearest row of b, its distance, the second distance)."""
    import cv2

    matcher = cv2.BFMatcher(cv2.NORM_HAMMING, crossCheck=False)
    k = min(2, len(desc_b))
    knn = matcher.knnMatch(np.ascontiguousarray(desc_a, np.uint8), np.ascontiguousarray(desc_b, np.uint8), k=k)
    first = np.array([m[0].trainIdx for m in knn], dtype=int)
    best = np.array([m[0].distance for m in knn], dtype=float)
    second = np.array([m[1].distance if len(m) > 1 else np.inf for m in knn], dtype=float)
    return first, best, second


def _two_nearest_in_cells(uv_a, desc_a, uv_b, desc_b, cell_px: float):
    """``_two_nearest`` restricted to a window: the rows of a in one cell of a ``cell_px`` grid
    are compared (``cv2.batchDistance``, K = 2) with the rows of b in that cell and its 8
    neighbours only. Returns (index into b or -1, best, second) per row of a."""
    import cv2

    n = len(desc_a)
    first = np.full(n, -1)
    best = np.full(n, np.inf)
    second = np.full(n, np.inf)
    cell_a = np.floor(uv_a / cell_px).astype(int)
    cell_b = np.floor(uv_b / cell_px).astype(int)
    cols = int(max(cell_a[:, 0].max(), cell_b[:, 0].max())) + 3
    key_a = (cell_a[:, 1] + 1) * cols + cell_a[:, 0] + 1
    key_b = (cell_b[:, 1] + 1) * cols + cell_b[:, 0] + 1
    order_b = np.argsort(key_b, kind="stable")
    sorted_b = key_b[order_b]
    for key in np.unique(key_a):
        rows = np.flatnonzero(key_a == key)
        near = np.concatenate([order_b[np.searchsorted(sorted_b, key + dv * cols - 1):
                                       np.searchsorted(sorted_b, key + dv * cols + 1, side="right")]
                               for dv in (-1, 0, 1)])
        if len(near) == 0:
            continue
        k = min(2, len(near))
        dist, nidx = cv2.batchDistance(desc_a[rows], desc_b[near], cv2.CV_32S, normType=cv2.NORM_HAMMING, K=k)
        first[rows] = near[nidx[:, 0]]
        best[rows] = dist[:, 0]
        if k == 2:
            second[rows] = dist[:, 1]
    return first, best, second


def match_descriptors_windowed(uv_a: np.ndarray, desc_a: np.ndarray, uv_b: np.ndarray, desc_b: np.ndarray,
                               window_px: float, ratio: float = 0.8, max_distance: int = 64) -> np.ndarray:
    """``match_descriptors`` (ratio test, cross-check, ``max_distance``) with every keypoint of a
    compared only with the keypoints of b near it (guided matching): both sets are bucketed in
    a grid of ``window_px`` cells and a keypoint's candidates are those of its cell and the 8
    around it, so every pair closer than ``window_px`` in u and v is compared (and none farther
    than 2 ``window_px``). The neighbourhood is symmetric, so the cross-check runs the same search
    from b. Used frame to frame, where the image motion is small; (M, 2) pairs sorted by i."""
    if len(desc_a) == 0 or len(desc_b) == 0:
        return np.empty((0, 2), dtype=int)
    uv_a, uv_b = np.asarray(uv_a, float), np.asarray(uv_b, float)
    desc_a, desc_b = np.ascontiguousarray(desc_a, np.uint8), np.ascontiguousarray(desc_b, np.uint8)
    first, best, second = _two_nearest_in_cells(uv_a, desc_a, uv_b, desc_b, window_px)
    keep = (first >= 0) & (best < ratio * second) & (best <= max_distance)
    if keep.any():
        targets = np.unique(first[keep])
        back, _, _ = _two_nearest_in_cells(uv_b[targets], desc_b[targets], uv_a, desc_a, window_px)
        nearest_in_a = np.full(len(desc_b), -1)
        nearest_in_a[targets] = back
        keep &= nearest_in_a[np.maximum(first, 0)] == np.arange(len(desc_a))
    ia = np.flatnonzero(keep)
    return np.stack([ia, first[ia]], axis=1)


def match_descriptors(desc_a: np.ndarray, desc_b: np.ndarray, ratio: float = 0.8, cross_check: bool = True,
                      max_distance: int = 64) -> np.ndarray:
    """(M, 2) index pairs (i into a, j into b) passing the ratio test, the cross-check and
    ``max_distance``; sorted by i. Brute force (every pair's Hamming distance) by OpenCV."""
    if len(desc_a) == 0 or len(desc_b) == 0:
        return np.empty((0, 2), dtype=int)
    first, best, second = _two_nearest(desc_a, desc_b)
    keep = (best < ratio * second) & (best <= max_distance)
    if cross_check and keep.any():
        # only the descriptors of b that some match points at need their own nearest in a
        targets = np.unique(first[keep])
        back, _, _ = _two_nearest(np.asarray(desc_b)[targets], desc_a)
        nearest_in_a = np.full(len(desc_b), -1)
        nearest_in_a[targets] = back
        keep &= nearest_in_a[first] == np.arange(len(desc_a))
    ia = np.flatnonzero(keep)
    return np.stack([ia, first[ia]], axis=1)
