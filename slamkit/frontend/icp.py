"""2D iterative closest point (ICP): point-to-point and point-to-line, with a KD-tree, outlier
rejection, an initial guess (from odometry), a convergence test and a covariance estimate for the
resulting pose-graph constraint.

* Point-to-point: Besl & McKay, "A method for registration of 3-D shapes", IEEE PAMI 14(2),
  1992; each iteration solves the closed-form least-squares rigid alignment of the current
  correspondences with the SVD of the cross-covariance (Arun, Huang & Blostein, IEEE PAMI 9(5),
  1987), so the error sum_i ||R p_i + t - q_i||^2 decreases monotonically and convergence is
  linear.
* Point-to-line: Chen & Medioni, "Object modelling by registration of multiple range images",
  IVC 10(3), 1992; in 2D Censi, "An ICP variant using a point-to-line metric", ICRA 2008. The
  residual is the distance along the target's normal, e_i = n_i^T (R p_i + t - q_i); one
  Gauss-Newton step on the linearised rotation per iteration (Low, "Linear least-squares
  optimization for point-to-plane ICP", TR04-004, 2004). Converges quadratically near the
  optimum (Censi 2008, sec. V), hence in fewer iterations than point-to-point.
* Target normals: the eigenvector of the smallest eigenvalue of the covariance of each target
  point's ``normal_neighbours`` nearest neighbours (PCA). A target stacked from scans taken close
  together samples a wall every few mm, below the range noise, and such normals point anywhere:
  ``target_voxel_m`` first keeps one point (the centroid) per cell (the voxel filter of PCL /
  KISS-ICP), so the neighbourhood spans the wall.
* Degeneracy (``degenerate_below``; Zhang, Kaess & Singh, "On degeneracy of optimization-based
  state estimation problems", ICRA 2016): along a featureless corridor the Gauss-Newton system is
  near singular and the step along the corridor is noise; the degeneracy-aware step solves only in
  the eigen-directions of J^T J (rotation scaled by the points' RMS range) whose eigenvalue is at
  least ``degenerate_below`` x the number of correspondences and keeps the guess in the others.
* Outlier rejection: correspondences farther than ``max_correspondence_m`` are dropped; with
  ``trim_fraction`` < 1 only the closest fraction of the rest is used (trimmed ICP, Chetverikov
  et al., ICPR 2002). Trimming is off by default: with full overlap a fixed trim fraction makes
  point-to-point converge to a biased fixed point (measured 1.5 cm / 0.015 rad off on noise-free
  office scans at trim 0.9, exact at 1.0); use it for scans that only partly overlap.
* Refinement (``refine_trim_fraction``): trimming decides which points may pull, and it decides
  badly from far away -- while the position along a corridor is off, the door jambs that would
  fix it have the largest residuals and are trimmed away -- and well from close by, where the
  worst residuals are the chairs and people that bias an untrimmed match. So a match may run
  untrimmed to convergence and then once more, trimmed, from there; the refined pose is kept
  when it stays within a small step of the first (a larger one means the trimmed problem has
  another optimum, and the first pass's is the one the whole scan agrees with). On the Intel log
  lidar only (pipelines/lidar_slam_logs.yaml, 0.2 m / 3 deg bound): relation error 0.0229 ->
  0.0150 m (0.0180 m with a 0.05 m bound, which refused the corridor case of
  tests/frontend/test_icp.py: a 9.9 cm step from 0.204 m to the true 0.3 m).
* Initial heading (``rotation_search``): ICP converges only from a guess inside its basin; a
  robot turning on the spot without odometry (lidar only, constant-velocity prior) starts it a
  few degrees off, and in a corridor the wrong heading is "repaired" by sliding along the
  corridor. Before ICP the heading of the guess can be searched on a grid (the rotational part
  of the correlative scan matcher of Olson, "Real-time correlative scan matching", ICRA 2009),
  scoring each heading by the truncated mean squared distance of the moved source points to
  their nearest target points, coarse then fine.
* Convergence: the increment of an iteration is below ``translation_tol_m`` and
  ``rotation_tol_rad``, or the correspondence set repeats one seen in the last four iterations
  while the increment is below 0.1 mm / 1e-4 rad (point-to-line can cycle between two sets).
* Covariance (Hessian method, e.g. Bengtsson & Baerveldt, RAS 44, 2003; Prakhya et al., 2015):
  Sigma = s^2 (J^T J)^-1 with J the point-to-line residual Jacobian at the solution and s^2 the
  residual variance (floored at ``sigma_floor_m``^2). The point-to-line Jacobian is used for both
  methods because it exposes degenerate geometry (a corridor constrains nothing along its
  axis); point-to-point's J^T J would be well conditioned there and overconfident. Scan points
  are not independent (they sample the same few walls), so the Hessian covariance is inflated
  by ``covariance_scale`` before it is used as a constraint.

Compiled kernel (``_icpkernel.c``): when it is built, a target keeps a k-d tree of its own
(exact nearest neighbours, as scipy's cKDTree) and its normals from it, and point-to-line ICP
without the degeneracy-aware step runs its whole iteration loop and the final statistics in C;
the numpy/cKDTree code below is the fallback (``SLAMKIT_NO_NATIVE=1``, no compiler) and the
reference the tests compare it against (the same correspondences and iterations; the pose within
the last bits: sums in another order, the 3x3 system by elimination instead of LAPACK).

Conventions: ``target_T_source`` maps source points into the target frame,
q ~ R(theta) p + (x, y). ``covariance`` is expressed in the tangent space of the *right*
perturbation, target_T_source o exp(xi) -- the convention of GTSAM's BetweenFactor<Pose2> and of
``slamkit.data.pose_graph`` information matrices.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from slamkit._native import load_extension
from slamkit.errors import ConfigError, DataError
from slamkit.frontend.preprocess import voxel_downsample
from slamkit.geometry import se2

METHODS = ("point_to_point", "point_to_line")


@dataclass(frozen=True)
class IcpConfig:
    method: str = "point_to_line"
    max_iterations: int = 50
    max_correspondence_m: float = 1.0
    #: fraction of the gated correspondences (closest first) used in each step
    trim_fraction: float = 1.0
    translation_tol_m: float = 1e-7
    rotation_tol_rad: float = 1e-7
    normal_neighbours: int = 6
    min_correspondences: int = 10
    #: a source point counts as matched in ``fitness`` when its nearest target point is this close
    fitness_distance_m: float = 0.1
    sigma_floor_m: float = 0.01
    covariance_scale: float = 10.0
    #: the target is reduced to one point (the centroid) per cell of this size before its
    #: normals are estimated (0: off; see ``slamkit.frontend.preprocess.voxel_downsample``)
    target_voxel_m: float = 0.0
    #: degeneracy-aware step (0: off): directions in which the correspondences constrain the
    #: pose less than this fraction of what they would if every one constrained it (eigenvalues of
    #: the scaled point-to-line normal matrix below ``degenerate_below`` x their number) are not
    #: updated, so the guess (the motion prior) is kept there (see the module docstring). Off in
    #: the logs pipeline: on the whole Intel log lidar only it measured 0.118 +- 0.395 m at 0.005
    #: against 0.026 +- 0.050 m off -- after a turn on the spot the constant-velocity prior says
    #: "standing", and keeping it along the corridor is the very failure to avoid
    degenerate_below: float = 0.0
    #: a second, trimmed pass from the converged pose (None: off; see the module docstring): the
    #: match keeps the refined pose and covariance when it moves less than ``refine_max_step_m`` /
    #: ``refine_max_step_rad`` from the first pass, else the first pass's; ``fitness`` is the first
    #: pass's (whether to trust a match is not the refinement's to decide)
    refine_trim_fraction: float | None = None
    refine_max_step_m: float = 0.2
    refine_max_step_rad: float = float(np.deg2rad(3.0))

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ConfigError(f"IcpConfig.method must be one of {METHODS}, got {self.method!r}")
        if self.max_iterations < 1:
            raise ConfigError(f"IcpConfig.max_iterations must be >= 1, got {self.max_iterations}")
        if not self.max_correspondence_m > 0:
            raise ConfigError(f"IcpConfig.max_correspondence_m must be > 0, got {self.max_correspondence_m}")
        if not 0 < self.trim_fraction <= 1:
            raise ConfigError(f"IcpConfig.trim_fraction must lie in (0, 1], got {self.trim_fraction}")
        if self.normal_neighbours < 2:
            raise ConfigError("IcpConfig.normal_neighbours must be >= 2")
        if not (self.target_voxel_m >= 0 and 0 <= self.degenerate_below < 1):
            raise ConfigError("IcpConfig.target_voxel_m must be >= 0 and degenerate_below in [0, 1)")
        if self.refine_trim_fraction is not None and not 0 < self.refine_trim_fraction <= 1:
            raise ConfigError(f"IcpConfig.refine_trim_fraction must lie in (0, 1], got {self.refine_trim_fraction}")
        if not (self.refine_max_step_m > 0 and self.refine_max_step_rad > 0):
            raise ConfigError("IcpConfig.refine_max_step_m and refine_max_step_rad must be > 0")


@dataclass(frozen=True)
class IcpResult:
    """``fitness``: fraction of source points within ``fitness_distance_m`` of the target after
    alignment; ``rmse_m``: RMS residual of the correspondences used in the last step."""

    target_T_source: np.ndarray
    covariance: np.ndarray
    iterations: int
    converged: bool
    fitness: float
    rmse_m: float
    num_correspondences: int

    @property
    def information(self) -> np.ndarray:
        return np.linalg.inv(self.covariance)


#: the compiled k-d tree and ICP loop (``_icpkernel.c``; the same algorithm as the numpy code here)
KERNEL_MODULE = "slamkit.frontend._icpkernel"
#: points per leaf of the compiled k-d tree
KD_LEAF = 8
#: the compiled normals take at most this many neighbours (more: the numpy normals)
KD_MAX_NEIGHBOURS = 1024


def _kernel():
    """The compiled kernel (``slamkit.frontend._icpkernel``), or None: not built, or
    ``SLAMKIT_NO_NATIVE`` set."""
    return load_extension(KERNEL_MODULE)


class _KdTree:
    """The compiled kernel's k-d tree of a point set: the points reordered (``sorted``, with
    ``perm`` their original indices) and the split axis and value of every internal node
    (``dims``, ``splits``): plain arrays, so a target pickles; the kernel is passed to each call."""

    def __init__(self, kernel, points: np.ndarray):
        m = len(points)
        n, depth = m, 0
        while n > KD_LEAF:
            n, depth = (n + 1) // 2, depth + 1
        self.m = m
        self.perm = np.empty(m, dtype=np.int64)
        self.sorted = np.empty((m, 2))
        self.dims = np.empty(2 ** (depth + 1) - 1, dtype=np.int8)
        self.splits = np.empty(len(self.dims))
        kernel.build(np.ascontiguousarray(points, dtype=float), m, KD_LEAF, self.perm, self.sorted, self.dims,
                     self.splits, len(self.dims))

    def normals(self, kernel, k: int) -> np.ndarray:
        """(M, 2) unit normals in the tree's order (``estimate_normals``' numbers)."""
        out = np.empty((self.m, 2))
        kernel.normals(self.sorted, self.m, KD_LEAF, self.dims, self.splits, len(self.dims), min(k, self.m), out)
        return out

    def query(self, kernel, points: np.ndarray, upper_bound: float) -> tuple[np.ndarray, np.ndarray]:
        """cKDTree.query(points, k=1, distance_upper_bound=upper_bound)'s (dist, idx)."""
        q = np.ascontiguousarray(points, dtype=float)
        dist, idx = np.empty(len(q)), np.empty(len(q), dtype=np.int64)
        kernel.nearest(self.sorted, self.m, KD_LEAF, self.dims, self.splits, len(self.dims), self.perm, q, len(q),
                            float(upper_bound), dist, idx)
        return dist, idx


