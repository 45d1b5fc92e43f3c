"""Levenberg-Marquardt driven from Python, for graphs that hold Python ``gtsam.CustomFactor``\\ s.

The algorithm is GTSAM's ``LevenbergMarquardtOptimizer`` (Levenberg 1944, Marquardt 1963; GTSAM's
trust-region variant), step for step with its defaults: damping ``sqrt(lambda) I`` on every
variable (``diagonalDamping`` off), lambda starting at ``lambda_initial``, divided by
``lambda_factor`` after an accepted step and multiplied by it after a rejected one, a step accepted
when the linearised cost decreases and the model fidelity (actual / predicted decrease) exceeds
``min_model_fidelity``, LM giving up when lambda reaches ``lambda_upper_bound``, and GTSAM's
``checkConvergence`` (absolute or relative decrease under its tolerance). The COLAMD ordering of
the nonlinear graph is computed once, as LM does when its params hold an ordering. On the same
graph it takes the same steps and returns the same values (tested).

Why it exists: a ``CustomFactor``'s Python callback receives the ``gtsam.Values`` it is evaluated
at. pybind11 hands a C++ object to Python by reference only when that object already has a Python
wrapper; otherwise it *copies* it. Inside GTSAM's C++ optimiser the linearisation point and each
trial's values are C++ temporaries, so every callback copied the whole Values: on Plaza 2 with the
range scale estimated (3529 scaled range factors, 4096 variables) one error evaluation costs
3529 copies of 4096 values, 1.25 s (``perf``: the time is in ``gtsam::Values::insert``, malloc and
free), and the batch solve took ~50 s. Here every Values the graph is linearised or evaluated at
is a Python object, so the callbacks get it by reference: the same solve takes ~20x less.
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np


@dataclass(frozen=True)
class LMResult:
    values: gtsam.Values
    iterations: int
    error: float
    #: linear solves (lambda trials) over all iterations
    trials: int


def levenberg_marquardt(graph: gtsam.NonlinearFactorGraph, initial: gtsam.Values, *,
                        max_iterations: int = 100, relative_error_tol: float = 1e-5,
                        absolute_error_tol: float = 1e-5, error_tol: float = 0.0,
                        lambda_initial: float = 1e-5, lambda_factor: float = 10.0,
                        lambda_upper_bound: float = 1e5, min_model_fidelity: float = 1e-3) -> LMResult:
    """Minimise ``graph`` from ``initial`` (see the module docstring; GTSAM's LM defaults)."""
    ordering = gtsam.Ordering.ColamdNonlinearFactorGraph(graph)
    zero = initial.zeroVectors()
    key_dims = [(key, zero.at(key).shape[0]) for key in initial.keys()]
    damping: dict[float, gtsam.GaussianFactorGraph] = {}   # per lambda (it takes few values)

    def damping_factors(lam: float) -> gtsam.GaussianFactorGraph:
        if lam not in damping:
            factors, root = gtsam.GaussianFactorGraph(), np.sqrt(lam)
            for key, dim in key_dims:
                factors.add(gtsam.JacobianFactor(key, root * np.eye(dim), np.zeros(dim),
                                                 gtsam.noiseModel.Unit.Create(dim)))
            damping[lam] = factors
        return damping[lam]

    values, error, lam = initial, graph.error(initial), lambda_initial
    iterations = trials = 0
    while iterations < max_iterations and np.isfinite(error) and error > error_tol:
        linear = graph.linearize(values)
        accepted = None
        while accepted is None:
            trials += 1
            damped = linear.clone()
            damped.push_back(damping_factors(lam))
            delta = damped.optimize(ordering)
            linearized_change = error - linear.error(delta)
            if linearized_change >= 0:
                candidate = values.retract(delta)
                candidate_error = graph.error(candidate)
                if linearized_change > 1e-20:
                    success = (error - candidate_error) / linearized_change > min_model_fidelity
                else:
                    success = True
                if success:
                    accepted = (candidate, candidate_error)
                    lam /= lambda_factor
                    break
            lam *= lambda_factor
            if lam >= lambda_upper_bound:
                break                     # GTSAM: "giving up because cannot decrease error"
        iterations += 1
        if accepted is None:
            break
        previous = error
        values, error = accepted
        decrease = previous - error
        if decrease <= absolute_error_tol or decrease / previous <= relative_error_tol:
            break
    return LMResult(values, iterations, float(error), trials)
