"""Rerun view of global planning: the map, the search growing, the final paths.

Entity tree (2D, world frame, metres; timeline ``iteration``):

* ``world/map``                        occupancy grid (image; black = occupied) or, for a
                                       costmap, the cost as a grey image (static)
* ``world/obstacles/circles|polygons`` obstacles of a continuous world (static)
* ``world/start``, ``world/goal``      (static)
* ``world/search/<planner>/expanded``  grid planners: the cells closed in each batch
                                       (the blueprint shows all batches up to the cursor, so
                                       scrubbing the timeline replays the frontier growing)
* ``world/search/<planner>/tree``      sampling planners: the tree (parent-child segments)
                                       at each snapshot
* ``world/path/<planner>``             the final path
* ``plots/best_cost/<planner>``        sampling planners' best solution cost per iteration

Planners never log: :meth:`PlanRecorder.hook` returns the callable a planner takes as ``hook``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.planning.protocols import Hook, PlanEvent, PlanningProblem, PlanResult
from slamkit.planning.worlds import PointWorld, SE2World
from slamkit.viz.recording import Recording, open_recording

PALETTE = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
           (140, 86, 75), (227, 119, 194), (23, 190, 207)]
TIMELINE = "iteration"


def blueprint() -> rrb.Blueprint:
    history = rrb.VisibleTimeRange(TIMELINE, start=rrb.TimeRangeBoundary.infinite(),
                                   end=rrb.TimeRangeBoundary.cursor_relative(seq=0))
    return rrb.Blueprint(rrb.Horizontal(
        rrb.Spatial2DView(origin="world", name="planning", time_ranges=history),
        rrb.TimeSeriesView(origin="plots", name="best cost"),
        column_shares=[3, 1]))


class PlanRecorder:
    def __init__(self, path: str | Path | None = None, spawn: bool = False,
                 recording: Recording | None = None):
        self.rec = recording or open_recording("slamkit_planning", path, spawn, blueprint())
        self.stream = self.rec.stream
        self._colors: dict[str, tuple[int, int, int]] = {}

    def _color(self, planner: str) -> tuple[int, int, int]:
        if planner not in self._colors:
            self._colors[planner] = PALETTE[len(self._colors) % len(PALETTE)]
        return self._colors[planner]

    # ---------------------------------------------------------------- static scene
    def log_problem(self, problem: PlanningProblem, costmap: np.ndarray | None = None) -> None:
        s = self.stream
        world = problem.world
        grid = world if isinstance(world, OccupancyGrid) else None
        base = world.base if isinstance(world, SE2World) else world
        if isinstance(base, PointWorld):
            grid = base.grid
            if len(base.circles):
                s.log("world/obstacles/circles", rr.Points2D(base.circles[:, :2], radii=base.circles[:, 2],
                                                              colors=[(80, 80, 80)]), static=True)
            if base.polygons:
                s.log("world/obstacles/polygons", rr.LineStrips2D(
                    [np.vstack([p, p[:1]]) for p in base.polygons], colors=[(80, 80, 80)]), static=True)
            lo, hi = base.bounds_m
            s.log("world/bounds", rr.LineStrips2D([[lo, [hi[0], lo[1]], hi, [lo[0], hi[1]], lo]],
                                                  colors=[(180, 180, 180)]), static=True)
        if grid is not None:
            if costmap is not None:
                img = (255 - np.clip(np.asarray(costmap, float), 0, 254)).astype(np.uint8)
            else:
                img = np.where(grid.occupied, 0, 255).astype(np.uint8)
            # image pixel (ix, iy) spans [ix, ix+1) x [iy, iy+1): scale to metres, shift to origin
            s.log("world/map", rr.Transform3D(translation=[*grid.origin_xy_m, 0.0],
                                              scale=grid.resolution_m), static=True)
            s.log("world/map", rr.Image(img, color_model="L"), static=True)
        s.log("world/start", rr.Points2D([problem.start[:2]], radii=[0.3], colors=[(0, 170, 0)],
                                         labels=["start"]), static=True)
        s.log("world/goal", rr.Points2D([problem.goal[:2]], radii=[0.3], colors=[(200, 0, 0)],
                                        labels=["goal"]), static=True)

    # ---------------------------------------------------------------- hook
    def hook(self, planner: str) -> Hook:
        """The ``hook`` to pass to a planner; it logs under ``world/search/<planner>``."""
        color = self._color(planner)
        s = self.stream

        def on_event(event: PlanEvent) -> None:
            s.set_time(TIMELINE, sequence=int(event.iteration))
            if event.kind == "expanded":
                s.log(f"world/search/{planner}/expanded",
                      rr.Points2D(event.points[:, :2], radii=[0.2], colors=[(*color, 120)]))
            elif event.parents is not None:
                pts = event.points[:, :2]
                child = np.flatnonzero(event.parents >= 0)
                segs = np.stack([pts[event.parents[child]], pts[child]], axis=1)
                entity = "roadmap" if event.kind == "roadmap" else "tree"
                s.log(f"world/search/{planner}/{entity}",
                      rr.LineStrips2D(segs, radii=[0.02], colors=[(*color, 110)]) if len(segs)
                      else rr.Points2D(pts, radii=[0.05], colors=[(*color, 160)]))
                if np.isfinite(event.best_cost):
                    s.log(f"plots/best_cost/{planner}", rr.Scalars(float(event.best_cost)))

        return on_event

    def log_result(self, result: PlanResult, planner: str | None = None) -> None:
        name = planner or result.planner
        if result.solved and len(result.path) >= 2:
            self.stream.log(f"world/path/{name}", rr.LineStrips2D([result.path[:, :2]], radii=[0.12],
                                                                  colors=[self._color(name)],
                                                                  labels=[f"{name}: {result.cost:.2f}"]),
                            static=True)

    def close(self) -> Path | None:
        return self.rec.close()


def record_plans(path: str | Path, problem: PlanningProblem, planners: dict[str, object],
                 costmap: np.ndarray | None = None) -> dict[str, PlanResult]:
    """Run each planner (name -> planner whose ``hook`` attribute is set here) on ``problem``
    and write one recording; returns the results."""
    rec = PlanRecorder(path)
    rec.log_problem(problem, costmap)
    results = {}
    for name, planner in planners.items():
        planner.hook = rec.hook(name)
        results[name] = planner.plan(problem)
        rec.log_result(results[name], name)
    rec.close()
    return results