class IcpTarget:
    """A target point set prepared once: KD-tree and unit normals (N, 2); with ``voxel_m`` > 0
    the points are first reduced to one per ``voxel_m`` cell. With the compiled kernel the tree
    and the normals are the kernel's (scipy's ``tree`` is then built only if asked for)."""

    def __init__(self, points_xy: np.ndarray, normal_neighbours: int = 6, voxel_m: float = 0.0):
        pts = _check_points(voxel_downsample(_check_points(points_xy, "target"), voxel_m), "target")
        self.points = pts
        kernel = _kernel()
        self._kd = None if kernel is None else _KdTree(kernel, pts)
        if self._kd is None or normal_neighbours > KD_MAX_NEIGHBOURS:
            self._kd = None
            self.normals = estimate_normals(pts, self.tree, normal_neighbours)
        else:
            self._normals_sorted = self._kd.normals(kernel, normal_neighbours)
            self.normals = np.empty_like(self._normals_sorted)
            self.normals[self._kd.perm] = self._normals_sorted

    @cached_property
    def tree(self) -> cKDTree:
        return cKDTree(self.points)

    def nearest(self, points: np.ndarray, upper_bound: float = np.inf) -> tuple[np.ndarray, np.ndarray]:
        """Each point's nearest target point closer than ``upper_bound``: (distance, index) as
        ``tree.query(points, k=1, distance_upper_bound=upper_bound)`` (inf and len(self.points) when
        there is none), from the compiled tree when there is one."""
        kernel = None if self._kd is None else _kernel()
        if kernel is not None:
            return self._kd.query(kernel, points, upper_bound)
        return self.tree.query(points, k=1, distance_upper_bound=upper_bound)


