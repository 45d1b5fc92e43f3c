"""Rerun view of closed-loop local planning: why the robot did what it did.

Entity tree (2D, world frame, metres; timeline ``sim_time``):

* ``world/map``             occupied cells of the static map (static)
* ``world/global_path``     the A* path being tracked (static)
* ``world/goal``            the goal (static)
* ``world/robot``           the robot's disc and heading arrow, per step
* ``world/trail``           the driven trajectory so far
* ``world/obstacles``       the moving circles, per step
* ``world/candidates``      DWA rollouts (a subsample, coloured from red = worst to green = best;
                            inadmissible ones grey)
* ``world/chosen``          the rollout DWA picked
* ``world/mpc_horizon``     the MPC's predicted trajectory
* ``world/mpc_reference``   the reference points it tracks (pushed out of obstacles)
* ``world/forces/...``      potential-field attractive / repulsive / total force arrows
* ``plots/speed_mps``, ``plots/omega_radps``, ``plots/clearance_m``, ``plots/solve_time_ms``

:class:`ClosedLoopRecorder` is an observer for ``slamkit.experiments.closed_loop.run_episode``
(``on_episode`` / ``on_step``); each episode goes under its own prefix
``<controller>/<scenario>/`` so several controllers can be compared in one recording.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from slamkit.experiments.closed_loop import Episode, LocalPlanningSnapshot
from slamkit.viz.recording import Recording, open_recording
from slamkit.viz.views import log_world_y_up, planar_2d_view

MAX_CANDIDATES = 60
GREY = (150, 150, 150, 90)


def blueprint(prefixes: list[str] | None = None) -> rrb.Blueprint:
    prefixes = prefixes or [""]
    views = [planar_2d_view(p, p.strip("/") or "world") for p in prefixes]
    plots = [rrb.TimeSeriesView(origin=f"{p}plots" if p else "plots", name=f"{p}plots") for p in prefixes]
    return rrb.Blueprint(rrb.Horizontal(rrb.Grid(*views), rrb.Vertical(*plots), column_shares=[3, 1]))


def _score_colors(scores: np.ndarray) -> np.ndarray:
    s = np.asarray(scores, dtype=float)
    ok = np.isfinite(s)
    out = np.tile(np.array(GREY, dtype=np.uint8), (len(s), 1))
    if ok.any():
        lo, hi = s[ok].min(), s[ok].max()
        t = (s[ok] - lo) / (hi - lo) if hi > lo else np.ones(ok.sum())
        out[ok] = np.column_stack([255 * (1 - t), 200 * t, np.full(ok.sum(), 40), np.full(ok.sum(), 200)])
    return out


class ClosedLoopRecorder:
    """Observer that logs every closed-loop step into a recording (file and/or viewer)."""

    def __init__(self, path: str | Path | None = None, spawn: bool = False,
                 recording: Recording | None = None, prefixes: list[str] | None = None):
        self.rec = recording or open_recording("slamkit_local_planning", path, spawn,
                                               blueprint(prefixes) if prefixes else None)
        self.stream = self.rec.stream
        self.prefix = ""
        self._trail: list[np.ndarray] = []

    # -- observer protocol
    def on_episode(self, scenario, controller: str) -> None:
        self.prefix = f"{controller}/{scenario.name}/"
        self._trail = []
        s, p = self.stream, self.prefix
        log_world_y_up(s, f"{p}world")
        g = scenario.grid
        iy, ix = np.nonzero(g.occupied)
        cells = g.cell_to_world(np.column_stack([ix, iy]))
        s.log(f"{p}world/map", rr.Boxes2D(centers=cells, sizes=np.full((len(cells), 2), g.resolution_m),
                                           colors=[(60, 60, 60)]), static=True)
        s.log(f"{p}world/global_path", rr.LineStrips2D([scenario.path_xy_m], colors=[(0, 0, 0)],
                                                        radii=[0.02]), static=True)
        s.log(f"{p}world/goal", rr.Points2D([scenario.goal_xy_m], radii=[0.15], colors=[(0, 160, 0)]),
              static=True)

    def on_step(self, snap) -> None:
        s, p = self.stream, self.prefix
        s.set_time("sim_time", duration=float(snap.t_s))
        x = np.asarray(snap.world_xytheta_body)
        self._trail.append(x[:2].copy())
        out = snap.output
        heading = 0.4 * np.array([np.cos(x[2]), np.sin(x[2])])
        s.log(f"{p}world/robot", rr.Points2D([x[:2]], radii=[0.2], colors=[(30, 90, 220, 160)]))
        s.log(f"{p}world/robot/heading", rr.Arrows2D(origins=[x[:2]], vectors=[heading], colors=[(30, 90, 220)]))
        s.log(f"{p}world/trail", rr.LineStrips2D([np.array(self._trail)], colors=[(30, 90, 220)], radii=[0.015]))
        s.log(f"{p}world/obstacles", rr.Points2D(snap.obstacle_xy_m, radii=snap.obstacle_radius_m,
                                                  colors=[(220, 40, 40, 170)]))
        if out.candidates_xytheta is not None and len(out.candidates_xytheta):
            cand = out.candidates_xytheta
            pick = np.unique(np.linspace(0, len(cand) - 1, min(MAX_CANDIDATES, len(cand))).astype(int))
            s.log(f"{p}world/candidates", rr.LineStrips2D([c[:, :2] for c in cand[pick]],
                                                         colors=_score_colors(out.scores[pick]), radii=[0.006]))
            if out.chosen >= 0:
                s.log(f"{p}world/chosen", rr.LineStrips2D([cand[out.chosen, :, :2]], colors=[(0, 200, 0)],
                                                         radii=[0.03]))
        if out.predicted_xytheta is not None:
            s.log(f"{p}world/mpc_horizon", rr.LineStrips2D([out.predicted_xytheta[:, :2]],
                                                           colors=[(200, 0, 200)], radii=[0.025]))
        if "reference_xytheta" in out.info:
            s.log(f"{p}world/mpc_reference", rr.Points2D(np.asarray(out.info["reference_xytheta"])[:, :2],
                                                         radii=[0.03], colors=[(255, 160, 0)]))
        for name, f in out.force_xy.items():
            s.log(f"{p}world/forces/{name}", rr.Arrows2D(origins=[x[:2]], vectors=[np.asarray(f)]))
        s.log(f"{p}plots/speed_mps", rr.Scalars(float(out.command[0])))
        s.log(f"{p}plots/omega_radps", rr.Scalars(float(out.command[1])))
        s.log(f"{p}plots/clearance_m", rr.Scalars(float(snap.clearance_m)))
        s.log(f"{p}plots/solve_time_ms", rr.Scalars(1e3 * float(out.solve_time_s)))

    def close(self) -> Path | None:
        return self.rec.close()


class LocalPlanningObserver:
    """The ``local_planning`` pipeline's recorder (registered in ``slamkit.viz.pipelines``): receives
    ``slamkit.experiments.observers.StepSnapshot``s whose state is a
    :class:`~slamkit.experiments.closed_loop.LocalPlanningSnapshot` (scenario, controller, step), and draws them with :class:`ClosedLoopRecorder`."""

    payload_type = list[Episode]
    wants_steps = True
    step_every = 1  # every closed-loop cycle

    def __init__(self, path: str | Path | None, spawn: bool = False):
        self.recorder = ClosedLoopRecorder(path, spawn)
        self._run: str | None = None
        self._prefixes: list[str] = []

    def on_step(self, snapshot) -> None:
        state: LocalPlanningSnapshot = snapshot.state
        if snapshot.run != self._run:
            self._run = snapshot.run
            self.recorder.on_episode(state.scenario, state.controller)
            self._prefixes.append(self.recorder.prefix)
        self.recorder.on_step(state.step)

    def on_output(self, output) -> None:
        pass

    def close(self) -> None:
        if self._prefixes:
            # the views' origins are only known once the episodes ran
            self.recorder.stream.send_blueprint(blueprint(self._prefixes))
        self.recorder.close()
