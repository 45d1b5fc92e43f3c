"""Two-view geometry of a calibrated camera: the essential matrix (normalised 8-point, Nister's
5-point), RANSAC with the adaptive iteration count, decomposition into the four (R, t) with the
cheirality check, and linear triangulation.

Conventions. Correspondences are normalised image points (x, y) = K^-1 (u, v, 1) (undistorted):
``x1`` in the first camera, ``x2`` in the second. (R, t) maps first-camera coordinates to the
second: camera2_p = R camera1_p + t (OpenCV's recoverPose), so the essential matrix
E = [t]x R satisfies x2^T E x1 = 0 (homogeneous x). Monocular translation has no scale: |t| = 1.

* 8-point: Longuet-Higgins, Nature 293, 1981, with Hartley's normalisation ("In defense of the
  eight-point algorithm", PAMI 19(6), 1997); the nearest essential matrix has singular values
  (s, s, 0) (Hartley & Zisserman, *Multiple View Geometry*, 2nd ed., sec. 9.6 / 11.1).
* 5-point: D. Nister, "An efficient solution to the five-point relative pose problem", PAMI
  26(6), 2004: E = x E1 + y E2 + z E3 + E4 from the 4D null space of the 5 epipolar constraints;
  det E = 0 and 2 E E^T E - tr(E E^T) E = 0 give 10 cubic equations in (x, y, z). They are solved
  here with the action matrix of Stewenius, Engels & Nister, "Recent developments on direct
  relative orientation", ISPRS J. 60(4), 2006: Gauss-Jordan elimination of the 10 x 20
  coefficient matrix expresses the 10 cubic monomials in the basis
  (x^2, xy, xz, y^2, yz, z^2, x, y, z, 1); multiplication by x is a 10 x 10 matrix whose real
  eigenvectors are the (up to 10) solutions.
* RANSAC: Fischler & Bolles, CACM 24(6), 1981; the iteration count is updated from the best
  inlier ratio w as N = log(1 - p) / log(1 - w^s) (Hartley & Zisserman, sec. 4.7.1). Points are
  scored by the Sampson distance (first-order geometric error, H&Z eq. 11.9), as OpenCV.
* Decomposition: E = U diag(1, 1, 0) V^T, R in {U W V^T, U W^T V^T}, t = +-u3 (H&Z result 9.19);
  the pair that puts the most triangulated points in front of both cameras wins (cheirality).
* Triangulation: the linear (DLT) method of H&Z sec. 12.2, batched over points.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError

__all__ = [
    "eight_point", "five_point", "sampson_distance", "essential_from_pose", "decompose_essential",
    "triangulate", "recover_pose", "ransac_iterations", "RansacResult", "ransac_essential", "RelativePose",
]


def _homogeneous(x) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    return np.concatenate([x, np.ones(x.shape[:-1] + (1,))], axis=-1)


def _check_pairs(x1, x2, minimum: int) -> tuple[np.ndarray, np.ndarray]:
    x1 = np.asarray(x1, dtype=float).reshape(-1, 2)
    x2 = np.asarray(x2, dtype=float).reshape(-1, 2)
    if len(x1) != len(x2):
        raise ConfigError(f"correspondences need equal counts, got {len(x1)} and {len(x2)}")
    if len(x1) < minimum:
        raise ConfigError(f"at least {minimum} correspondences are needed, got {len(x1)}")
    return x1, x2


def _epipolar_rows(x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """(N, 9) rows a with a . vec(E) = x2^T E x1 (vec row-major)."""
    h1, h2 = _homogeneous(x1), _homogeneous(x2)
    return (h2[:, :, None] * h1[:, None, :]).reshape(-1, 9)


def _nearest_essential(F: np.ndarray) -> np.ndarray:
    U, s, Vt = np.linalg.svd(F)
    E = U @ np.diag([1.0, 1.0, 0.0]) @ Vt
    return E / np.linalg.norm(E)


def eight_point(x1, x2) -> np.ndarray:
    """Essential matrix (unit Frobenius norm) from >= 8 correspondences, least squares."""
    x1, x2 = _check_pairs(x1, x2, 8)

    def normaliser(x):
        c = x.mean(axis=0)
        d = np.sqrt(((x - c) ** 2).sum(axis=1)).mean()
        s = np.sqrt(2.0) / max(d, 1e-12)
        return np.array([[s, 0, -s * c[0]], [0, s, -s * c[1]], [0, 0, 1.0]])

    T1, T2 = normaliser(x1), normaliser(x2)
    n1 = (_homogeneous(x1) @ T1.T)[:, :2]
    n2 = (_homogeneous(x2) @ T2.T)[:, :2]
    _, _, Vt = np.linalg.svd(_epipolar_rows(n1, n2), full_matrices=False)
    F = T2.T @ Vt[-1].reshape(3, 3) @ T1
    return _nearest_essential(F)


# --- Nister's five-point solver (Stewenius' action matrix) -----------------------------------------

_MONOMIALS = [m for d in (3, 2, 1, 0) for m in itertools.product(range(d + 1), repeat=3) if sum(m) == d]
# the 10 cubic monomials come first (eliminated), then the basis x^2, xy, xz, y^2, yz, z^2, x, y, z, 1
_MONOMIALS = ([m for m in _MONOMIALS if sum(m) == 3]
              + [(2, 0, 0), (1, 1, 0), (1, 0, 1), (0, 2, 0), (0, 1, 1), (0, 0, 2), (1, 0, 0), (0, 1, 0),
                 (0, 0, 1), (0, 0, 0)])
_INDEX = {m: i for i, m in enumerate(_MONOMIALS)}
_PRODUCT = np.zeros((20, 20, 20))  # monomial i times monomial j = monomial k (degree <= 3)
for _i, _a in enumerate(_MONOMIALS):
    for _j, _b in enumerate(_MONOMIALS):
        _c = (_a[0] + _b[0], _a[1] + _b[1], _a[2] + _b[2])
        if sum(_c) <= 3:
            _PRODUCT[_i, _j, _INDEX[_c]] = 1.0
_LEVI_CIVITA = np.zeros((3, 3, 3))
for _p in itertools.permutations(range(3)):
    _LEVI_CIVITA[_p] = np.linalg.det(np.eye(3)[list(_p)])
# action of multiplication by x on the basis: (row, target monomial index)
_ACTION_X = [_INDEX[(m[0] + 1, m[1], m[2])] for m in _MONOMIALS[10:]]


_PRODUCT_FLAT = _PRODUCT.reshape(400, 20)


def _poly_mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Products of polynomials (..., 20) x (..., 20) -> (..., 20) (broadcast)."""
    outer = p[..., :, None] * q[..., None, :]
    return outer.reshape(outer.shape[:-2] + (400,)) @ _PRODUCT_FLAT