def finite_points_xy(points: np.ndarray, what: str, min_points: int = 1) -> np.ndarray:
    """The finite rows of an (N, 2) point set; a wrong shape or fewer than ``min_points`` finite
    points is a DataError naming ``what`` (every scan matcher's input check)."""
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2:
        raise DataError(f"{what} points must have shape (N, 2), got {p.shape}")
    p = p[np.all(np.isfinite(p), axis=1)]
    if len(p) < max(min_points, 1):
        raise DataError(f"{what} needs at least {min_points} finite points, got {len(p)}" if min_points > 1
                        else f"{what} has no finite points")
    return p


def _check_points(points: np.ndarray, name: str) -> np.ndarray:
    return finite_points_xy(points, f"ICP {name}", 3)


def scan_to_points(ranges_m: np.ndarray, angles_rad: np.ndarray, max_range_m: float = np.inf
                   ) -> np.ndarray:
    """(N, 2) sensor-frame end points of the beams with a return (finite range < max)."""
    r = np.asarray(ranges_m, dtype=float)
    a = np.asarray(angles_rad, dtype=float)
    ok = np.isfinite(r) & (r < max_range_m)
    return np.column_stack([r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok])])


def estimate_normals(points: np.ndarray, tree: cKDTree, k: int) -> np.ndarray:
    """Unit normals (N, 2) by PCA of each point's k nearest neighbours: the eigenvector of the
    smallest eigenvalue of the 2x2 scatter [[a, b], [b, c]], in closed form -- the major axis
    lies at phi = atan2(2b, a - c) / 2, the normal is perpendicular to it (the sign of a normal
    does not matter to point-to-line ICP)."""
    k = min(k, len(points))
    _, idx = tree.query(points, k=k)
    nb = points[idx]  # (N, k, 2)
    centred = nb - nb.mean(axis=1, keepdims=True)
    a = np.einsum("nk,nk->n", centred[..., 0], centred[..., 0])
    b = np.einsum("nk,nk->n", centred[..., 0], centred[..., 1])
    c = np.einsum("nk,nk->n", centred[..., 1], centred[..., 1])
    phi = 0.5 * np.arctan2(2.0 * b, a - c)
    return np.column_stack([-np.sin(phi), np.cos(phi)])


