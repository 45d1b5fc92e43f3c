"""Rerun recordings of filters against smoothers: every estimate over the same ground truth.

Entity tree of one scenario (the pipeline prefixes it with ``<scenario>/``; static data logged
once, time on the ``time`` timeline in seconds):

    world/landmarks                       true landmarks with their ids (static)
    world/ground_truth                    the true path (static)
    world/estimate/<name>                 the estimator's final trajectory (static)
    world/estimate/<name>/covariance      3-sigma position ellipses along it (static, every k-th pose)
    world/estimate/<name>/pose            the estimate at each snapshot (time)
    world/estimate/<name>/ellipse         its 3-sigma position ellipse (time)
    world/estimate/<name>/particles       particles of particle methods (time)
    world/estimate/<name>/landmarks       landmarks a SLAM estimator holds (time)
    world/estimate/<name>/associations    pose -> landmark lines for the observations just used (time)
    world/gps, world/gps_withheld, plots/outage, plots/bias/...   inertial sequences only
                                          (slamkit.viz.inertial)
    plots/error/<name>                    position error (m) of every pose (send_columns)
    plots/nees/<name>                     pose NEES, or its Monte-Carlo average (send_columns)
    plots/nees/band_lower, band_upper     its 95% chi-square band

``FilterVsSmootherObserver`` is the pipeline's recorder (registered in ``slamkit.viz.pipelines``)
and streams: it opens the recording (file and/or ``--spawn`` viewer) when the run starts and logs
every :class:`~slamkit.experiments.observers.BeliefSnapshot` as it arrives, every
``step_every``-th event (the ``time``-timeline entities above: pose, ellipse, particles, held
landmarks, associations), growing the blueprint as scenarios appear. What arrives live is what
the parent process runs: the first seed of every scenario (the pipeline runs the other seeds in
a process pool, and they come back only as finished results). Everything that needs the finished
run -- ground truth, true landmarks, final trajectories with their ellipses, the error and NEES
plots with the Monte-Carlo averages -- is logged when the pipeline's output arrives, and the
file is then complete. Live association lines therefore end where the measurement puts the
landmark (the true map comes with the output) unless the estimator holds that landmark.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from slamkit.data.inertial import is_inertial
from slamkit.experiments.filter_vs_smoother import FilterVsSmootherPayload
from slamkit.experiments.observers import BeliefSnapshot, StepSnapshot
from slamkit.experiments.pipeline import PipelineOutput
from slamkit.viz.inertial import log_inertial
from slamkit.viz.recording import open_recording
from slamkit.viz.views import labels_fit, log_metre_axes, scene_bounds, series_view, top_down_view

APPLICATION_ID = "slamkit_filter_vs_smoother"
TIMELINE = "time"
COLOR_GROUND_TRUTH = (40, 200, 80)
COLOR_LANDMARK = (230, 60, 60)
# grey: the estimators take the palette's colours (orange among them)
COLOR_ASSOCIATION = (120, 120, 120)
COLOR_BAND = (150, 150, 150)
PALETTE = [(30, 120, 255), (255, 127, 14), (148, 103, 189), (214, 39, 40), (23, 190, 207),
           (188, 189, 34), (227, 119, 194), (140, 86, 75), (127, 127, 127)]
#: a covariance ellipse every this many poses along a final trajectory
ELLIPSE_EVERY = 25
#: points per ellipse outline
ELLIPSE_POINTS = 32


def color_of(k: int) -> tuple[int, int, int]:
    return PALETTE[k % len(PALETTE)]


def _xyz(xy: np.ndarray) -> np.ndarray:
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    return np.column_stack([xy, np.zeros(len(xy))])


def ellipse_outlines(centres_xy: np.ndarray, covariances_xy: np.ndarray, n_sigma: float = 3.0,
                     n_points: int = ELLIPSE_POINTS) -> np.ndarray:
    """(K, n_points + 1, 3) closed outlines of the n-sigma ellipses of 2x2 covariances: the
    points c + n_sigma L (cos t, sin t) with L L^T = P (eigen-decomposition, clipped at 0)."""
    P = np.asarray(covariances_xy, dtype=float).reshape(-1, 2, 2)
    w, V = np.linalg.eigh(0.5 * (P + np.swapaxes(P, -1, -2)))
    L = V * np.sqrt(np.clip(w, 0.0, None))[:, None, :]
    t = np.linspace(0.0, 2.0 * np.pi, n_points + 1)
    circle = np.stack([np.cos(t), np.sin(t)])  # (2, n+1)
    pts = np.asarray(centres_xy, dtype=float).reshape(-1, 2)[:, :, None] + n_sigma * (L @ circle)
    pts = np.swapaxes(pts, 1, 2)
    return np.concatenate([pts, np.zeros(pts.shape[:2] + (1,))], axis=2)


def _positions(trajectory) -> np.ndarray:
    """(N, 3) positions to draw: planar trajectories on z = 0, 3D ones as they are."""
    return _xyz(trajectory.xytheta()[:, :2]) if trajectory.planar else np.asarray(trajectory.world_t_body)


def blueprint(prefixes: Iterable[str] = ("",), inertial: Iterable[str] = (),
              fits: Mapping[str, "SceneFit"] | None = None) -> rrb.Blueprint:
    """One spatial view per scenario over an error and a NEES plot; inertial scenarios add a
    bias plot and the GPS outage windows (``slamkit.viz.inertial``). A planar scenario whose
    extent is known (``fits``, from the finished run) is seen from straight above with a metre
    grid, and its plots' legends sit above the curves (``slamkit.viz.views``)."""
    prefixes = list(prefixes)
    inertial = [x for x in prefixes if x in set(inertial)]
    fits = fits or {}

    def p(path: str, prefix: str) -> str:
        return f"{prefix}/{path}" if prefix else path

    def world_view(x: str):
        fit = fits.get(x)
        if fit is None or x in inertial:
            return rrb.Spatial3DView(origin=p("world", x), name=x or "world")
        return top_down_view(p("world", x), x or "world", fit.min_xy, fit.max_xy)

    def fit_of(x: str, what: str) -> float | None:
        return getattr(fits[x], what) if x in fits else None

    views = [world_view(x) for x in prefixes]
    errors = [series_view(p("plots/error", x), f"{x} position error (m)".strip(), fit_of(x, "error_max_m"))
              for x in prefixes]
    nees = [series_view(p("plots/nees", x), f"{x} NEES".strip(), fit_of(x, "nees_max")) for x in prefixes]
    plots = [rrb.Grid(*errors), rrb.Grid(*nees)]
    if inertial:
        plots.append(rrb.Grid(*[rrb.TimeSeriesView(origin=p("plots/bias", x), name=f"{x} IMU biases".strip())
                                for x in inertial],
                              *[rrb.TimeSeriesView(origin=p("plots/outage", x), name=f"{x} GPS outage".strip())
                                for x in inertial]))
    return rrb.Blueprint(
        rrb.Horizontal(rrb.Grid(*views), rrb.Vertical(*plots), column_shares=[3, 2]),
        collapse_panels=True,
    )