def _poly_matmul(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Product of 3x3 matrices of polynomials, (3, 3, 20) each."""
    return _poly_mul(A[:, :, None, :], B[None, :, :, :]).sum(axis=1)


def five_point(x1, x2) -> list[np.ndarray]:
    """The (up to 10) essential matrices consistent with 5 correspondences (more points: the
    null space in the least-squares sense)."""
    x1, x2 = _check_pairs(x1, x2, 5)
    rows = _epipolar_rows(x1, x2)
    _, _, Vt = np.linalg.svd(rows, full_matrices=len(rows) < 9)
    basis = Vt[-4:].reshape(4, 3, 3)  # E = x E1 + y E2 + z E3 + E4
    E = np.zeros((3, 3, 20))
    for b, mono in zip(basis, [(1, 0, 0), (0, 1, 0), (0, 0, 1), (0, 0, 0)]):
        E[:, :, _INDEX[mono]] += b
    EEt = _poly_matmul(E, np.transpose(E, (1, 0, 2)))
    trace = EEt[0, 0] + EEt[1, 1] + EEt[2, 2]
    C = 2.0 * _poly_matmul(EEt, E) - _poly_mul(trace, E)
    cross = np.tensordot(_LEVI_CIVITA, _poly_mul(E[0][:, None], E[1][None, :]), axes=([0, 1], [0, 1]))
    det = _poly_mul(cross, E[2]).sum(axis=0)  # E0 . (E1 x E2)
    A = np.vstack([det[None], C.reshape(9, 20)])
    try:
        G = np.linalg.solve(A[:, :10], A[:, 10:])
    except np.linalg.LinAlgError:
        return []
    action = np.zeros((10, 10))
    for row, target in enumerate(_ACTION_X):
        if target >= 10:
            action[row, target - 10] = 1.0
        else:
            action[row] = -G[target]
    values, vectors = np.linalg.eig(action)
    out = []
    for k in np.flatnonzero(np.abs(values.imag) < 1e-9):
        v = vectors[:, k].real
        if abs(v[9]) < 1e-12:
            continue
        x, y, z = v[6] / v[9], v[7] / v[9], v[8] / v[9]
        Ek = x * basis[0] + y * basis[1] + z * basis[2] + basis[3]
        out.append(Ek / np.linalg.norm(Ek))
    return out


def sampson_distance(E: np.ndarray, x1, x2) -> np.ndarray:
    """(N,) squared Sampson distance of each correspondence to the epipolar geometry of ``E``
    (normalised units; multiply by focal^2 for pixels^2). ``E`` may be (k, 3, 3): (k, N)."""
    h1, h2 = _homogeneous(x1), _homogeneous(x2)
    Ex1 = np.einsum("...ij,nj->...ni", E, h1)
    Etx2 = np.einsum("...ji,nj->...ni", E, h2)
    num = np.einsum("ni,...ni->...n", h2, Ex1) ** 2
    den = Ex1[..., 0] ** 2 + Ex1[..., 1] ** 2 + Etx2[..., 0] ** 2 + Etx2[..., 1] ** 2
    return num / np.maximum(den, 1e-300)


def essential_from_pose(R, t) -> np.ndarray:
    t = np.asarray(t, dtype=float)
    tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
    return tx @ np.asarray(R, dtype=float)


def decompose_essential(E) -> list[tuple[np.ndarray, np.ndarray]]:
    """The four (R, t) with [t]x R ~ E, |t| = 1."""
    U, _, Vt = np.linalg.svd(np.asarray(E, dtype=float))
    if np.linalg.det(U) < 0:
        U = -U
    if np.linalg.det(Vt) < 0:
        Vt = -Vt
    W = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    t = U[:, 2]
    Ra, Rb = U @ W @ Vt, U @ W.T @ Vt
    return [(Ra, t), (Ra, -t), (Rb, t), (Rb, -t)]


def triangulate(P1, P2, x1, x2) -> np.ndarray:
    """(N, 3) points from two 3x4 projection matrices (normalised: [R | t] = camera_T_world) and
    their (N, 2) image points, by the linear (DLT) method."""
    P1, P2 = np.asarray(P1, float), np.asarray(P2, float)
    x1 = np.asarray(x1, dtype=float).reshape(-1, 2)
    x2 = np.asarray(x2, dtype=float).reshape(-1, 2)
    A = np.stack([x1[:, 0:1] * P1[2] - P1[0], x1[:, 1:2] * P1[2] - P1[1],
                  x2[:, 0:1] * P2[2] - P2[0], x2[:, 1:2] * P2[2] - P2[1]], axis=1)
    _, _, Vt = np.linalg.svd(A)
    X = Vt[:, -1]
    with np.errstate(divide="ignore", invalid="ignore"):
        return X[:, :3] / X[:, 3:4]


@dataclass(frozen=True)
class RelativePose:
    """(R, t) of the second camera (camera2_p = R camera1_p + t, |t| = 1), the triangulated
    points in the first camera (NaN where not in front), and the cheirality mask."""

    R: np.ndarray
    t: np.ndarray
    points_camera1: np.ndarray
    in_front: np.ndarray


def _depths(R, t, X) -> tuple[np.ndarray, np.ndarray]:
    return X[:, 2], X @ R[2] + t[2]


def recover_pose(E, x1, x2, mask=None, max_depth: float = 50.0) -> RelativePose:
    """Decompose ``E`` and keep the (R, t) with the most points in front of both cameras (only
    points of ``mask`` are used; depths beyond ``max_depth`` baselines are treated as at
    infinity and not counted, as OpenCV's recoverPose distanceThresh)."""
    x1 = np.asarray(x1, dtype=float).reshape(-1, 2)
    x2 = np.asarray(x2, dtype=float).reshape(-1, 2)
    use = np.ones(len(x1), dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    P1 = np.hstack([np.eye(3), np.zeros((3, 1))])
    best = None
    for R, t in decompose_essential(E):
        X = triangulate(P1, np.hstack([R, t[:, None]]), x1, x2)
        z1, z2 = _depths(R, t, X)
        front = use & np.isfinite(z1) & (z1 > 0) & (z2 > 0) & (z1 < max_depth) & (z2 < max_depth)
        if best is None or front.sum() > best[3].sum():
            best = (R, t, X, front)
    R, t, X, front = best
    X = np.where(front[:, None], X, np.nan)
    return RelativePose(R, t, X, front)


def ransac_iterations(inlier_ratio: float, sample_size: int, confidence: float, maximum: int) -> int:
    """N = log(1 - p) / log(1 - w^s), at most ``maximum``."""
    w = float(np.clip(inlier_ratio, 0.0, 1.0))
    good = w ** sample_size
    if good >= 1.0:
        return 1
    if good <= 0.0:
        return maximum
    n = np.log(1.0 - confidence) / np.log(1.0 - good)
    return int(min(maximum, max(1, np.ceil(n))))


@dataclass(frozen=True)
class RansacResult:
    model: np.ndarray
    inliers: np.ndarray
    iterations: int

    @property
    def inlier_ratio(self) -> float:
        return float(self.inliers.mean()) if self.inliers.size else 0.0


def ransac_essential(x1, x2, threshold: float, confidence: float = 0.999, max_iterations: int = 1000,
                     rng: np.random.Generator | None = None, solver: str = "five_point") -> RansacResult:
    """Essential matrix by RANSAC over minimal samples (``solver``: ``five_point`` or
    ``eight_point``); a point is an inlier when its Sampson distance is below ``threshold``
    (normalised units: pixels / focal). The best model is then re-estimated from its inliers by
    the 8-point algorithm and kept if that keeps at least as many inliers."""
    x1, x2 = _check_pairs(x1, x2, 8 if solver == "eight_point" else 5)
    if solver not in ("five_point", "eight_point"):
        raise ConfigError(f"ransac_essential solver must be five_point or eight_point, got {solver!r}")
    rng = np.random.default_rng(0) if rng is None else rng
    s = 5 if solver == "five_point" else 8
    thr2 = threshold * threshold
    n = len(x1)
    best_E, best_in, best_count = None, np.zeros(n, dtype=bool), -1
    needed, it = max_iterations, 0
    while it < needed:
        it += 1
        idx = rng.choice(n, s, replace=False)
        models = five_point(x1[idx], x2[idx]) if s == 5 else [eight_point(x1[idx], x2[idx])]
        if not models:
            continue
        d = sampson_distance(np.stack(models), x1, x2)
        counts = (d < thr2).sum(axis=1)
        k = int(np.argmax(counts))
        if counts[k] > best_count:
            best_count, best_E, best_in = int(counts[k]), models[k], d[k] < thr2
            needed = min(needed, ransac_iterations(best_count / n, s, confidence, max_iterations))
    if best_E is None:
        raise ConfigError("RANSAC found no essential matrix (degenerate correspondences)")
    if best_in.sum() >= 8:
        refit = eight_point(x1[best_in], x2[best_in])
        refit_in = sampson_distance(refit, x1, x2) < thr2
        if refit_in.sum() >= best_in.sum():
            best_E, best_in = refit, refit_in
    return RansacResult(best_E, best_in, it)