def _correspondences(target: IcpTarget, moved: np.ndarray, config: IcpConfig):
    dist, idx = target.nearest(moved, config.max_correspondence_m)
    return _gated(dist, idx, config)


def _gated(dist: np.ndarray, idx: np.ndarray, config: IcpConfig):
    """(source, target) indices of the correspondences from the gated nearest-neighbour query
    (``dist`` inf beyond the gate), trimmed to ``trim_fraction``."""
    ok = np.isfinite(dist)
    src = np.flatnonzero(ok)
    d = dist[ok]
    if config.trim_fraction < 1.0 and len(d) > config.min_correspondences:
        keep = max(config.min_correspondences, int(np.ceil(config.trim_fraction * len(d))))
        order = np.argpartition(d, keep - 1)[:keep]
        src, d = src[order], d[order]
    return src, idx[src]


def _point_to_line_jacobian(moved: np.ndarray, normals: np.ndarray) -> np.ndarray:
    # d e / d(dx, dy, dtheta) of e = n^T (p + (dx, dy) + dtheta (-p_y, p_x) - q)
    return np.column_stack([normals[:, 0], normals[:, 1],
                            normals[:, 1] * moved[:, 0] - normals[:, 0] * moved[:, 1]])


def _point_to_line_step(J: np.ndarray, e: np.ndarray, moved: np.ndarray, degenerate_below: float) -> np.ndarray:
    """The Gauss-Newton step of point-to-line ICP, -(J^T J)^-1 J^T e; degeneracy-aware
    (``degenerate_below`` > 0) only in the well-constrained directions (Zhang, Kaess & Singh,
    "On degeneracy of optimization-based state estimation problems", ICRA 2016): the rotation
    is scaled by the RMS range of the points so that its eigenvalues compare with the
    translations', and the step along every eigenvector whose eigenvalue is below
    ``degenerate_below`` x the number of correspondences is zero."""
    A, g = J.T @ J, J.T @ e
    if degenerate_below <= 0:
        try:
            return -np.linalg.solve(A, g)
        except np.linalg.LinAlgError:
            return -np.linalg.lstsq(A, g, rcond=None)[0]
    length = max(float(np.sqrt(np.mean(np.einsum("ni,ni->n", moved, moved)))), 1e-6)
    D = np.array([1.0, 1.0, 1.0 / length])
    w, V = np.linalg.eigh(A * np.outer(D, D))
    keep = w >= degenerate_below * len(e)
    V = V[:, keep]
    return -D * (V @ ((V.T @ (D * g)) / w[keep]))