@dataclass(frozen=True)
class SceneFit:
    """What a scenario's views are fitted to: its planar extent (m) and its plots' highest values."""

    min_xy: np.ndarray
    max_xy: np.ndarray
    error_max_m: float | None
    nees_max: float | None


def _finite_max(values: Iterable[np.ndarray]) -> float | None:
    finite = [np.asarray(v, float)[np.isfinite(v)] for v in values if v is not None]
    finite = [v for v in finite if v.size]
    return float(max(v.max() for v in finite)) if finite else None


def scene_fit(sequence, runs: Mapping[str, Any], series: Mapping[str, Any] | None = None,
              anees: Mapping[str, Any] | None = None) -> SceneFit:
    """The extent of the ground truth, the true landmarks and every estimate, and the highest
    position error and NEES plotted (the chi-square band included)."""
    series, anees = series or {}, anees or {}
    parts = [np.asarray(list(sequence.world_p_landmarks.values()), float)[:, :2]] if sequence.world_p_landmarks else []
    if sequence.ground_truth is not None and len(sequence.ground_truth):
        parts.append(sequence.ground_truth.xytheta()[:, :2])
    parts += [r.estimate.trajectory.xytheta()[:, :2] for r in runs.values() if r.estimate is not None]
    lo, hi = scene_bounds(*parts)
    nees = [s.nees for s in series.values() if s.nees is not None] + [c.anees for c in anees.values()]
    nees += [np.asarray(c.band, float) for c in anees.values()]
    return SceneFit(lo, hi, _finite_max(s.position_error_m for s in series.values()), _finite_max(nees))


