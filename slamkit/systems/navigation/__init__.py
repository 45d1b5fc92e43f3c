"""The navigation stack as a system: sensor events and a goal in, velocity commands out (the
course's Example 10.3, with section 11.4's safety under uncertainty on top).

Where each responsibility lives (issue 30: one module each, with its own config section):

| module | responsibility (config section of :class:`NavigationConfig`) |
|---|---|
| :mod:`.stack` | :class:`NavigationStack`: orchestration, localisation (MCL), perception (tracks from the scan), the local planner and the one prediction of the tracks (top-level fields) |
| :mod:`.global_planning` | the global path, its cost cache, the chance margins (``planning``) |
| :mod:`.yielding` | yielding to crossing traffic: sweep, waiting places, back-off along the trail (``yielding``) |
| :mod:`.safety` | the safety guard: evasion, passive safety, brake profiles, safe stop (``safety``) |
| :mod:`.goal` | the goal regulator's final approach (``goal``) |
| :mod:`.recovery` | stuck detection and nav2-style recovery (``recovery``) |
| :mod:`.command` | :class:`NavigationCommand` and :class:`CommandStatus` |
| :mod:`.config` | :class:`NavigationConfig`, its sections, the local planner's defaults |

Layers, each timed per call (``NavigationStack.timings_s``):

* ``localisation`` -- MCL with the likelihood field (:class:`slamkit.estimation.lidar_mcl.LidarMCL`,
  a fixed 500 particles, tracking from the given start belief) on wheel odometry (``Odometry``
  events: predict) and lidar (``Scan`` events: update). ``current_pose`` and
  ``latest_estimate`` (the ``LatestBelief`` protocol) give the pose and its covariance; the
  other layers only ever see that estimate.
* ``perception`` -- moving obstacles from the scan itself: end points the static map does not
  explain, clustered and tracked with a constant-velocity filter
  (:mod:`slamkit.estimation.obstacle_tracker`).
* ``global_planner`` -- A* (or any grid planner of the registry; D* Lite repairs its search) on the
  Nav2 costmap of the map, from the estimated pose to the goal, every ``planning.replan_period_s``
  or at once when the path is blocked or the robot is stuck (:mod:`.global_planning`,
  :mod:`.recovery`).
* ``local_planner`` -- every ``command`` (10 Hz in the experiment): a controller of the registry
  (``dwa`` with the course's alpha 0.8 / beta 0.2 / gamma 0.4, ``rollout``, ``mpc`` ...) tracking
  the global path among the tracked obstacles (constant-velocity prediction) and the static
  distance field, capped at ``cruise_speed_mps`` and by yielding (:mod:`.yielding`), guarded by
  :mod:`.safety`; within ``goal.approach_radius_m`` of the goal the regulator (:mod:`.goal`)
  takes over.

Planning under uncertainty (``NavigationConfig.uncertainty``, :mod:`.global_planning`):

* ``"covariance"``: the costmap's inscribed radius is the robot radius plus the path margin plus
  k sigma (k = Phi^-1(1 - delta), sigma the largest standard deviation of the position
  covariance; :func:`slamkit.maps.inflation.chance_inflation_m`) and the local planner sees every
  obstacle tightened by k sigma_n (:func:`slamkit.control.chance_constraints.tightened_world`),
  which for the MPC makes its obstacle rows chance constraints: the walls by the pose
  covariance, the lidar tracks by their own covariance only (the pose error moves them with the
  robot). When k sigma leaves no path (a narrow passage, or the estimate inside the margin) the
  plan uses the largest margin that does, and the stack lowers k for the local planner to match
  (``chance_k``; ``planned_collision_probability_max`` is the delta that amounts to);
* ``"local"``: the costmap stays fixed and only the local planner's obstacles are tightened by
  k sigma_n -- with ``controller: mpc`` the chance-constrained MPC on its own;
* ``"fixed"``: the margins stay what they are whatever the covariance.

The stack knows nothing of a simulator or of ground truth.
"""

from slamkit.systems.navigation.command import CommandStatus, NavigationCommand, speed_capped
from slamkit.systems.navigation.config import (MOVED_FIELDS, SECTIONS, UNCERTAINTY_MODES, NavigationConfig,
                                               default_controller_params)
from slamkit.systems.navigation.global_planning import GlobalPlanning, GlobalPlanningConfig
from slamkit.systems.navigation.goal import GoalConfig, GoalRegulator
from slamkit.systems.navigation.recovery import Recovery, RecoveryConfig
from slamkit.systems.navigation.safety import SafetyConfig, SafetyGuard
from slamkit.systems.navigation.stack import LAYERS, NavigationStack, layer_timing_summary
from slamkit.systems.navigation.yielding import YieldDecision, Yielding, YieldingConfig, shuttle_centres

#: the former private name (tests and notebooks imported it)
_speed_capped = speed_capped

__all__ = ["CommandStatus", "GlobalPlanning", "GlobalPlanningConfig", "GoalConfig", "GoalRegulator", "LAYERS",
           "MOVED_FIELDS", "NavigationCommand", "NavigationConfig", "NavigationStack", "Recovery",
           "RecoveryConfig", "SECTIONS", "SafetyConfig", "SafetyGuard", "UNCERTAINTY_MODES", "YieldDecision",
           "Yielding", "YieldingConfig", "default_controller_params", "layer_timing_summary", "shuttle_centres",
           "speed_capped"]
