"""What a viewer gets of a navigation step (issue 30, item 4): frozen values, never the live
stack or plant -- the scene drawn once per episode (:class:`NavigationScene`) and per cycle a
:class:`NavigationSnapshot`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from slamkit.experiments.observers import PipelineObserver, StepSnapshot
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.sim.navigation_world import NavigationPlant, NavigationScenario
from slamkit.systems.navigation import CommandStatus, NavigationCommand, NavigationStack

SNAPSHOT_MAX_PARTICLES = 500


def _frozen(a: Any, dtype: type = float) -> np.ndarray:
    """A read-only copy (a snapshot shares no array with the stack or the plant)."""
    out = np.array(a, dtype=dtype, copy=True)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class NavigationScene:
    """What a recording of one episode draws once: the robot's map, the world's own grid (the
    same object when the robot's map is the world's), ``costmap_blocked`` (H, W) the free cells of
    the robot's map the inflated robot may not enter (the global planner's costmap without a
    chance margin), the goal pose and the robot's radius."""

    robot_map: OccupancyGrid
    true_map: OccupancyGrid
    costmap_blocked: np.ndarray
    goal_xytheta: np.ndarray
    robot_radius_m: float


@dataclass(frozen=True)
class NavigationSnapshot:
    """One control cycle of a navigation episode as the viewer draws it (issue 30, item 4): copied,
    read-only arrays, never the live stack or plant. The truth (``true_xytheta``, the crossing
    obstacles ``obstacles_xy_m`` / ``obstacles_radius_m`` of the episode's traffic at the stamp) beside the
    stack's belief (``estimate_xytheta``, ``covariance`` (3, 3), at most
    :data:`SNAPSHOT_MAX_PARTICLES` ``particles_xytheta``), its global ``path_xy_m`` (None before
    the first plan), the scan end points the map does not explain, the lidar tracks (ids,
    centres, radii, velocities), the decision (``command``, ``status``) and the local planner's
    candidates with their scores and ``chosen`` index, or the MPC's predicted horizon."""

    scene: NavigationScene
    true_xytheta: np.ndarray
    estimate_xytheta: np.ndarray
    covariance: np.ndarray
    particles_xytheta: np.ndarray
    path_xy_m: np.ndarray | None
    scan_unexplained_xy_m: np.ndarray
    track_ids: np.ndarray
    track_xy_m: np.ndarray
    track_radius_m: np.ndarray
    track_velocity_mps: np.ndarray
    obstacles_xy_m: np.ndarray
    obstacles_radius_m: np.ndarray
    command: np.ndarray
    status: CommandStatus
    candidates_xytheta: np.ndarray | None = None
    candidate_scores: np.ndarray | None = None
    chosen: int = -1
    mpc_horizon_xytheta: np.ndarray | None = None


def navigation_scene(scenario: NavigationScenario, stack: NavigationStack) -> NavigationScene:
    g = stack.grid
    return NavigationScene(g, scenario.grid, _frozen(~np.isfinite(stack.cell_cost(0)) & ~g.occupied, bool),
                           _frozen(scenario.goal_xytheta), float(stack.config.robot_radius_m))


def navigation_snapshot(scene: NavigationScene, scenario: NavigationScenario, stack: NavigationStack,
                        plant: NavigationPlant, t_s: float, decision: NavigationCommand) -> NavigationSnapshot:
    """The snapshot of the cycle that has just ended (read at once: the stack and plant move on)."""
    mean, cov = stack.current_pose()
    tracks = stack.tracks()
    # the plant's own traffic: social-force people react to this episode's robot, so the
    # scenario's template would draw them walking as if it were not there
    obs = plant.obstacles
    out = decision.output
    has_candidates = out is not None and out.candidates_xytheta is not None and len(out.candidates_xytheta) > 0
    return NavigationSnapshot(
        scene, _frozen(plant.world_xytheta_body), _frozen(mean), _frozen(cov),
        _frozen(stack.particles[:SNAPSHOT_MAX_PARTICLES]),
        None if stack.path is None else _frozen(stack.path), _frozen(stack.last_scan_points),
        _frozen(tracks.ids, int), _frozen(tracks.xy_m), _frozen(tracks.radius_m), _frozen(tracks.velocity_mps),
        _frozen(obs.position_at(t_s) if len(obs) else np.zeros((0, 2))),
        _frozen(obs.radius_m if len(obs) else np.zeros(0)),
        _frozen(decision.command), CommandStatus(decision.status),
        candidates_xytheta=_frozen(out.candidates_xytheta) if has_candidates else None,
        candidate_scores=_frozen(out.scores) if has_candidates and out.scores is not None else None,
        chosen=int(out.chosen) if has_candidates else -1,
        mpc_horizon_xytheta=(_frozen(out.predicted_xytheta) if out is not None and out.predicted_xytheta is not None
                             else None))


def _snapshots(observer: PipelineObserver, run_name: str, scenario: NavigationScenario):
    """An ``on_step`` that hands each cycle to a pipeline observer as a ``StepSnapshot`` whose
    state is a :class:`NavigationSnapshot` (its :class:`NavigationScene` built at the first cycle)."""
    counter = iter(range(10**9))
    scene: list[NavigationScene] = []

    def on_step(stack, plant, t_s, decision) -> None:
        if not scene:
            scene.append(navigation_scene(scenario, stack))
        observer.on_step(StepSnapshot("navigation", run_name, next(counter), t_s,
                                      navigation_snapshot(scene[0], scenario, stack, plant, t_s, decision)))
    return on_step
