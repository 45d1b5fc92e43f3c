"""Filter consistency: NEES and NIS with chi-square acceptance bands.

Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to Tracking and Navigation*, 2001,
sec. 5.4: the normalised estimation error squared e^T P^-1 e of a consistent estimator is
chi-square with d degrees of freedom; the average of n independent values, times n, is
chi-square with n d degrees of freedom, so its two-sided p band is
[chi2.ppf((1 - p)/2, n d) / n, chi2.ppf((1 + p)/2, n d) / n] (eq. 5.4.2-8 ff.).
NIS is the same quantity for innovations nu with covariance S.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from slamkit.errors import DataError


def _check_shapes(err: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    e = np.asarray(err, dtype=float)
    P = np.asarray(cov, dtype=float)
    if e.ndim == 1:
        e = e[:, None]
        P = P.reshape(len(e), 1, 1)
    if P.shape != e.shape + e.shape[-1:]:
        raise DataError(f"errors {e.shape} and covariances {P.shape} do not match: need (N, d) and (N, d, d)")
    return e, P


def nees_or_nan(err: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """e^T P^-1 e for errors (N, d) and covariances (N, d, d) -> (N,), NaN where P is not
    symmetric positive definite (or e or P is not finite).

    Computed as |L^-1 e|^2 with the Cholesky factor P = L L^T: a covariance that is not positive
    definite has no NEES, and forcing one through ``solve`` gives the negative or astronomically
    large values (a particle cloud collapsed to a line: NEES 1e15 or -1.9e37) that a mean then
    reports as a result. Callers count the NaN steps (``nees_degenerate_fraction``)."""
    e, P = _check_shapes(err, cov)
    out = np.full(len(e), np.nan)
    finite = np.isfinite(e).all(axis=1) & np.isfinite(P).all(axis=(1, 2))
    sym = finite.copy()
    sym[finite] = np.all(np.abs(P[finite] - np.swapaxes(P[finite], -1, -2))
                         <= 1e-9 * np.maximum(1.0, np.abs(P[finite])), axis=(1, 2))
    idx = np.flatnonzero(sym)
    if len(idx) == 0:
        return out
    try:
        L = np.linalg.cholesky(P[idx])
        ok = np.ones(len(idx), bool)
    except np.linalg.LinAlgError:  # some are not PD: factor one by one to find which
        L = np.zeros_like(P[idx])
        ok = np.zeros(len(idx), bool)
        for k, i in enumerate(idx):
            try:
                L[k] = np.linalg.cholesky(P[i])
                ok[k] = True
            except np.linalg.LinAlgError:
                pass
    # a factor with a vanishing pivot is numerically singular: no meaningful NEES either
    diag = np.diagonal(L, axis1=-2, axis2=-1)
    ok &= np.all(diag > 1e-12 * np.maximum(diag.max(axis=-1, keepdims=True), 1e-300), axis=-1)
    good = idx[ok]
    if len(good):
        y = np.linalg.solve(L[ok], e[good][..., None])[..., 0]  # L y = e (batched)
        out[good] = np.einsum("...i,...i->...", y, y)
    return out


def nees(err: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """e^T P^-1 e for errors (N, d) and covariances (N, d, d) -> (N,); every P must be symmetric
    positive definite (a DataError otherwise; :func:`nees_or_nan` marks such steps instead)."""
    out = nees_or_nan(err, cov)
    bad = np.flatnonzero(np.isnan(out))
    if len(bad):
        raise DataError(f"covariance {int(bad[0])} is not symmetric positive definite (or an entry is not "
                        f"finite); NEES is undefined for {len(bad)} of {len(out)} steps")
    return out


def nis(innovation: np.ndarray, innovation_cov: np.ndarray) -> np.ndarray:
    """nu^T S^-1 nu for innovations (N, m) and their covariances (N, m, m)."""
    return nees(innovation, innovation_cov)


@dataclass(frozen=True)
class Chi2Band:
    lower: float
    upper: float
    dof: int
    n: int
    p: float

    def contains(self, value: float) -> bool:
        return self.lower <= value <= self.upper


def chi2_band(dof: int, n: int = 1, p: float = 0.95) -> Chi2Band:
    """Two-sided ``p`` band for the mean of ``n`` chi-square(dof) samples."""
    if dof < 1 or n < 1 or not 0.0 < p < 1.0:
        raise DataError(f"chi2_band needs dof >= 1, n >= 1 and 0 < p < 1 (got {dof}, {n}, {p})")
    lo, hi = stats.chi2.ppf([(1.0 - p) / 2.0, (1.0 + p) / 2.0], n * dof) / n
    return Chi2Band(lower=float(lo), upper=float(hi), dof=int(dof), n=int(n), p=float(p))


@dataclass(frozen=True)
class ConsistencyResult:
    """Mean of the values, the band for that mean, and the fraction of single values inside the
    single-sample band (about ``p`` for a consistent estimator)."""

    mean: float
    band: Chi2Band
    fraction_inside: float
    consistent: bool
    num: int


def consistency(values: np.ndarray, dof: int, p: float = 0.95) -> ConsistencyResult:
    """Summarise NEES or NIS values (N,) that are chi-square(dof) under consistency."""
    v = np.asarray(values, dtype=float).reshape(-1)
    if v.size == 0:
        raise DataError("no NEES/NIS values")
    band = chi2_band(dof, v.size, p)
    single = chi2_band(dof, 1, p)
    mean = float(v.mean())
    inside = float(np.mean((v >= single.lower) & (v <= single.upper)))
    return ConsistencyResult(mean=mean, band=band, fraction_inside=inside,
                             consistent=band.contains(mean), num=int(v.size))
