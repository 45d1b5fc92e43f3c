"""Privileged perception of the moving discs, an ablation of the navigation benchmark
(``EpisodeConfig.perception``): how well would the stack do if it saw the traffic better?

* ``lidar`` (the benchmark): the stack detects and tracks the discs from its own scans
  (:mod:`slamkit.estimation.obstacle_tracker`).
* ``true_detections``: each scan's detections are the true discs that scan saw (at least
  ``min_beams`` of its noise-free beams end on the disc: the lidar's own visibility, walls and other
  discs occlude), with their true centre and radius and no clutter; the stack's tracker filters them
  as usual. What is left is the tracker's: its lag, the velocity it has to infer, births and deaths.
* ``true_tracks``: the same, and after every scan the tracker's tracks take the true centre,
  velocity and radius of the disc they follow (the motion history -- span, reversals, typical
  speed -- is still the tracker's, from those exact positions). Only visibility is left.

Comparing the three on the same seeds splits the collisions between the detector, the tracker
and the planner (the paired tables of ``slamkit.experiments.navigation.benchmark``). Measured
(issue 33; pipelines/navigation.yaml's constant-velocity traffic and stack, successes / moving /
static / timeouts of 270 runs, 3 worlds x 90 seeds):

| perception | development seeds 3000-3089 | evaluation blocks 5000-5089 |
|---|---|---|
| lidar (the stack's own) | 245 / 21 / 3 / 1 | 250 / 19 / 0 / 1 |
| true_detections | 252 / 12 / 1 / 5 | 251 / 15 / 1 / 3 |
| true_detections, a quick tracker (``accel_psd`` 5, ``sigma_detection_m`` 0.02) | 258 / 3 / 0 / 9 | 254 / 8 / 0 / 8 |
| true_tracks | 258 / 2 / 0 / 10 | 255 / 5 / 0 / 10 |

With what the lidar sees, seen exactly, the planner keeps the moving hits at 0.7-1.9% (the goal:
< 2%): the collisions are perception's -- the detector's centres, which force a sluggish tracker
(with exact detections and a tracker quick enough for them, nearly as good as the truth).

The truth is the plant's (:meth:`NavigationPlant.discs_seen`), put into the robot's map frame
through the episode's :class:`RobotMap`.
"""

from __future__ import annotations

import math

import numpy as np

from slamkit.errors import DataError
from slamkit.estimation.obstacle_tracker import ConstantVelocityTracker, Detection, TrackerConfig, Tracks
from slamkit.experiments.navigation.map_source import RobotMap
from slamkit.sim.navigation_world import NavigationPlant

PERCEPTION = ("lidar", "true_detections", "true_tracks")


class TruePerception:
    """The stack's tracker (``NavigationStack(tracker=...)``) fed from the plant's truth; see the
    module docstring. ``true_tracks``: the tracks' states are the truth, else the tracker's own."""

    def __init__(self, plant: NavigationPlant, robot: RobotMap, config: TrackerConfig, true_tracks: bool,
                 min_beams: int = 3):
        self.plant, self.robot = plant, robot
        self.true_tracks, self.min_beams = bool(true_tracks), int(min_beams)
        self.tracker = ConstantVelocityTracker(config)

    @property
    def config(self) -> TrackerConfig:
        return self.tracker.config

    def reset(self) -> None:
        self.tracker.reset()

    def truth_at(self, t_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every disc's centre (K, 2), velocity (K, 2) and radius (K,) at ``t_s``, in the map frame."""
        obs = self.plant.obstacles
        xy, v = obs.position_at(t_s), obs.velocity_at(t_s)
        heading = np.arctan2(v[:, 1], v[:, 0])
        in_map = np.array([self.robot.to_map(np.array([x, y, h])) for (x, y), h in zip(xy, heading)]).reshape(-1, 3)
        speed = np.linalg.norm(v, axis=1)
        v_map = speed[:, None] * np.column_stack([np.cos(in_map[:, 2]), np.sin(in_map[:, 2])])
        return in_map[:, :2], v_map, np.asarray(obs.radius_m, float)

    def update(self, t_s: float, detection: Detection) -> None:
        """The stack's detection is ignored: the truth the scan at ``t_s`` saw replaces it."""
        t_seen, beams = self.plant.discs_seen()
        if not math.isclose(t_seen, t_s, abs_tol=1e-9):
            raise DataError(f"TruePerception: the plant's last scan is at {t_seen} s, the stack's at {t_s} s")
        xy, v, r = self.truth_at(t_s)
        seen = beams >= self.min_beams
        self.tracker.update(t_s, Detection(xy[seen], r[seen], beams[seen]))
        if self.true_tracks:
            track_xy, _, _ = self.tracker.states()
            if len(track_xy) and len(xy):
                k = np.argmin(np.linalg.norm(track_xy[:, None] - xy[None], axis=2), axis=1)  # the disc each follows
                self.tracker.set_states(xy[k], v[k], r[k])

    def tracks(self) -> Tracks:
        return self.tracker.tracks()