class _Prefixed:
    def __init__(self, stream: rr.RecordingStream, prefix: str):
        self._stream, self._prefix = stream, prefix

    def _p(self, path: str) -> str:
        return f"{self._prefix}/{path}" if self._prefix else path

    def log(self, path: str, *args, **kwargs):
        return self._stream.log(self._p(path), *args, **kwargs)

    def send_columns(self, path: str, *args, **kwargs):
        return self._stream.send_columns(self._p(path), *args, **kwargs)

    def set_time(self, *args, **kwargs):
        return self._stream.set_time(*args, **kwargs)


def log_comparison(stream, sequence, runs: Mapping[str, Any], series: Mapping[str, Any] | None = None,
                   anees: Mapping[str, Any] | None = None, snapshots: Iterable[StepSnapshot] = (),
                   colors: Mapping[str, tuple[int, int, int]] | None = None) -> None:
    """Log one scenario: ground truth, landmarks, every run's estimate (``EstimatorRun``), its
    error and NEES series (``ErrorSeries`` by name), Monte-Carlo NEES curves
    (name -> ``NeesCurve``) and snapshots of the runner (``StepSnapshot[BeliefSnapshot]``).
    ``colors`` (estimator -> RGB) defaults to the palette in the order of ``runs``."""
    series = series or {}
    anees = anees or {}
    colors = dict(colors) if colors is not None else {name: color_of(k) for k, name in enumerate(runs)}
    lms = sequence.world_p_landmarks
    true_lm: dict[int, np.ndarray] = {}
    if lms:
        ids = sorted(lms)
        true_lm = {int(i): np.asarray(lms[i], float)[:2] for i in ids}
        xy = np.array(list(true_lm.values()))
        stream.log("world/landmarks", rr.Points3D(_xyz(xy), radii=[0.12], colors=[COLOR_LANDMARK],
                                                  labels=[str(i) for i in ids], show_labels=labels_fit(xy)),
                   static=True)
    if sequence.ground_truth is not None and len(sequence.ground_truth):
        stream.log("world/ground_truth", rr.LineStrips3D([sequence.ground_truth.world_t_body],
                                                         radii=[0.03], colors=[COLOR_GROUND_TRUTH]),
                   static=True)
    if is_inertial(sequence):
        log_inertial(stream, sequence, runs)
    else:
        log_metre_axes(stream, "world/axes")
    for name, run in runs.items():
        est = run.estimate  # an EstimatorRun (None when it failed)
        if est is None:
            continue
        base = f"world/estimate/{name}"
        xyz = _positions(est.trajectory)
        stream.log(base, rr.LineStrips3D([xyz], radii=[0.025], colors=[colors[name]]),
                   static=True)
        if est.pose_covariances is not None and len(est.pose_covariances) == len(xyz):
            # horizontal (x, y) ellipses at the pose's height; both pose conventions put x, y first
            idx = np.arange(0, len(xyz), ELLIPSE_EVERY)
            outlines = ellipse_outlines(xyz[idx, :2], np.asarray(est.pose_covariances)[idx, :2, :2])
            outlines[..., 2] += xyz[idx, 2][:, None]
            stream.log(f"{base}/covariance", rr.LineStrips3D(outlines, radii=[0.01], colors=[colors[name]]),
                       static=True)
        if est.world_p_landmarks:
            lid = sorted(est.world_p_landmarks)
            held_xy = np.array([np.asarray(est.world_p_landmarks[i], float)[:2] for i in lid])
            stream.log(f"{base}/map", rr.Points3D(_xyz(held_xy), radii=[0.08], colors=[colors[name]],
                                                  labels=[str(i) for i in lid], show_labels=labels_fit(held_xy)),
                       static=True)
    for name in runs:
        # the plots use the estimator's colour of the world view
        for plot in ("error", "nees"):
            stream.log(f"plots/{plot}/{name}", rr.SeriesLines(colors=[colors[name]], names=[name]), static=True)
    for name, s in series.items():
        index = [rr.TimeColumn(TIMELINE, duration=np.asarray(s.stamps_s))]
        stream.send_columns(f"plots/error/{name}", indexes=index,
                            columns=rr.Scalars.columns(scalars=s.position_error_m))
        if s.nees is not None and name not in anees:
            ok = np.isfinite(s.nees)
            if ok.any():
                stream.send_columns(f"plots/nees/{name}",
                                    indexes=[rr.TimeColumn(TIMELINE, duration=np.asarray(s.stamps_s)[ok])],
                                    columns=rr.Scalars.columns(scalars=s.nees[ok]))
    band = None
    for name, curve in anees.items():
        ok = np.isfinite(curve.anees)
        if ok.any():
            stream.send_columns(f"plots/nees/{name}", indexes=[rr.TimeColumn(TIMELINE, duration=curve.stamps_s[ok])],
                                columns=rr.Scalars.columns(scalars=curve.anees[ok]))
            band = (curve.stamps_s[ok], curve.band)
    if band is None and any(s.nees is not None for s in series.values()):
        from slamkit.metrics.consistency import chi2_band

        s0 = next(s for s in series.values() if s.nees is not None)
        b = chi2_band(s0.dof, 1, 0.95)
        band = (np.asarray(s0.stamps_s), (b.lower, b.upper))
    if band is not None:
        stamps, (lo, hi) = band
        index = [rr.TimeColumn(TIMELINE, duration=stamps)]
        for bound in ("lower", "upper"):
            stream.log(f"plots/nees/band_{bound}", rr.SeriesLines(colors=[COLOR_BAND], names=[f"95% band {bound}"]),
                       static=True)
        stream.send_columns("plots/nees/band_lower", indexes=index,
                            columns=rr.Scalars.columns(scalars=np.full(len(stamps), lo)))
        stream.send_columns("plots/nees/band_upper", indexes=index,
                            columns=rr.Scalars.columns(scalars=np.full(len(stamps), hi)))
    for snap in snapshots:
        log_snapshot(stream, snap, colors.get(snap.state.estimator, PALETTE[0]), true_lm)


