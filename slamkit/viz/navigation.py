"""Rerun view of the navigation pipeline: what the stack believes beside what is true.

Entity tree under ``<variant>/<scenario>/`` (2D, world frame, metres; timeline ``sim_time``):

* ``world/map``              occupied cells of the robot's map (static): the world's grid, or the
                             map SLAM built on a mapping tour (``map: {source: slam_tour}``)
* ``world/map_true``         the world's own grid, when the robot's map is another (static)
* ``world/costmap``          the A* costmap (cells the inflated robot may not enter; static)
* ``world/goal``             the goal pose (static)
* ``world/ground_truth``     the true robot disc and heading (scoring only: the stack never sees it)
* ``world/estimate``         the MCL mean, its 3-sigma position ellipse, and ``particles``
* ``world/global_path``      the current A* path
* ``world/candidates``       DWA / rollout candidates (subsample) and ``chosen``; ``mpc_horizon``
* ``world/scan_unexplained`` scan end points the map does not explain
* ``world/tracks``           tracked obstacles (discs, labelled by track id) with velocity arrows and
                             ``trails`` (each live track's estimated positions so far); ``world/obstacles_true``
* ``plots/localisation_error_m``, ``plots/speed_mps``, ``plots/sigma_xy_m``
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from slamkit.experiments.navigation import Episode, NavigationScene, NavigationSnapshot
from slamkit.viz.control import MAX_CANDIDATES, _score_colors
from slamkit.viz.recording import open_recording
from slamkit.viz.views import log_world_y_up, planar_2d_view, series_view


def blueprint(prefixes: list[str], ranges: dict[str, dict[str, tuple[float, float]]] | None = None) -> rrb.Blueprint:
    """Per episode the world (y up) beside two plots: the localisation error with its sigma, and
    the speed (metres and metres per second do not share an axis); ``ranges`` (prefix -> plot ->
    (min, max) plotted) leaves room for the legends above the curves."""
    ranges = ranges or {}
    views = [planar_2d_view(p, p.strip("/")) for p in prefixes]
    plots = []
    for p in prefixes:
        loc, speed = ranges.get(p, {}).get("localisation"), ranges.get(p, {}).get("speed")
        plots.append(series_view(f"{p}plots", f"{p.strip('/')} localisation (m)", loc[1] if loc else None,
                                 contents=["+ $origin/localisation_error_m", "+ $origin/sigma_xy_m"]))
        plots.append(series_view(f"{p}plots", f"{p.strip('/')} speed (m/s)", speed[1] if speed else None,
                                 min(speed[0], 0.0) if speed else 0.0, contents=["+ $origin/speed_mps"]))
    return rrb.Blueprint(rrb.Horizontal(rrb.Grid(*views), rrb.Vertical(*plots), column_shares=[3, 1]),
                         collapse_panels=True)


def ellipse_xy(mean_xy: np.ndarray, cov_xy: np.ndarray, n_sigma: float = 3.0, n: int = 32) -> np.ndarray:
    """(n + 1, 2) closed outline of the n-sigma ellipse of a 2D Gaussian."""
    vals, vecs = np.linalg.eigh(0.5 * (cov_xy + cov_xy.T))
    t = np.linspace(0.0, 2.0 * np.pi, n + 1)
    circle = np.column_stack([np.cos(t), np.sin(t)]) * n_sigma * np.sqrt(np.maximum(vals, 0.0))
    return mean_xy + circle @ vecs.T


def _log_cells(stream, entity: str, grid, mask: np.ndarray, color) -> None:
    """The cells of ``grid`` where ``mask`` holds, as static points of half a cell's radius."""
    iy, ix = np.nonzero(mask)
    stream.log(entity, rr.Points2D(grid.cell_to_world(np.column_stack([ix, iy])), radii=[0.5 * grid.resolution_m],
                                   colors=[color]), static=True)


