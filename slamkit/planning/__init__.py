"""Global planning: grid search and sampling-based planners behind one contract.

``planner.plan(PlanningProblem(world, start, goal)) -> PlanResult`` (see :mod:`.protocols`).

Grid (OccupancyGrid, optional per-cell cost multipliers from a costmap): ``astar``,
``dijkstra`` (compiled C core with a pure-Python fallback, :mod:`.grid_search`), ``dstar_lite``
(incremental). Sampling (:class:`.worlds.PointWorld` with circles/polygons/grid, or
:class:`.worlds.SE2World` for a rigid polygonal body): ``prm``, ``rrt``, ``rrt_connect``,
``rrt_star``, ``informed_rrt_star``. Build any of them by name with
:func:`.registry.make_planner`; post-process paths with :mod:`.postprocess`;
``slamkit bench planning`` runs :mod:`slamkit.bench.planning`. Along a fixed path, the speed against moving
obstacles: :func:`.speed_profile.plan_speed_along_path` (the navigation stack's yielding uses it).
"""

from slamkit.planning.protocols import (PlanEvent, Planner, PlanningProblem, PlanResult, PlanStats,
                                        PlanStatus)
from slamkit.planning.registry import make_planner, planner_names

__all__ = ["PlanEvent", "Planner", "PlanningProblem", "PlanResult", "PlanStats", "PlanStatus",
           "make_planner", "planner_names"]