def log_snapshot(stream, snapshot: StepSnapshot[BeliefSnapshot], color: tuple[int, int, int],
                 true_landmarks: Mapping[int, np.ndarray]) -> None:
    """The belief of one estimator after one event (see ``runner.belief_snapshot``) at its
    stamp. An observed landmark id goes to the landmark the estimator holds, else to the true one
    in ``true_landmarks``, else (unknown id -1, or no map) along the measured ray."""
    belief = snapshot.state
    base = f"world/estimate/{belief.estimator}"
    stream.set_time(TIMELINE, duration=float(snapshot.stamp_s))
    pose = belief.pose.xytheta()[0]
    where = _positions(belief.pose)[:1]
    stream.log(f"{base}/pose", rr.Points3D(where, radii=[0.15], colors=[color]))
    if belief.covariance is not None:
        outline = ellipse_outlines(pose[None, :2], np.asarray(belief.covariance)[None, :2, :2])
        outline[..., 2] += where[0, 2]
        stream.log(f"{base}/ellipse", rr.LineStrips3D(outline, radii=[0.015], colors=[color]))
    if belief.particles is not None:
        stream.log(f"{base}/particles", rr.Points3D(_xyz(np.asarray(belief.particles)[:, :2]),
                                                    radii=[0.03], colors=[color]))
    held: dict[int, np.ndarray] = {}
    if len(belief.landmark_ids):
        held = {int(i): p[:2] for i, p in zip(belief.landmark_ids, belief.world_p_landmarks)}
        stream.log(f"{base}/landmarks", rr.Points3D(_xyz(np.asarray(belief.world_p_landmarks)[:, :2]),
                                                    radii=[0.1], colors=[color]))
    obs = belief.observation
    if obs is not None:
        ids = np.asarray(obs.landmark_ids, dtype=np.int64)
        r, b = np.asarray(obs.range_m, float), np.asarray(obs.bearing_rad, float)
        ends = pose[:2] + np.column_stack([r * np.cos(pose[2] + b), r * np.sin(pose[2] + b)])
        for k, i in enumerate(ids):
            if int(i) in held:
                ends[k] = held[int(i)]
            elif int(i) in true_landmarks:
                ends[k] = true_landmarks[int(i)]
        segments = np.stack([np.repeat(_xyz(pose[:2]), len(ends), axis=0), _xyz(ends)], axis=1)
        stream.log(f"{base}/associations", rr.LineStrips3D(segments, radii=[0.01],
                                                           colors=[COLOR_ASSOCIATION]))