def _best_rigid(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Least-squares q ~ R p + t (Arun et al. 1987) as (x, y, theta)."""
    mp, mq = p.mean(axis=0), q.mean(axis=0)
    H = (p - mp).T @ (q - mq)
    theta = np.arctan2(H[0, 1] - H[1, 0], H[0, 0] + H[1, 1])
    c, s = np.cos(theta), np.sin(theta)
    t = mq - np.array([c * mp[0] - s * mp[1], s * mp[0] + c * mp[1]])
    return np.array([t[0], t[1], theta])


#: a correspondence cycle with steps below these is treated as converged
CYCLE_STEP_TOL_M = 1e-4
CYCLE_STEP_TOL_RAD = 1e-4


def icp(source_xy: np.ndarray, target: np.ndarray | IcpTarget,
        initial_target_T_source: np.ndarray | None = None, config: IcpConfig = IcpConfig()
        ) -> IcpResult:
    """Align ``source_xy`` (N, 2) to ``target`` ((M, 2) points or a prepared :class:`IcpTarget`),
    starting from ``initial_target_T_source`` (for example the odometry between the scans)."""
    src = _check_points(source_xy, "source")
    tgt = target if isinstance(target, IcpTarget) else IcpTarget(target, config.normal_neighbours,
                                                                 config.target_voxel_m)
    T = np.zeros(3) if initial_target_T_source is None else np.asarray(initial_target_T_source, float).reshape(3)
    res = _icp_pass(src, tgt, T, config)
    if config.refine_trim_fraction is None or not res.converged:
        return res
    refined = _icp_pass(src, tgt, res.target_T_source, replace(config, trim_fraction=config.refine_trim_fraction))
    step = se2.between(res.target_T_source, refined.target_T_source)
    if (np.hypot(step[0], step[1]) > config.refine_max_step_m or abs(step[2]) > config.refine_max_step_rad
            or not np.all(np.isfinite(refined.covariance))):
        return res
    return replace(refined, fitness=res.fitness, iterations=res.iterations + refined.iterations)


def _icp_pass(src: np.ndarray, tgt: IcpTarget, T: np.ndarray, config: IcpConfig) -> IcpResult:
    """One ICP run from ``T``: the compiled kernel where it applies, else numpy."""
    if config.method == "point_to_line" and config.degenerate_below <= 0 and tgt._kd is not None:
        kernel = _kernel()
        if kernel is not None:
            res = _icp_compiled(kernel, src, tgt, T, config)
            if res is not None:
                return res
    return _icp_python(src, tgt, T, config)


def _icp_compiled(kernel, src: np.ndarray, tgt: IcpTarget, T: np.ndarray, config: IcpConfig) -> IcpResult | None:
    """:func:`_icp_python` (point-to-line, no degeneracy-aware step) in the compiled kernel; None
    when its 3x3 system was exactly singular (then the reference runs: numpy's least squares)."""
    kd = tgt._kd
    (status, x, y, theta, iterations, converged, fitness, n, a00, a01, a02, a11, a12, a22, ee, rss) = kernel.icp(
        kd.sorted, kd.m, KD_LEAF, kd.dims, kd.splits, len(kd.dims), tgt._normals_sorted, np.ascontiguousarray(src),
        len(src),
        float(T[0]), float(T[1]), float(T[2]), config.max_iterations, config.max_correspondence_m,
        config.min_correspondences, config.trim_fraction, config.translation_tol_m, config.rotation_tol_rad,
        CYCLE_STEP_TOL_M, CYCLE_STEP_TOL_RAD, config.fitness_distance_m)
    if status != 0:
        return None
    A = np.array([[a00, a01, a02], [a01, a11, a12], [a02, a12, a22]])
    return _result(np.array([x, y, theta]), iterations, bool(converged), fitness, n, A, ee, rss, config)


def _icp_python(src: np.ndarray, tgt: IcpTarget, T: np.ndarray, config: IcpConfig) -> IcpResult:
    """The ICP loop in numpy: the fallback and the compiled kernel's reference."""
    converged = False
    iterations = 0
    recent: list[bytes] = []
    for iterations in range(1, config.max_iterations + 1):
        moved = se2.transform_points(T, src)
        si, ti = _correspondences(tgt, moved, config)
        if len(si) < config.min_correspondences:
            break
        # point-to-line can settle into a short cycle of correspondence sets whose steps stay
        # just above the tolerances; a repeated set with a sub-0.1-mm step is a fixed point
        key = si.tobytes() + ti.tobytes()
        cycling = key in recent
        recent = (recent + [key])[-4:]
        if config.method == "point_to_point":
            delta = _best_rigid(moved[si], tgt.points[ti])
        else:
            n = tgt.normals[ti]
            e = np.einsum("ni,ni->n", n, moved[si] - tgt.points[ti])
            J = _point_to_line_jacobian(moved[si], n)
            delta = _point_to_line_step(J, e, moved[si], config.degenerate_below)
        # the increment acts in the target frame (left perturbation)
        T = se2.compose(delta, T)
        step_m, step_rad = np.hypot(delta[0], delta[1]), abs(delta[2])
        if (step_m < config.translation_tol_m and step_rad < config.rotation_tol_rad) or (
                cycling and step_m < CYCLE_STEP_TOL_M and step_rad < CYCLE_STEP_TOL_RAD):
            converged = True
            break
    return _finish(src, tgt, T, iterations, converged, config)


def _finish(src: np.ndarray, tgt: IcpTarget, T: np.ndarray, iterations: int, converged: bool,
            config: IcpConfig) -> IcpResult:
    moved = se2.transform_points(T, src)
    if config.fitness_distance_m < config.max_correspondence_m:
        # one query serves both: a point within the fitness distance of the target is within
        # the gate, so its nearest neighbour and distance are the gated query's (exact search)
        dist, idx = tgt.nearest(moved, config.max_correspondence_m)
        fitness = float(np.mean(dist <= config.fitness_distance_m))
        si, ti = _gated(dist, idx, config)
    else:
        dist, _ = tgt.nearest(moved)
        fitness = float(np.mean(dist <= config.fitness_distance_m))
        si, ti = _correspondences(tgt, moved, config)
    if len(si) < 3:
        return _result(T, iterations, converged, fitness, len(si), None, 0.0, 0.0, config)
    n = tgt.normals[ti]
    e = np.einsum("ni,ni->n", n, moved[si] - tgt.points[ti])
    J = _point_to_line_jacobian(moved[si], n)
    residual = np.linalg.norm(moved[si] - tgt.points[ti], axis=1)
    return _result(T, iterations, converged, fitness, len(si), J.T @ J, float(e @ e),
                   float(np.sum(residual ** 2)), config)


def _result(T: np.ndarray, iterations: int, converged: bool, fitness: float, n: int, A: np.ndarray | None,
            ee: float, rss: float, config: IcpConfig) -> IcpResult:
    """The result at ``T`` from the final correspondences' statistics (``n`` of them, the
    point-to-line normal matrix ``A`` = J^T J, the squared residual ``ee`` along the normals and
    ``rss`` of the point distances); fewer than 3: no constraint (huge covariance)."""
    if n < 3:
        return IcpResult(T, np.diag([1e6, 1e6, 1e6]), iterations, False, fitness, float("inf"), n)
    dof = max(n - 3, 1)
    s2 = max(ee / dof, config.sigma_floor_m ** 2)
    # a tiny ridge instead of a pseudo-inverse: a direction nothing constrains (all points on
    # one line) must get a huge variance, whereas pinv would report it as perfectly known
    cov_left = s2 * np.linalg.inv(A + 1e-9 * np.trace(A) * np.eye(3)) * config.covariance_scale
    # left perturbation exp(d) o T = T o exp(Ad(T^-1) d): move the covariance to the right
    Ad = se2.adjoint(se2.inverse(T))
    cov = Ad @ cov_left @ Ad.T
    cov = 0.5 * (cov + cov.T)
    return IcpResult(T, cov, iterations, converged, fitness, float(np.sqrt(rss / n)), n)


def rotation_search(source_xy: np.ndarray, target: IcpTarget, guess: np.ndarray, half_window_rad: float,
                    step_rad: float = float(np.deg2rad(0.5)), cap_m: float = 0.3) -> tuple[np.ndarray, float]:
    """(``guess`` with its heading replaced by the best on a grid within +-``half_window_rad``,
    its score): coarse grid of 4 ``step_rad``, then ``step_rad`` around the best; the score of a
    heading is the mean of min(d, ``cap_m``)^2 over the source points, d the distance to the
    nearest target point (see the module docstring)."""
    src = _check_points(source_xy, "source")
    g = np.asarray(guess, dtype=float).reshape(3)

    n = len(src)

    def best(offsets: np.ndarray) -> tuple[float, float]:
        # every heading's points at once and one KD-tree query for them all (a point's nearest
        # neighbour does not depend on the others in the batch): the numbers of one
        # se2.transform_points per heading (each heading's cos and sin taken as one scalar each)
        poses = [g + np.array([0.0, 0.0, d]) for d in offsets]
        x0 = np.array([T[0] for T in poses])[:, None]
        y0 = np.array([T[1] for T in poses])[:, None]
        c = np.array([np.cos(T[..., 2]) for T in poses])[:, None]
        s = np.array([np.sin(T[..., 2]) for T in poses])[:, None]
        moved = np.empty((len(poses), n, 2))
        moved[..., 0] = x0 + c * src[:, 0] - s * src[:, 1]
        moved[..., 1] = y0 + s * src[:, 0] + c * src[:, 1]
        dist, _ = target.nearest(moved.reshape(-1, 2), cap_m)
        scores = np.mean((np.minimum(dist, cap_m) ** 2).reshape(len(poses), n), axis=1)
        k = int(np.argmin(scores))
        return float(offsets[k]), float(scores[k])

    coarse, _ = best(np.arange(-half_window_rad, half_window_rad + 1e-12, 4 * step_rad))
    fine, score = best(coarse + np.arange(-3, 4) * step_rad)
    return g + np.array([0.0, 0.0, fine]), score
