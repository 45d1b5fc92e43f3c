"""Batch and incremental solvers for pose graphs: build -> initialise -> optimise -> marginals.

* ``lm``: Levenberg-Marquardt (Levenberg 1944, Marquardt 1963; GTSAM's trust-region variant
  with lambda scaled by ``lambdaFactor``), ``gn``: Gauss-Newton, ``dogleg``: Powell's dog-leg
  (Powell 1970; Rosen, Kaess, Leonard, "RISE", IEEE TRO 30(5) 2014) with Gauss-Newton steps,
  ``isam2``: incremental replay (``slamkit.backend.isam2``).
* The optimiser is iterated here (``iterate()`` plus ``gtsam.checkConvergence``, the same loop
  and stopping rule as GTSAM's ``NonlinearOptimizer::defaultOptimize``) so an ``on_iteration``
  hook can watch every step while the iteration count and final error stay identical to
  ``optimizer.optimize()``.
* QR fallback: sparse Cholesky fails on badly conditioned problems (input_INTEL_g2o's
  information spans 10 .. 2.7e12). When it raises IndeterminantLinearSystem, when the error turns
  inf/NaN, or when LM gives up at its maximum lambda without one accepted step, the solve is
  redone from the same initial values with Powell's dog-leg on a multifrontal QR factorisation
  (which never squares the Jacobian) and the switch is recorded in ``warnings``/``solver``.
  LM on QR is not used as the fallback: on input_INTEL_g2o it is still at error 5.5e4 after 100
  iterations while dog-leg+QR converges to 107.919 in 19.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable

import gtsam
import numpy as np

from slamkit.backend._convert import G2O_TO_GTSAM, poses_from_values
from slamkit.backend.graph import ROBUST_KINDS, build_graph
from slamkit.backend.initialisation import INIT_METHODS, initial_values, is_indeterminant
from slamkit.backend.isam2 import Isam2Params, isam2_replay
from slamkit.data.pose_graph import PoseGraph
from slamkit.errors import BackendError, ConfigError
from slamkit.timing import Stopwatch

SOLVERS = ("lm", "gn", "dogleg", "isam2")
LINEAR_SOLVERS = {"cholesky": "MULTIFRONTAL_CHOLESKY", "qr": "MULTIFRONTAL_QR"}

IterationHook = Callable[[int, float, np.ndarray], None]
#: which edges OptimizeConfig.robust applies to
ROBUST_EDGES = ("all", "loop_closures")


@dataclass(frozen=True)
class OptimizeConfig:
    """How to solve a pose graph. Tolerances are GTSAM's defaults; ``robust_k`` None means the
    kernel's 95%-efficiency default; ``prior_sigma`` (m, rad) is the gauge prior's sigma.
    ``robust_edges``: the edges the ``robust`` kernel applies to, ``all`` or ``loop_closures``
    (every edge but the consecutive-id ones, which stay least squares: trusted odometry, as the
    robust back-ends of ``slamkit.backend.robust`` treat it)."""

    solver: str = "lm"
    init: str = "file"
    robust: str = "none"
    robust_k: float | None = None
    robust_edges: str = "all"
    max_iterations: int = 100
    relative_error_tol: float = 1e-5
    absolute_error_tol: float = 1e-5
    error_tol: float = 0.0
    linear_solver: str = "cholesky"
    compute_marginals: bool = False
    prior_sigma: float = 1e-6
    qr_fallback: bool = True
    isam2: Isam2Params = field(default_factory=Isam2Params)

    def __post_init__(self) -> None:
        for name, value, allowed in (("solver", self.solver, SOLVERS),
                                     ("init", self.init, INIT_METHODS),
                                     ("robust", self.robust, ROBUST_KINDS),
                                     ("robust_edges", self.robust_edges, ROBUST_EDGES),
                                     ("linear_solver", self.linear_solver, tuple(LINEAR_SOLVERS))):
            if value not in allowed:
                raise ConfigError(f"{name} must be one of {allowed}, got {value!r}")
        if int(self.max_iterations) < 0:
            raise ConfigError(f"max_iterations must be >= 0, got {self.max_iterations}")
        for name in ("relative_error_tol", "absolute_error_tol", "error_tol"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"{name} must be a finite number >= 0, got {v!r}")
        if not (math.isfinite(self.prior_sigma) and self.prior_sigma > 0):
            raise ConfigError(f"prior_sigma must be > 0, got {self.prior_sigma!r}")
        if self.robust_k is not None and not (math.isfinite(self.robust_k) and self.robust_k > 0):
            raise ConfigError(f"robust_k must be > 0, got {self.robust_k!r}")


@dataclass(frozen=True)
class OptimizeResult:
    """Everything a solve produced. Poses are in the PoseGraph layout, rows matching
    ``vertex_ids``. ``final_error`` is GTSAM's error (1/2 sum of whitened squared residuals,
    including the gauge prior and any robust loss), ``chi2`` = 2 * final_error. ``errors`` holds
    the error before the first and after every ``iterate()`` (batch) or ``ISAM2.update``
    (isam2, only ``[initial, final]`` unless a hook asked for more). ``marginal_covariances``
    (N, 3, 3) in (x, y, theta) or (N, 6, 6) in the PoseGraph's g2o order (x, y, z, rx, ry, rz);
    ``solver``, ``linear_solver`` and ``init`` are what was actually used after fallbacks."""

    name: str
    vertex_ids: np.ndarray
    initial_poses: np.ndarray
    poses: np.ndarray
    initial_error: float
    final_error: float
    chi2: float
    iterations: int
    errors: np.ndarray
    num_factors: int
    time_build_s: float
    time_init_s: float
    time_solve_s: float
    time_marginals_s: float
    solver: str
    linear_solver: str
    init: str
    converged: bool
    warnings: tuple[str, ...] = ()
    marginal_covariances: np.ndarray | None = None
    config: OptimizeConfig = field(default_factory=OptimizeConfig)


def _params(solver: str, linear_solver: str, config: OptimizeConfig):
    params = {"lm": gtsam.LevenbergMarquardtParams, "gn": gtsam.GaussNewtonParams,
              "dogleg": gtsam.DoglegParams}[solver]()
    params.setMaxIterations(int(config.max_iterations))
    params.setRelativeErrorTol(float(config.relative_error_tol))
    params.setAbsoluteErrorTol(float(config.absolute_error_tol))
    params.setErrorTol(float(config.error_tol))
    params.setLinearSolverType(LINEAR_SOLVERS[linear_solver])
    return params


def make_optimizer(fg: gtsam.NonlinearFactorGraph, values: gtsam.Values, solver: str,
                   linear_solver: str, config: OptimizeConfig):
    """The GTSAM optimizer (and its params) ``optimize`` drives, exposed for references."""
    params = _params(solver, linear_solver, config)
    cls = {"lm": gtsam.LevenbergMarquardtOptimizer, "gn": gtsam.GaussNewtonOptimizer,
           "dogleg": gtsam.DoglegOptimizer}[solver]
    return cls(fg, values, params), params


class _SolveFailed(Exception):
    pass


def iterate_to_convergence(optimizer, params, on_step: Callable[[int, float], None] | None = None,
                           ) -> tuple[list[float], bool]:
    """GTSAM's ``defaultOptimize`` loop, written out so each step is observable.

    Returns the error before the first and after every ``iterate()`` and whether the loop
    stopped on the convergence test (not on the iteration cap). Raises ``_SolveFailed`` when a
    linear solve fails or the error becomes non-finite."""
    current = optimizer.error()
    errors = [current]
    if on_step is not None:
        on_step(optimizer.iterations(), current)
    max_it, rel, abs_, etol = (params.getMaxIterations(), params.getRelativeErrorTol(),
                               params.getAbsoluteErrorTol(), params.getErrorTol())
    if not math.isfinite(current):
        raise _SolveFailed(f"initial error is {current}")
    if current <= etol:
        return errors, True
    if optimizer.iterations() >= max_it:
        return errors, False
    is_lm = isinstance(optimizer, gtsam.LevenbergMarquardtOptimizer)
    new = current
    while True:
        current = new
        before = optimizer.iterations()
        try:
            optimizer.iterate()
        except RuntimeError as exc:
            if is_indeterminant(exc):
                raise _SolveFailed(f"indeterminant linear system: {str(exc).strip().splitlines()[0]}")
            raise
        new = optimizer.error()
        errors.append(new)
        if on_step is not None:
            on_step(optimizer.iterations(), new)
        if not math.isfinite(new):
            raise _SolveFailed(f"error became {new}")
        if (is_lm and before == 0 and optimizer.iterations() == 0
                and optimizer.lambda_() >= params.getlambdaUpperBound() and new >= current):
            # LM catches IndeterminantLinearSystem internally and raises lambda until it gives
            # up: no accepted step at all means the linear solver never produced one.
            raise _SolveFailed("Levenberg-Marquardt gave up at its maximum lambda without a step")
        converged = gtsam.checkConvergence(rel, abs_, etol, current, new)
        if not (optimizer.iterations() < max_it and not converged and math.isfinite(current)):
            return errors, bool(converged)


def marginal_covariances(fg: gtsam.NonlinearFactorGraph, values: gtsam.Values, dim: int,
                         keys: list[int]) -> np.ndarray:
    """Marginal covariance of every key (GTSAM's ``Marginals``: Cholesky of the information at
    ``values``), returned in slamkit's tangent order (3D: translation first, as the PoseGraph's
    information)."""
    marginals = gtsam.Marginals(fg, values)
    cov = np.stack([marginals.marginalCovariance(k) for k in keys])
    if dim == 3:
        cov = cov[:, G2O_TO_GTSAM][:, :, G2O_TO_GTSAM]
    return cov


def optimize(graph: PoseGraph, config: OptimizeConfig = OptimizeConfig(),
             on_iteration: IterationHook | None = None) -> OptimizeResult:
    """Solve ``graph`` as configured. ``on_iteration(iteration, error, poses)`` is called with the
    initial state (iteration 0) and after every step (poses in the PoseGraph layout); it only
    observes. After a QR fallback the hook sees the restarted solve from iteration 0 again."""
    warnings: list[str] = []
    nonpd = _count_non_pd(graph.information)
    if nonpd:
        warnings.append(f"{nonpd} of {graph.num_edges} edges have an information matrix that is "
                        f"not positive definite; GTSAM factorises them as given (as readG2o does)")
    with Stopwatch() as sw_build:
        mask = ~graph.is_odometry() if config.robust_edges == "loop_closures" else None
        fg, key_of = build_graph(graph, config.robust, config.robust_k, config.prior_sigma, robust_mask=mask)
    with Stopwatch() as sw_init:
        init = initial_values(graph, config.init, config.prior_sigma,
                              factor_graph=fg if config.robust == "none" else None)
    warnings += init.warnings
    initial_error = None
    keys = [key_of[int(v)] for v in graph.vertex_ids.tolist()]

    def to_numpy(values: gtsam.Values) -> np.ndarray:
        return poses_from_values(graph.dim, graph.vertex_ids, values)

    solver, linear = config.solver, config.linear_solver
    with Stopwatch() as sw_solve:
        if solver == "isam2":
            initial_error = fg.error(init.values)
            hook = on_iteration
            if hook is not None:
                hook(0, initial_error, init.poses)
            isam_params = config.isam2
            try:
                values, iterations = isam2_replay(graph, fg, isam_params, on_update=hook)
            except RuntimeError as exc:
                if not (is_indeterminant(exc) and config.qr_fallback
                        and isam_params.factorization == "cholesky"):
                    raise BackendError(f"{graph.name}: iSAM2 replay failed: {exc}") from exc
                warnings.append(f"iSAM2 with Cholesky hit an indeterminant linear system on "
                                f"{graph.name}; replay redone with QR factorisation")
                isam_params = replace(isam_params, factorization="qr")
                values, iterations = isam2_replay(graph, fg, isam_params, on_update=hook)
            errors = [initial_error, fg.error(values)]
            converged = True
            linear = isam_params.factorization
        else:
            try:
                values, errors, iterations, converged = _batch(fg, init.values, solver, linear,
                                                               config, on_iteration, to_numpy)
            except _SolveFailed as failure:
                if not (config.qr_fallback and linear == "cholesky"):
                    raise BackendError(f"{graph.name}: {solver} with {linear} failed: {failure}")
                warnings.append(f"{solver} with sparse Cholesky failed on {graph.name} "
                                f"({failure}); redone with dogleg on multifrontal QR")
                solver, linear = "dogleg", "qr"
                try:
                    values, errors, iterations, converged = _batch(
                        fg, init.values, solver, linear, config, on_iteration, to_numpy)
                except _SolveFailed as again:
                    raise BackendError(f"{graph.name}: QR fallback failed too: {again}") from None
            # the optimizer already evaluated both: no need to sweep the graph again
            initial_error = errors[0]
    final_error = errors[-1]
    if not converged:
        warnings.append(f"stopped at the iteration cap ({config.max_iterations}) before the "
                        f"convergence test passed")
    cov = None
    with Stopwatch() as sw_marg:
        if config.compute_marginals:
            try:
                cov = marginal_covariances(fg, values, graph.dim, keys)
            except RuntimeError as exc:
                warnings.append(f"marginal covariances unavailable: {str(exc).strip()[:200]}")
    return OptimizeResult(
        name=graph.name, vertex_ids=np.array(graph.vertex_ids), initial_poses=init.poses,
        poses=to_numpy(values), initial_error=float(initial_error), final_error=float(final_error),
        chi2=2.0 * float(final_error), iterations=int(iterations), errors=np.asarray(errors),
        num_factors=int(fg.size()), time_build_s=sw_build.elapsed_s, time_init_s=sw_init.elapsed_s,
        time_solve_s=sw_solve.elapsed_s, time_marginals_s=sw_marg.elapsed_s, solver=solver,
        linear_solver=linear, init=init.method, converged=converged, warnings=tuple(warnings),
        marginal_covariances=cov, config=config)


def _batch(fg, values, solver, linear, config, on_iteration, to_numpy):
    optimizer, params = make_optimizer(fg, values, solver, linear, config)
    on_step = None
    if on_iteration is not None:
        def on_step(iteration: int, error: float) -> None:
            on_iteration(iteration, error, to_numpy(optimizer.values()))
    errors, converged = iterate_to_convergence(optimizer, params, on_step)
    # copy: the optimizer owns its Values and is dropped when this returns
    return gtsam.Values(optimizer.values()), errors, optimizer.iterations(), converged


def _count_non_pd(information: np.ndarray) -> int:
    """Edges whose (symmetrised) information is not positive definite, by Sylvester's criterion
    (all leading principal minors > 0), batched."""
    if len(information) == 0:
        return 0
    sym = 0.5 * (information + np.swapaxes(information, 1, 2))
    ok = np.ones(len(sym), dtype=bool)
    for n in range(1, sym.shape[1] + 1):
        ok &= np.linalg.det(sym[:, :n, :n]) > 0.0
    return int(np.count_nonzero(~ok))