def record_comparison(path: str | Path | None, sequence, runs: Mapping[str, Any],
                      series: Mapping[str, Any] | None = None, snapshots: Iterable[Any] = (),
                      spawn: bool = False) -> Path | None:
    """Record one sequence and its runs (a notebook's ``slamkit.experiments.runner`` output)."""
    fit = None if is_inertial(sequence) else scene_fit(sequence, runs, series)
    with open_recording("slamkit_filter_vs_smoother", path, spawn,
                        blueprint(fits={"": fit} if fit is not None else None)) as rec:
        log_comparison(rec.stream, sequence, runs, series, None, snapshots)
    return None if path is None else Path(path)


class FilterVsSmootherObserver:
    """Records the ``filter_vs_smoother`` pipeline as it runs: ``<scenario>/world/...`` and
    ``<scenario>/plots/...`` (see the module docstring for what streams and what waits for the
    output). The recording opens here, so ``--spawn`` without a viewer fails before the run."""

    payload_type = FilterVsSmootherPayload
    wants_steps = True
    step_every = 10

    def __init__(self, path, spawn: bool = False):
        self.recording = open_recording(APPLICATION_ID, path, spawn)
        self._prefixes: list[str] = []
        self._inertial: set[str] = set()
        self._colors: dict[str, tuple[int, int, int]] = {}
        self._done = False

    def _color(self, estimator: str) -> tuple[int, int, int]:
        """One colour per estimator for the whole recording, in the order they appear."""
        return self._colors.setdefault(estimator, color_of(len(self._colors)))

    def _show(self, scenario: str, inertial: bool = False) -> None:
        if scenario not in self._prefixes or (inertial and scenario not in self._inertial):
            if scenario not in self._prefixes:
                self._prefixes.append(scenario)
            if inertial:
                self._inertial.add(scenario)
            self.recording.stream.send_blueprint(blueprint(self._prefixes, self._inertial))

    def on_step(self, snapshot: StepSnapshot[BeliefSnapshot]) -> None:
        scenario = snapshot.run.split("/", 1)[0]
        self._show(scenario)
        log_snapshot(_Prefixed(self.recording.stream, scenario), snapshot,
                     self._color(snapshot.state.estimator), {})

    def on_output(self, output: PipelineOutput[FilterVsSmootherPayload]) -> None:
        payload = output.payload
        if payload is None:
            return
        for name in payload.estimators:
            self._color(name)
        fits = {}
        for o in payload.scenarios:
            self._show(o.name, is_inertial(o.sequence))
            log_comparison(_Prefixed(self.recording.stream, o.name), o.sequence, o.runs, o.series, o.anees,
                           colors=self._colors)
            fits[o.name] = scene_fit(o.sequence, o.runs, o.series, o.anees)
        self.recording.stream.send_blueprint(blueprint(self._prefixes, self._inertial, fits))
        self.recording.close()
        self._done = True

    def close(self) -> None:
        if not self._done:
            # no output (the run failed): no half recording is left behind
            self.recording.abort()
            self._done = True