class NavigationObserver:
    """The ``navigation`` pipeline's recorder (registered in ``slamkit.viz.pipelines``): each step
    snapshot's state is a :class:`~slamkit.experiments.navigation.NavigationSnapshot` (copied
    arrays; the recorder never holds the live stack or plant)."""

    payload_type = list[Episode]
    wants_steps = True
    step_every = 1

    def __init__(self, path: str | Path | None, spawn: bool = False):
        self.rec = open_recording("slamkit_navigation", path, spawn)
        self.stream = self.rec.stream
        self._run: str | None = None
        self._prefixes: list[str] = []
        self._ranges: dict[str, dict[str, tuple[float, float]]] = {}

    def _start(self, prefix: str, scene: NavigationScene) -> None:
        s, g = self.stream, scene.robot_map
        log_world_y_up(s, f"{prefix}world")
        _log_cells(s, f"{prefix}world/map", g, g.occupied, (60, 60, 60))
        truth = scene.true_map
        if truth is not g and (truth.shape != g.shape or not np.array_equal(truth.occupied, g.occupied)):
            _log_cells(s, f"{prefix}world/map_true", truth, truth.occupied, (40, 120, 220, 110))
        _log_cells(s, f"{prefix}world/costmap", g, scene.costmap_blocked, (230, 200, 120, 90))
        goal = scene.goal_xytheta
        s.log(f"{prefix}world/goal", rr.Arrows2D(origins=[goal[:2]], vectors=[0.4 * np.array([np.cos(goal[2]), np.sin(goal[2])])],
                                                 colors=[(0, 160, 0)]), static=True)
        self._track_trails: dict[int, list[np.ndarray]] = {}

    def on_step(self, snapshot) -> None:
        st: NavigationSnapshot = snapshot.state
        if snapshot.run != self._run:
            self._run = snapshot.run
            self._prefixes.append(f"{snapshot.run}/")
            self._start(f"{snapshot.run}/", st.scene)
            # the layout from the first step (a viewer loading the file shows it before the end,
            # where close() sends it again with the plots' ranges)
            self.stream.send_blueprint(blueprint(self._prefixes))
        p, s = f"{snapshot.run}/", self.stream
        s.set_time("sim_time", duration=float(snapshot.stamp_s))
        x = st.true_xytheta
        mean, cov = st.estimate_xytheta, st.covariance
        s.log(f"{p}world/ground_truth", rr.Points2D([x[:2]], radii=[st.scene.robot_radius_m],
                                                    colors=[(30, 90, 220, 120)]))
        s.log(f"{p}world/ground_truth/heading", rr.Arrows2D(origins=[x[:2]], vectors=[0.4 * np.array([np.cos(x[2]), np.sin(x[2])])]))
        s.log(f"{p}world/estimate", rr.Points2D([mean[:2]], radii=[0.03], colors=[(220, 120, 0)]))
        s.log(f"{p}world/estimate/ellipse", rr.LineStrips2D([ellipse_xy(mean[:2], cov[:2, :2])], colors=[(220, 120, 0)]))
        s.log(f"{p}world/estimate/particles", rr.Points2D(st.particles_xytheta[:, :2], radii=[0.005],
                                                          colors=[(220, 120, 0, 120)]))
        if st.path_xy_m is not None:
            s.log(f"{p}world/global_path", rr.LineStrips2D([st.path_xy_m], colors=[(0, 0, 0)], radii=[0.02]))
        if st.candidates_xytheta is not None:
            cand = st.candidates_xytheta
            pick = np.unique(np.linspace(0, len(cand) - 1, min(MAX_CANDIDATES, len(cand))).astype(int))
            s.log(f"{p}world/candidates", rr.LineStrips2D([c[:, :2] for c in cand[pick]],
                                                         colors=_score_colors(st.candidate_scores[pick]), radii=[0.006]))
            if st.chosen >= 0:
                s.log(f"{p}world/candidates/chosen", rr.LineStrips2D([cand[st.chosen, :, :2]], colors=[(0, 200, 0)], radii=[0.03]))
        if st.mpc_horizon_xytheta is not None:
            s.log(f"{p}world/mpc_horizon", rr.LineStrips2D([st.mpc_horizon_xytheta[:, :2]], colors=[(200, 0, 200)], radii=[0.025]))
        s.log(f"{p}world/scan_unexplained", rr.Points2D(st.scan_unexplained_xy_m, radii=[0.02], colors=[(255, 0, 0)]))
        s.log(f"{p}world/tracks", rr.Points2D(st.track_xy_m, radii=st.track_radius_m, colors=[(255, 140, 0, 110)],
                                              labels=[str(i) for i in st.track_ids]))
        s.log(f"{p}world/tracks/velocity", rr.Arrows2D(origins=st.track_xy_m, vectors=st.track_velocity_mps))
        live = {int(i): xy for i, xy in zip(st.track_ids, st.track_xy_m)}
        self._track_trails = {i: self._track_trails.get(i, []) for i in live}  # ended tracks drop out
        for i, xy in live.items():
            self._track_trails[i].append(xy.copy())
        trails = [(i, np.array(t)) for i, t in self._track_trails.items() if len(t) >= 2]
        s.log(f"{p}world/tracks/trails", rr.LineStrips2D([t for _, t in trails], labels=[str(i) for i, _ in trails],
                                                         colors=[(255, 140, 0)], radii=[0.01]))
        if len(st.obstacles_radius_m):
            s.log(f"{p}world/obstacles_true", rr.Points2D(st.obstacles_xy_m, radii=st.obstacles_radius_m,
                                                          colors=[(220, 40, 40, 90)]))
        error_m = float(np.linalg.norm(mean[:2] - x[:2]))
        sigma_m = float(np.sqrt(max(np.linalg.eigvalsh(cov[:2, :2])[-1], 0.0)))
        speed_mps = float(st.command[0])
        s.log(f"{p}plots/localisation_error_m", rr.Scalars(error_m))
        s.log(f"{p}plots/sigma_xy_m", rr.Scalars(sigma_m))
        s.log(f"{p}plots/speed_mps", rr.Scalars(speed_mps))
        ranges = self._ranges.setdefault(p, {})
        for plot, values in (("localisation", (error_m, sigma_m)), ("speed", (speed_mps,))):
            lo, hi = ranges.get(plot, (np.inf, -np.inf))
            ranges[plot] = (min(lo, *values), max(hi, *values))

    def on_output(self, output) -> None:
        pass

    def close(self) -> Path | None:
        if self._prefixes:
            self.stream.send_blueprint(blueprint(self._prefixes, self._ranges))
        return self.rec.close()
