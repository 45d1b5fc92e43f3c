"""Optimality certificates for pose-graph solutions, verified the way SE-Sync verifies them.

Rosen, Carlone, Bandeira, Leonard, "SE-Sync: A certifiably correct algorithm for synchronization
over the special Euclidean group", IJRR 38(2-3), 2019 (Sections 3-4); for the planar case Carlone,
Calafiore, Tommolillo, Dellaert, "Planar pose graph optimization: duality, optimal solutions, and
verification", IEEE TRO 32(3), 2016; the preconditioned eigensolver as in Rosen, "Accelerating
certifiable estimation with preconditioned eigensolvers", IEEE RA-L 7(4), 2022.

**Objective.** SE-Sync's F (``objective.py``) is a quadratic form in X = [t_1 .. t_n | R_1 .. R_n]
(d x (n + dn)): F = tr(X M X^T) with the sparse *data matrix*

    M = [[L(W^tau), V], [V^T, L(G^rho) + Sigma]]

where L(W^tau) is the tau-weighted graph Laplacian (n x n), L(G^rho) the kappa-weighted
*connection Laplacian* (dn x dn: blocks kappa I on the diagonal, -kappa R~_ij at (i, j)),
Sigma = blockdiag_i(sum_{ij} tau t~ t~^T) and V (n x dn) couples translations and rotations
(row i, block i: +tau t~_ij^T; row j, block i: -tau t~_ij^T). Minimising over t for fixed R
(t = -R V^T L(W^tau)^+) leaves F(R) = tr(Q R^T R) with the translation-marginalised matrix

    Q = L(G^rho) + Sigma - V^T L(W^tau)^+ V.

**Certificate.** The Lagrange multipliers of the constraints R_i^T R_i = I at a first-order
critical point R are Lambda = SymBlockDiag_d(Q R^T R), i.e. Lambda_i = sym((Q R^T)_i R_i), and
S = Q - Lambda is the certificate matrix: S R^T = 0 at a critical point, and if S is positive
semidefinite then R is a globally optimal solution of the rotation problem (and of its SDP
relaxation). For *any* symmetric block-diagonal Lambda, weak duality gives
f* >= tr(Lambda) + d n min(lambda_min(S), 0), so ``objective - dual_lower_bound`` is a
suboptimality bound (the duality gap) that holds whether or not the solution is certified
(exact when lambda_min is exact; lambda_min is computed iteratively, to ``eig_tol``).

**Numerics.** Q is dense (the projection), so it is never formed: Q x is one sparse solve with
the anchored Laplacian (pose 0's translation removed; F is translation-invariant). lambda_min(S)
is found with LOBPCG (scipy) on that operator, preconditioned by the exact (S + sigma I)^-1,
applied through one sparse LU factorisation of the *full* sparse matrix
[[L_red, V_red], [V_red^T, L(G^rho) + Sigma - Lambda + sigma I]] (its Schur complement is
S + sigma I): no dense decomposition of a big graph. Graphs with d n <= ``dense_max`` use a
dense ``eigh`` of Q - Lambda instead (exact, for tests and tiny problems).

``certified`` is lambda_min(S) >= -eps; ``eps`` defaults to 1e-3, SE-Sync's own threshold
(``min_eig_num_tol`` in the C++ code, ``min_eig_lower_bound = -1e-3`` in the MATLAB code), in
F's units.

**Refinement.** The certificate speaks about SE-Sync's F, and a GTSAM optimum minimises a
different objective (log-map residuals, full information). So by default the solution is first
refined on F itself (Gauss-Newton / Levenberg-Marquardt on the residuals of F with a right
retraction R_i Exp(w_i), pose 0 fixed, sparse LU on the normal equations) until F stops
decreasing; the certificate is then about that refined solution, and the report says how far
it moved (largest rotation and translation change). For isotropic noise the move is small.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from slamkit.backend._convert import rotation_to_quat_wxyz
from slamkit.backend.objective import (SESyncProblem, pose_arrays, sesync_problem,
                                       sesync_residuals, sesync_value)
from slamkit.data.pose_graph import PoseGraph
from slamkit.errors import BackendError, ConfigError
from slamkit.geometry import so2, so3
from slamkit.timing import Stopwatch


@dataclass(frozen=True)
class CertifyConfig:
    """How to certify. ``eps`` (F's units) is the tolerance on lambda_min(S) (SE-Sync: 1e-3);
    ``refine`` first refines the solution on F (see module docstring); ``eig_tol`` is LOBPCG's
    residual tolerance relative to the largest diagonal entry of Q; ``shift`` (relative to the
    mean diagonal of the connection Laplacian) is the preconditioner's sigma; ``dense_max``: at
    most this many rotation unknowns (d n) use a dense eigendecomposition instead; ``seed`` seeds
    LOBPCG's random start block."""

    eps: float = 1e-3
    refine: bool = True
    refine_max_iterations: int = 50
    refine_rel_tol: float = 1e-13
    eig_tol: float = 1e-9
    eig_max_iterations: int = 500
    block_size: int = 4
    shift: float = 1e-3
    dense_max: int = 600
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("eps", "refine_rel_tol", "eig_tol", "shift"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"certify {name} must be a finite number >= 0, got {v!r}")
        for name in ("refine_max_iterations", "eig_max_iterations", "block_size", "dense_max"):
            if int(getattr(self, name)) < 0:
                raise ConfigError(f"certify {name} must be >= 0, got {getattr(self, name)!r}")


#: the three outcomes of a certificate (``Certificate.verdict``)
CERTIFIED = "certified"
NOT_OPTIMAL = "not optimal"
NOT_VERIFIED = "not verified"


@dataclass(frozen=True)
class Certificate:
    """The verdict on one solution. Objective values are SE-Sync's F (not GTSAM's error):
    ``objective_input`` at the poses given, ``objective`` at the certified (refined) poses,
    ``dual_lower_bound`` = tr(Lambda) + d n min(lambda_min, 0) <= f*, ``suboptimality_bound`` =
    objective - dual_lower_bound (>= F(poses) - f*), ``relative_suboptimality`` = that / objective.
    ``poses`` are the refined poses (PoseGraph layout); ``max_rotation_change_rad`` and
    ``max_translation_change_m`` say how far refinement moved them. ``eig_method`` is
    ``lobpcg`` or ``dense``; ``eig_residual`` = ||S v - lambda_min v|| for the unit eigenvector;
    a result is only ``certified`` when the eigensolver converged (a negative Ritz value proves
    non-optimality even unconverged: it is a Rayleigh quotient of S).

    ``verdict`` says which of the three outcomes it is: :data:`CERTIFIED`, :data:`NOT_OPTIMAL`
    (lambda_min < -eps: a descent direction exists, whether or not the eigensolver converged), or
    :data:`NOT_VERIFIED` (the eigensolver did not converge and its estimate is not negative:
    nothing is proven either way -- not a failed certificate). ``solution`` names the poses the
    verdict is about: ``"refined"`` (refined on F from the poses given; ``poses``) or ``"as
    given"`` (``refine=False``: the poses given)."""

    certified: bool
    min_eigenvalue: float
    eps: float
    objective_input: float
    objective: float
    dual_lower_bound: float
    suboptimality_bound: float
    relative_suboptimality: float
    refine_iterations: int
    max_rotation_change_rad: float
    max_translation_change_m: float
    eig_method: str
    eig_converged: bool
    eig_residual: float
    time_data_matrix_s: float
    time_refine_s: float
    time_eig_s: float
    time_total_s: float
    poses: np.ndarray = field(repr=False)
    config: CertifyConfig = field(default_factory=CertifyConfig, repr=False)

    @property
    def verdict(self) -> str:
        if self.certified:
            return CERTIFIED
        return NOT_OPTIMAL if self.min_eigenvalue < -self.eps else NOT_VERIFIED

    @property
    def solution(self) -> str:
        return "refined" if self.config.refine else "as given"

    def describe(self) -> str:
        """One line: the verdict, the solution it is about, and how far refinement moved it."""
        what = (f"the solution refined on SE-Sync's F (F {self.objective:.6g}, from {self.objective_input:.6g} "
                f"at the poses given; moved up to {self.max_rotation_change_rad:.3g} rad, "
                f"{self.max_translation_change_m:.3g} m)" if self.config.refine
                else f"the poses given (F {self.objective:.6g})")
        why = {CERTIFIED: f"lambda_min {self.min_eigenvalue:.3g} >= -{self.eps:g}",
               NOT_OPTIMAL: f"lambda_min {self.min_eigenvalue:.3g} < -{self.eps:g}: a better solution exists",
               NOT_VERIFIED: f"the {self.eig_method} eigensolver did not converge (residual {self.eig_residual:.3g}, "
                             f"lambda_min estimate {self.min_eigenvalue:.3g}): optimality neither proven nor refuted"}
        return f"{self.verdict} ({why[self.verdict]}) for {what}"

    def summary(self) -> dict:
        """JSON-ready numbers (no arrays, no config), with ``verdict`` and ``solution``."""
        out = {k: getattr(self, k) for k in self.__dataclass_fields__ if k not in ("poses", "config")}
        out["verdict"] = self.verdict
        out["solution"] = self.solution
        return out


# ---- the data matrix ---------------------------------------------------------------------------


@dataclass(frozen=True)
class DataMatrix:
    """SE-Sync's data matrix in blocks (see module docstring): ``laplacian`` L(W^tau) (n x n),
    ``coupling`` V (n x dn), ``rotation_block`` L(G^rho) + Sigma (dn x dn), all sparse CSR.
    Rotation unknowns are ordered pose-major: column p d + a is column a of R_p."""

    dim: int
    num_poses: int
    laplacian: sp.csr_matrix
    coupling: sp.csr_matrix
    rotation_block: sp.csr_matrix

    def full(self) -> sp.csr_matrix:
        """M = [[L, V], [V^T, L(G^rho) + Sigma]] ((n + dn) square), F = tr(X M X^T)."""
        return sp.bmat([[self.laplacian, self.coupling],
                        [self.coupling.T, self.rotation_block]], format="csr")


def data_matrix(problem: SESyncProblem) -> DataMatrix:
    """Assemble SE-Sync's data matrix of ``problem`` (vectorised COO assembly, duplicates summed)."""
    d, n = problem.dim, problem.num_poses
    i, j, kappa, tau = problem.i, problem.j, problem.kappa, problem.tau
    Rz, tz = problem.rotation, problem.translation
    a = np.arange(d)
    # L(W^tau)
    lap = sp.coo_matrix((np.concatenate([tau, tau, -tau, -tau]),
                         (np.concatenate([i, j, i, j]), np.concatenate([i, j, j, i]))), shape=(n, n))
    # V: row i and row j, columns of block i
    cols = (i[:, None] * d + a).ravel()
    vt = (tau[:, None] * tz).ravel()
    coup = sp.coo_matrix((np.concatenate([vt, -vt]),
                          (np.concatenate([np.repeat(i, d), np.repeat(j, d)]), np.concatenate([cols, cols]))),
                         shape=(n, n * d))
    # connection Laplacian + Sigma
    rows_ii = (i[:, None, None] * d + a[:, None]) + 0 * a  # (M, d, d) row index of block (i, *)
    cols_ii = (i[:, None, None] * d + a[None, :]) + 0 * a[:, None]
    rows_jj = (j[:, None, None] * d + a[:, None]) + 0 * a
    cols_jj = (j[:, None, None] * d + a[None, :]) + 0 * a[:, None]
    eye = np.broadcast_to(np.eye(d), (len(i), d, d))
    kI = kappa[:, None, None] * eye
    off = -kappa[:, None, None] * Rz                                   # block (i, j)
    sigma = tau[:, None, None] * tz[:, :, None] * tz[:, None, :]       # block (i, i)
    rows = np.concatenate([rows_ii, rows_jj, rows_ii, rows_jj, rows_ii], axis=0).ravel()
    colv = np.concatenate([cols_ii, cols_jj, cols_jj, cols_ii, cols_ii], axis=0).ravel()
    vals = np.concatenate([kI, kI, off, np.swapaxes(off, 1, 2), sigma], axis=0).ravel()
    rot = sp.coo_matrix((vals, (rows, colv)), shape=(n * d, n * d))
    return DataMatrix(d, n, lap.tocsr(), coup.tocsr(), rot.tocsr())


class MarginalisedOperator:
    """Q = L(G^rho) + Sigma - V^T L(W^tau)^+ V as a product (one sparse LU of the Laplacian
    with pose 0 anchored), plus ``translations(R)``: the optimal translations for rotations R."""

    def __init__(self, dm: DataMatrix) -> None:
        self.dm = dm
        lap = dm.laplacian.tocsc()[1:, 1:]
        try:
            self._lu = symmetric_lu(lap)
        except RuntimeError as exc:  # singular: a vertex (set) has no translation information
            raise BackendError(f"the translation Laplacian is singular ({exc}): the pose graph is "
                               "disconnected or has edges without translation information") from None
        self._v = dm.coupling.tocsr()[1:]
        self._vt = self._v.T.tocsr()
        self.shape = dm.rotation_block.shape

    def matmat(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        vx = self._v @ x
        return self.dm.rotation_block @ x - self._vt @ self._lu.solve(np.asarray(vx).reshape(vx.shape))

    def translations(self, R: np.ndarray) -> np.ndarray:
        """(n, d) optimal translations for rotations (n, d, d), pose 0 at the origin."""
        Y = stack_transposed(R)
        t = np.zeros((self.dm.num_poses, self.dm.dim))
        t[1:] = -self._lu.solve(np.asarray(self._v @ Y))
        return t

    def dense(self) -> np.ndarray:
        """Q as a dense array (only for small problems)."""
        return self.matmat(np.eye(self.shape[0]))


def stack_transposed(R: np.ndarray) -> np.ndarray:
    """Rotations (n, d, d) -> Y = R^T stacked (dn, d): block p is R_p^T."""
    n, d, _ = R.shape
    return np.transpose(R, (0, 2, 1)).reshape(n * d, d)


def multipliers(Q: MarginalisedOperator, R: np.ndarray) -> np.ndarray:
    """Lambda_i = sym((Q R^T)_i R_i), (n, d, d)."""
    n, d, _ = R.shape
    QY = Q.matmat(stack_transposed(R)).reshape(n, d, d)
    lam = QY @ R
    return 0.5 * (lam + np.swapaxes(lam, 1, 2))


def _block_diag(blocks: np.ndarray) -> sp.csr_matrix:
    n, d, _ = blocks.shape
    a = np.arange(d)
    rows = (np.arange(n)[:, None, None] * d + a[:, None]) + 0 * a
    cols = (np.arange(n)[:, None, None] * d + a[None, :]) + 0 * a[:, None]
    return sp.coo_matrix((blocks.ravel(), (rows.ravel(), cols.ravel())), shape=(n * d, n * d)).tocsr()


def min_eigenvalue(Q: MarginalisedOperator, lam: np.ndarray, R: np.ndarray, config: CertifyConfig
                   ) -> tuple[float, str, float, bool]:
    """lambda_min(Q - Lambda): (value, method, residual norm ||S v - lambda v|| of its unit
    eigenvector, converged: residual <= 10 tol)."""
    n, d, _ = lam.shape
    size = n * d
    lam_sp = _block_diag(lam)
    if size <= config.dense_max:
        S = Q.dense() - lam_sp.toarray()
        w = np.linalg.eigvalsh(0.5 * (S + S.T))
        return float(w[0]), "dense", 0.0, True
    dm = Q.dm
    diag = dm.rotation_block.diagonal()
    sigma = max(config.shift * float(np.mean(diag)), config.eps, 1e-12)
    top = dm.laplacian[1:, 1:], dm.coupling[1:]
    for _ in range(40):
        # K = [[L_red, V_red], [V_red^T, B - Lambda + sigma I]] has Schur complement S + sigma I, so
        # its inertia (the signs of the LDL^T pivots, Sylvester) counts the eigenvalues of S below
        # -sigma: grow sigma until there are none, so the preconditioner is positive definite
        k = sp.bmat([[top[0], top[1]], [top[1].T, dm.rotation_block - lam_sp + sigma * sp.identity(size)]],
                    format="csc")
        lu = symmetric_lu(k)
        if _negative_pivots(lu) <= 0:  # none, or unknown (pivoted): use this sigma
            break
        sigma *= 4.0
    offset = n - 1

    def precondition(x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        two_d = x.ndim == 2
        x2 = x if two_d else x[:, None]
        rhs = np.zeros((offset + size, x2.shape[1]))
        rhs[offset:] = x2
        out = lu.solve(rhs)[offset:]
        return out if two_d else out[:, 0]

    def apply_s(x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        two_d = x.ndim == 2
        x2 = x if two_d else x[:, None]
        out = Q.matmat(x2) - lam_sp @ x2
        return out if two_d else out[:, 0]

    s_op = spla.LinearOperator((size, size), matvec=apply_s, matmat=apply_s, dtype=float)
    p_op = spla.LinearOperator((size, size), matvec=precondition, matmat=precondition, dtype=float)
    rng = np.random.default_rng(config.seed)
    m = max(int(config.block_size), d + 1)
    x0 = np.concatenate([stack_transposed(R), rng.standard_normal((size, m - d))], axis=1)
    tol = config.eig_tol * float(np.max(np.abs(diag)))
    w, v = spla.lobpcg(s_op, x0, M=p_op, tol=tol, maxiter=int(config.eig_max_iterations),
                       largest=False)
    k = int(np.argmin(w))
    residual = float(np.linalg.norm(apply_s(v[:, k]) - w[k] * v[:, k]))
    return float(w[k]), "lobpcg", residual, residual <= 10.0 * tol


# ---- refinement on F ----------------------------------------------------------------------------


def _generators(d: int) -> np.ndarray:
    """Basis of so(d): (1, 2, 2) for d = 2, (3, 3, 3) for d = 3."""
    if d == 2:
        return so2.hat(np.ones(1))
    return so3.hat(np.eye(3))


def _jacobian(problem: SESyncProblem, R: np.ndarray) -> sp.csr_matrix:
    """Jacobian of the weighted residuals [sqrt(kappa) vec(R_j - R_i R~), sqrt(tau)(t_j - t_i - R_i t~)]
    per edge with respect to (t_p (d), w_p (p)) per pose, pose-major."""
    d, n = problem.dim, problem.num_poses
    G = _generators(d)
    p = len(G)
    width = d + p
    m = len(problem.i)
    i, j = problem.i, problem.j
    sk, st = np.sqrt(problem.kappa), np.sqrt(problem.tau)
    per_edge = d * d + d
    base = np.arange(m) * per_edge
    rows, cols, vals = [], [], []
    # rotation residual rows base + a d + b
    rot_rows = base[:, None, None] + (np.arange(d)[:, None] * d + np.arange(d)[None, :])  # (m, d, d)
    RjG = np.einsum("mab,kbc->mkac", R[j], G)                          # (m, p, d, d)
    RiGRz = np.einsum("mab,kbc,mcd->mkad", R[i], G, problem.rotation)  # (m, p, d, d)
    for sign, blocks, who in ((1.0, RjG, j), (-1.0, RiGRz, i)):
        rows.append(np.broadcast_to(rot_rows[:, None], (m, p, d, d)).ravel())
        cols.append(np.broadcast_to((who * width + d)[:, None, None, None] + np.arange(p)[None, :, None, None],
                                    (m, p, d, d)).ravel())
        vals.append((sign * sk[:, None, None, None] * blocks).ravel())
    # translation residual rows base + d^2 + a
    tr_rows = base[:, None] + d * d + np.arange(d)[None, :]             # (m, d)
    for sign, who in ((1.0, j), (-1.0, i)):
        rows.append(tr_rows.ravel())
        cols.append((who[:, None] * width + np.arange(d)[None, :]).ravel())
        vals.append(np.repeat(sign * st, d))
    RiGt = np.einsum("mab,kbc,mc->mka", R[i], G, problem.translation)   # (m, p, d)
    rows.append(np.broadcast_to(tr_rows[:, None, :], (m, p, d)).ravel())
    cols.append(np.broadcast_to((i * width + d)[:, None, None] + np.arange(p)[None, :, None], (m, p, d)).ravel())
    vals.append((-st[:, None, None] * RiGt).ravel())
    J = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(m * per_edge, n * width)).tocsc()
    return J[:, width:]  # pose 0 fixed (gauge)


def _weighted_residual(problem: SESyncProblem, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    rot_res, trans_res = sesync_residuals(problem, R, t)
    rr = np.sqrt(problem.kappa)[:, None, None] * rot_res
    tt = np.sqrt(problem.tau)[:, None] * trans_res
    return np.concatenate([rr.reshape(len(rr), -1), tt], axis=1).ravel()


def _retract(R: np.ndarray, t: np.ndarray, step: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n, d, _ = R.shape
    p = 1 if d == 2 else 3
    full = np.concatenate([np.zeros(d + p), step]).reshape(n, d + p)
    if d == 2:
        dR = np.stack([np.stack([np.cos(full[:, 2]), -np.sin(full[:, 2])], -1),
                       np.stack([np.sin(full[:, 2]), np.cos(full[:, 2])], -1)], -2)
    else:
        dR = so3.exp(full[:, 3:])
    return R @ dR, t + full[:, :d]


def _newton_system(problem: SESyncProblem, dm: DataMatrix, R: np.ndarray, t: np.ndarray
                   ) -> tuple[sp.csc_matrix, np.ndarray]:
    """Riemannian Newton system of F in the coordinates (t_p, w_p) (pose 0 fixed): the Hessian
    H/2 = sum_a B_a^T (M - blockdiag(0, Lambda)) B_a, where B_a maps a step to row a of the
    tangent vector X' = [t' | R_p G(w_p)] and Lambda = SymBlockDiag(X^T X M) on the rotation
    blocks (the same multipliers as the certificate: the Hessian is 2 (M - Lambda) on the
    tangent space), and the gradient / 2 = sum_a B_a^T (M X^T)_a."""
    d, n = problem.dim, problem.num_poses
    G = _generators(d)
    p = len(G)
    width = d + p
    N = n + n * d
    X = np.concatenate([t.T, np.concatenate(list(R), axis=1)], axis=1)       # (d, N)
    M = dm.full()
    MXt = np.asarray(M @ X.T)                                                 # (N, d)
    XM_rot = MXt[n:].reshape(n, d, d)                                         # block p: (M X^T)_p
    lam = XM_rot @ R
    lam = 0.5 * (lam + np.swapaxes(lam, 1, 2))
    K = M - sp.block_diag([sp.csr_matrix((n, n)), _block_diag(lam)], format="csr")
    pose = np.arange(n)
    a_idx = np.arange(d)
    # translation entries: row a N + p, column p width + a
    rows_t = (a_idx[:, None] * N + pose[None, :]).ravel()
    cols_t = (pose[None, :] * width + a_idx[:, None]).ravel()
    # rotation entries: row a N + n + p d + b, column p width + d + k, value (R_p G_k)[a, b]
    RG = np.einsum("pab,kbc->pkac", R, G)                                     # (n, p, d, d)
    pp, kk, aa, bb = np.meshgrid(pose, np.arange(p), a_idx, a_idx, indexing="ij")
    rows_r = aa * N + n + pp * d + bb
    cols_r = pp * width + d + kk
    B = sp.coo_matrix((np.concatenate([np.ones(len(rows_t)), RG.ravel()]),
                       (np.concatenate([rows_t, rows_r.ravel()]), np.concatenate([cols_t, cols_r.ravel()]))),
                      shape=(d * N, n * width)).tocsc()[:, width:]
    Kbig = sp.kron(sp.identity(d), K, format="csr")
    H = (B.T @ Kbig @ B).tocsc()
    g = B.T @ MXt.T.ravel()
    return H, g


def refine(problem: SESyncProblem, R: np.ndarray, t: np.ndarray, max_iterations: int,
           rel_tol: float, dm: DataMatrix | None = None) -> tuple[np.ndarray, np.ndarray, int]:
    """Minimise F from (R, t) with pose 0 fixed; returns (R, t, iterations).

    Riemannian Newton steps (``_newton_system``) from the start: the input is a GTSAM optimum,
    close to F's, where Newton converges quadratically and Gauss-Newton only linearly (F's
    residual is not zero: sphere2500 from GTSAM's optimum, GN needs 9 steps for a 1e-6 relative
    decrease, ratio ~0.72 per step; Newton from the first step 3 instead of GN-then-Newton's 4);
    a Newton step that does not decrease F (an indefinite Hessian far from a minimum) is
    replaced by a Gauss-Newton one. Stops when the relative decrease is below ``rel_tol``, or
    after a Newton step whose relative decrease is below sqrt(``rel_tol``): Newton converges
    quadratically, so the next decrease would be below ``rel_tol``, and confirming it costs one
    more factorisation for nothing (city10000: 2 steps instead of 4, F within 6e-10 relative of
    the 4-step value, lambda_min -1.7e-12 instead of -7.7e-15)."""
    dm = data_matrix(problem) if dm is None else dm
    f = sesync_value(problem, R, t)
    mu = 0.0
    it = 0
    _solve = _StepSolver()
    for it in range(1, int(max_iterations) + 1):
        step_found = newton_step = False
        H, g = _newton_system(problem, dm, R, t)
        step = _solve(H, g)
        if step is not None:
            R_new, t_new = _retract(R, t, step)
            f_new = sesync_value(problem, R_new, t_new)
            step_found = newton_step = f_new <= f
        if not step_found:
            J = _jacobian(problem, R)
            r = _weighted_residual(problem, R, t)
            H = (J.T @ J).tocsc()
            g = J.T @ r
            dH = sp.diags(np.maximum(H.diagonal(), 1e-12))
            while not step_found:
                step = _solve(H + mu * dH if mu > 0 else H, g)
                if step is not None:
                    R_new, t_new = _retract(R, t, step)
                    f_new = sesync_value(problem, R_new, t_new)
                    step_found = f_new <= f
                if not step_found:
                    mu = 1e-6 if mu == 0 else mu * 10.0
                    if mu > 1e8:
                        return R, t, it
            mu = mu / 10.0 if mu > 1e-6 else 0.0
        decrease = f - f_new
        R, t, f = R_new, t_new, f_new
        if decrease <= rel_tol * max(f, 1e-300):
            break
        if newton_step and decrease <= math.sqrt(rel_tol) * max(f, 1e-300):
            break
    return R, t, it


def symmetric_lu(A: sp.spmatrix):
    """SuperLU of a symmetric matrix with a symmetric fill-reducing ordering and diagonal pivots
    (an LDL^T in effect). SuperLU's default partial pivoting destroys the ordering: on
    sphere2500's normal equations it takes 8.0 s and 25.6M factor entries instead of 0.15 s and
    2.5M."""
    return spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                     options={"SymmetricMode": True})


def _negative_pivots(lu) -> int:
    """Negative pivots of a ``symmetric_lu`` factorisation (= negative eigenvalues of the matrix,
    by Sylvester's law of inertia, when no off-diagonal pivot was taken)."""
    if not np.array_equal(lu.perm_r, lu.perm_c):
        return -1  # pivoted: the inertia is not readable; callers treat it as "unknown"
    return int(np.count_nonzero(lu.U.diagonal() < 0))


class _StepSolver:
    """-A^-1 g by sparse LU for a sequence of matrices with one sparsity pattern (the refinement's
    normal equations and Newton systems): the fill-reducing ordering is computed by the first
    factorisation and reused (city10000's 30k x 30k system: 0.55 s with MMD each time, 0.40 s
    reusing it). Returns None when A is singular."""

    def __init__(self) -> None:
        self._order: np.ndarray | None = None

    def __call__(self, A: sp.spmatrix, g: np.ndarray) -> np.ndarray | None:
        try:
            if self._order is None:
                lu = symmetric_lu(A)
                # SuperLU factors A[:, perm_c] with the same symmetric row order: A[q][:, q]
                # with q = argsort(perm_c) is already in that order
                self._order = np.argsort(lu.perm_c) if _negative_pivots(lu) >= 0 else None
                step = -lu.solve(g)
            else:
                q = self._order
                Aq = A.tocsr()[q][:, q].tocsc()
                lu = spla.splu(Aq, permc_spec="NATURAL", diag_pivot_thresh=0.0,
                               options={"SymmetricMode": True})
                step = np.empty_like(g, dtype=float)
                step[q] = -lu.solve(g[q])
        except RuntimeError:
            return None
        return step if np.all(np.isfinite(step)) else None


def _to_poses(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    if R.shape[1] == 2:
        return np.column_stack([t, np.arctan2(R[:, 1, 0], R[:, 0, 0])])
    return np.column_stack([t, rotation_to_quat_wxyz(R)])


def _rotation_angles(Ra: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    rel = np.swapaxes(Ra, 1, 2) @ Rb
    d = Ra.shape[1]
    c = (np.trace(rel, axis1=1, axis2=2) - (d - 2)) / 2.0
    return np.arccos(np.clip(c, -1.0, 1.0))


def certify(graph: PoseGraph, poses: np.ndarray, config: CertifyConfig = CertifyConfig()) -> Certificate:
    """Certify (or refute) the global optimality of ``poses`` (PoseGraph layout, rows matching
    ``graph.vertex_ids``) in SE-Sync's objective; see the module docstring."""
    width = 3 if graph.dim == 2 else 7
    poses = np.asarray(poses, dtype=float)
    if poses.shape != (graph.num_poses, width):
        raise BackendError(f"poses must have shape ({graph.num_poses}, {width}), got {poses.shape}")
    with Stopwatch() as total:
        with Stopwatch() as sw_build:
            problem = sesync_problem(graph)
            if not (np.all(np.isfinite(problem.kappa)) and np.all(np.isfinite(problem.tau))):
                raise BackendError(f"{graph.name}: SE-Sync weights are not finite")
            dm = data_matrix(problem)
            Q = MarginalisedOperator(dm)
        R0, t0 = pose_arrays(graph.dim, poses)
        f_input = sesync_value(problem, R0, t0)
        with Stopwatch() as sw_refine:
            R, t, iterations = (refine(problem, R0, t0, config.refine_max_iterations, config.refine_rel_tol, dm)
                                if config.refine else (R0, t0, 0))
        f = sesync_value(problem, R, t)
        with Stopwatch() as sw_eig:
            lam = multipliers(Q, R)
            lam_min, method, residual, converged = min_eigenvalue(Q, lam, R, config)
        lower = float(np.trace(lam, axis1=1, axis2=2).sum()) + graph.dim * graph.num_poses * min(lam_min, 0.0)
    gap = max(f - lower, 0.0)  # >= 0 by weak duality; a negative difference is rounding
    return Certificate(
        certified=bool(converged and lam_min >= -config.eps), min_eigenvalue=lam_min, eps=config.eps,
        objective_input=f_input, objective=f, dual_lower_bound=lower, suboptimality_bound=gap,
        relative_suboptimality=gap / f if f > 0 else 0.0, refine_iterations=iterations,
        max_rotation_change_rad=float(np.max(_rotation_angles(R0, R), initial=0.0)),
        max_translation_change_m=float(np.max(np.linalg.norm(t - t0, axis=1), initial=0.0)),
        eig_method=method, eig_converged=bool(converged), eig_residual=residual,
        time_data_matrix_s=sw_build.elapsed_s, time_refine_s=sw_refine.elapsed_s,
        time_eig_s=sw_eig.elapsed_s, time_total_s=total.elapsed_s, poses=_to_poses(R, t), config=config)
