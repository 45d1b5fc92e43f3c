"""An example slamkit plug-in: what a user writes to bring their own algorithm (issue 32).

Registry entries of every kind, declared as entry points in ``pyproject.toml`` so that installing the
package is all it takes (or, without installing, ``plugins: [slamkit_example_plugin]`` in a
pipeline config / ``slamkit run --plugin slamkit_example_plugin`` with the folder on
PYTHONPATH; importing this module then registers nothing twice, since entry points name the
objects and the registries skip an identical entry):

- ``odometry_only``: an estimator that integrates the odometry and nothing else (the exact-arc
  motion model, covariance propagated with Q = L M L^T). It estimates the pose only and is given
  no map, so the filter_vs_smoother report files it under "pose only".
- ``straight_line``: a planner that tries the straight segment from start to goal.
- ``pure_pursuit``: a controller steering onto the arc through a look-ahead point.
- ``odometry_drift``: a pipeline (its config model and run function) with a closed-form answer.
- ``example-square``: a four-pose g2o pose graph shipped inside the package.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slamkit.data.estimate import Estimate, Prior
from slamkit.data.noise import NoiseParams
from slamkit.data.registry import DatasetEntry, DatasetFile
from slamkit.data.sequence import Odometry
from slamkit.data.trajectory import Trajectory
from slamkit.experiments.estimators import EstimatorSpec
from slamkit.models.diff_drive import motion, process_noise
from slamkit.planning.protocols import PlanResult, PlanStats, PlanStatus, PlanningProblem, failed
from slamkit.planning.registry import PlannerSpec


# --- estimator ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class OdometryOnlyConfig:
    #: multiplies the assumed odometry covariance (1: the sequence's declared noise)
    covariance_scale: float = 1.0


class OdometryOnly:
    """Dead reckoning from ``Odometry`` events; every other event is counted and ignored."""

    name = "odometry_only"

    def __init__(self, noise: NoiseParams, config: OdometryOnlyConfig = OdometryOnlyConfig()):
        self.noise, self.config = noise, config

    def reset(self, prior: Prior) -> None:
        self._x = np.asarray(prior.world_xytheta_body, float).copy()
        self._P = np.asarray(prior.covariance, float).copy()
        self._stamps: list[float] = []
        self._poses: list[np.ndarray] = []
        self._covs: list[np.ndarray] = []
        self._latency: list[float] = []
        self._ignored = 0

    def step(self, event) -> None:
        t0 = time.perf_counter()
        if isinstance(event, Odometry):
            u = np.array([event.v_mps, event.omega_radps])
            from slamkit.models.diff_drive import motion_jacobians

            F, _ = motion_jacobians(self._x, u, event.dt_s)
            Q = process_noise(self._x, u, event.dt_s, self.config.covariance_scale * self.noise.control_cov)
            self._x = motion(self._x, u, event.dt_s)
            self._P = F @ self._P @ F.T + Q
        else:
            self._ignored += 1
        # one row per distinct stamp: the belief after the last event at that stamp
        if self._stamps and self._stamps[-1] == event.stamp_s:
            self._poses[-1], self._covs[-1] = self._x.copy(), self._P.copy()
        else:
            self._stamps.append(float(event.stamp_s))
            self._poses.append(self._x.copy())
            self._covs.append(self._P.copy())
        self._latency.append(time.perf_counter() - t0)

    def estimate(self) -> Estimate:
        return Estimate(trajectory=Trajectory.from_se2(np.array(self._stamps), np.array(self._poses).reshape(-1, 3)),
                        pose_covariances=np.array(self._covs).reshape(-1, 3, 3),
                        step_latency_s=np.array(self._latency), extras={"ignored_events": self._ignored})


ODOMETRY_ONLY = EstimatorSpec(
    name="odometry_only", kind="filter", target="slamkit_example_plugin:OdometryOnly",
    needs_landmark_map=False, config="OdometryOnlyConfig", random=False,
    description="odometry integration only (example plug-in)", estimates="pose")


# --- planner --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class StraightLineConfig:
    #: spacing of the collision checks along the segment, in cells
    step_cells: float = 0.25


class StraightLinePlanner:
    """The straight segment start -> goal when every point on it is free; TIMEOUT otherwise
    (its budget is one segment: it proves nothing about other paths)."""

    def __init__(self, config: StraightLineConfig = StraightLineConfig(), hook=None):
        self.config, self.hook = config, hook

    def plan(self, problem: PlanningProblem) -> PlanResult:
        t0 = time.perf_counter()
        grid, start, goal = problem.world, problem.start[:2], problem.goal[:2]
        if not grid.is_free_world(start[None])[0]:
            return failed(PlanStatus.INVALID_START, "straight_line")
        if not grid.is_free_world(goal[None])[0]:
            return failed(PlanStatus.INVALID_GOAL, "straight_line")
        length_m = float(np.linalg.norm(goal - start))
        if length_m == 0.0:
            return PlanResult(PlanStatus.SOLVED, start[None].copy(), 0.0,
                              PlanStats(time_s=time.perf_counter() - t0), "straight_line")
        n = int(np.ceil(length_m / (self.config.step_cells * grid.resolution_m))) + 1
        points = start + np.linspace(0.0, 1.0, n)[:, None] * (goal - start)
        if not grid.is_free_world(points).all():
            return failed(PlanStatus.TIMEOUT, "straight_line", time_s=time.perf_counter() - t0)
        return PlanResult(PlanStatus.SOLVED, np.stack([start, goal]), length_m,
                          PlanStats(time_s=time.perf_counter() - t0, expansions=n), "straight_line")


STRAIGHT_LINE = PlannerSpec(StraightLinePlanner, StraightLineConfig, needs_rng=False)


# --- controller -----------------------------------------------------------------------------------

@dataclass(frozen=True)
class PurePursuitConfig:
    lookahead_m: float = 0.5
    v_max_mps: float = 0.8
    omega_max_radps: float = 1.5
    goal_tolerance_m: float = 0.2
    #: length of the predicted arc shown with the command
    horizon_s: float = 1.0


class PurePursuit:
    """Pure pursuit (Coulter 1992): steer onto the arc through the path point ``lookahead_m``
    ahead, at the reference speed, slowing where the arc is tight; ignores obstacles."""

    name = "pure_pursuit"

    def __init__(self, config: PurePursuitConfig = PurePursuitConfig()):
        self.config = config

    def reset(self) -> None:
        pass  # no state between cycles

    def compute(self, state, reference, world):
        from slamkit.control.protocols import ControlOutput, ControlStatus, non_finite_brake

        t0 = time.perf_counter()
        if not state.finite:
            return non_finite_brake()
        c = self.config
        x, y, theta = state.world_xytheta_body
        path = reference.path_xy_m
        if np.hypot(*(reference.goal_xy_m - (x, y))) <= c.goal_tolerance_m:
            return ControlOutput(np.zeros(2), ControlStatus.GOAL_REACHED, solve_time_s=time.perf_counter() - t0)
        # the first path point at least lookahead_m away, after the closest one (else the goal)
        d = np.hypot(path[:, 0] - x, path[:, 1] - y)
        ahead = np.flatnonzero((np.arange(len(path)) >= np.argmin(d)) & (d >= c.lookahead_m))
        target = path[ahead[0]] if len(ahead) else reference.goal_xy_m
        dx, dy = target[0] - x, target[1] - y
        body_y = -np.sin(theta) * dx + np.cos(theta) * dy
        curvature = 2.0 * body_y / max(dx * dx + dy * dy, 1e-12)
        v = min(reference.speed_mps, c.v_max_mps)
        if abs(curvature) * v > c.omega_max_radps:
            v = c.omega_max_radps / abs(curvature)
        command = np.array([v, float(np.clip(curvature * v, -c.omega_max_radps, c.omega_max_radps))])
        ts = np.linspace(0.0, c.horizon_s, 11)
        predicted = motion(np.tile(state.world_xytheta_body, (len(ts), 1)), np.tile(command, (len(ts), 1)), ts)
        return ControlOutput(command, ControlStatus.OK, predicted_xytheta=predicted,
                             solve_time_s=max(time.perf_counter() - t0, 1e-9))


def _controller_spec():
    from slamkit.control.registry import ControllerSpec

    return ControllerSpec(PurePursuit, PurePursuitConfig)


PURE_PURSUIT = _controller_spec()


# --- pipeline -------------------------------------------------------------------------------------

def _pipeline():
    from typing import Literal

    from slamkit.experiments.config_models import PipelineConfig
    from slamkit.experiments.pipeline import Pipeline, PipelineOutput
    from slamkit.experiments.results import RunRecord

    class DriftConfig(PipelineConfig):
        pipeline: Literal["odometry_drift"]
        #: straight-line distance driven (m) and the heading bias of the odometry (rad/m)
        distance_m: float = 10.0
        heading_bias_radpm: float = 0.01

    def run(config, folder, progress, observer) -> PipelineOutput[dict]:
        """The end-point error of dead reckoning with a constant heading bias b over a straight
        drive of length L: the robot turns by b s after s metres, so it ends at
        (sin(bL)/b, (1 - cos(bL))/b) instead of (L, 0)."""
        length, bias = config.distance_m, config.heading_bias_radpm  # config: the validated DriftConfig
        end = np.array([np.sin(bias * length) / bias, (1 - np.cos(bias * length)) / bias]) if bias else np.array([length, 0.0])
        error_m = float(np.hypot(*(end - (length, 0.0))))
        record = RunRecord("straight", "biased_odometry", {"final_position_error_m": error_m})
        return PipelineOutput([record], f"# odometry drift\n\nfinal position error {error_m:.4f} m\n",
                              payload={"end_xy_m": end.tolist()})

    return Pipeline("odometry_drift", run, DriftConfig, dict, "dead-reckoning drift of a biased heading")


ODOMETRY_DRIFT = _pipeline()


# --- dataset --------------------------------------------------------------------------------------

_SQUARE = Path(__file__).with_name("square.g2o")
EXAMPLE_SQUARE = DatasetEntry(
    name="example-square", kind="pose_graph_2d", format="g2o",
    files=(DatasetFile(path=str(_SQUARE), sha256="", size_bytes=0, source="slamkit_example_plugin",
                       url=""),),
    title="a 2 m square driven once, with one loop closure (example plug-in)", licence="CC0-1.0",
    counts={"poses": 4, "edges": 4}, references=())


# Importing the module registers its entries too, so that ``plugins: [slamkit_example_plugin]``
# works without installing the package (re-registering the same entry is a no-op).
def _register() -> None:
    from slamkit.control.registry import register_controller
    from slamkit.data.registry import register_dataset
    from slamkit.experiments.estimators import register_estimator
    from slamkit.experiments.pipeline import register_pipeline
    from slamkit.planning.registry import register_planner

    register_estimator(ODOMETRY_ONLY)
    register_planner("straight_line", STRAIGHT_LINE)
    register_controller("pure_pursuit", PURE_PURSUIT)
    register_pipeline(ODOMETRY_DRIFT)
    register_dataset(EXAMPLE_SQUARE)


_register()
