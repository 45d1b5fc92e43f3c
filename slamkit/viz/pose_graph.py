"""Rerun recordings of pose-graph optimisation.

Entity tree (mirrors the frame tree): ``world/initial`` and ``world/estimate`` trajectories,
``world/loop_closures`` segments, ``world/ground_truth`` when known, ``world/estimate`` again
on the ``iteration`` timeline so the viewer scrubs through the solve, and ``plots/error`` (GTSAM
error per iteration) sent as one column.
"""

from __future__ import annotations

from typing import Sequence as Seq

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from slamkit.data.pose_graph import PoseGraph
from slamkit.experiments.pipeline import PipelineOutput
from slamkit.experiments.pose_graph import OptimizeReport
from slamkit.data.trajectory import Trajectory
from slamkit.viz.recording import OutputRecorder
from slamkit.viz.views import log_metre_axes, scene_bounds, series_view, top_down_view

COLOR_INITIAL = (150, 150, 150)
COLOR_ESTIMATE = (30, 120, 255)
COLOR_GROUND_TRUTH = (40, 200, 80)
COLOR_LOOP = (255, 140, 0)


def world_view(origin: str, name: str, report=None):
    """A 2D graph is seen from straight above with a metre grid (slamkit.viz.views); a 3D one in
    a free 3D view."""
    if report is not None and report.graph.dim == 2:
        lo, hi = scene_bounds(report.result.poses[:, :2], report.result.initial_poses[:, :2])
        return top_down_view(origin, name, lo, hi, grid_spacing_m=grid_spacing_m(hi - lo))
    return rrb.Spatial3DView(origin=origin, name=name)


def grid_spacing_m(extent_xy_m) -> float:
    """1, 10, 100 ... m: about 5-50 grid lines across the larger extent."""
    extent = max(float(np.max(extent_xy_m)), 1.0)
    return float(10.0 ** max(0, np.floor(np.log10(extent / 5.0))))


def _error_max(report) -> float | None:
    errors = np.asarray(report.result.errors if report is not None else (), float)
    errors = errors[np.isfinite(errors)]
    return float(errors.max()) if errors.size else None


def blueprint(report=None) -> rrb.Blueprint:
    return rrb.Blueprint(
        rrb.Horizontal(
            world_view("world", "trajectories", report),
            series_view("plots", "error per iteration", _error_max(report)),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def positions(graph_dim: int, poses: np.ndarray) -> np.ndarray:
    """(N, 3) positions of poses in the PoseGraph layout."""
    poses = np.asarray(poses, dtype=float)
    if graph_dim == 2:
        return np.column_stack([poses[:, 0], poses[:, 1], np.zeros(len(poses))])
    return poses[:, :3]


def log_pose_graph(stream: rr.RecordingStream, graph: PoseGraph, initial_poses: np.ndarray,
                   optimised_poses: np.ndarray, error_per_iteration: Seq[float] = (),
                   poses_per_iteration: Seq[np.ndarray] = (),
                   ground_truth: Trajectory | None = None) -> None:
    p_init = positions(graph.dim, initial_poses)
    p_opt = positions(graph.dim, optimised_poses)
    if graph.dim == 2:
        log_metre_axes(stream, "world/axes", grid_spacing_m(np.ptp(p_opt[:, :2], axis=0)))
    stream.log("world/initial", rr.LineStrips3D([p_init], colors=[COLOR_INITIAL], radii=[0.02]),
               static=True)
    stream.log("world/estimate", rr.LineStrips3D([p_opt], colors=[COLOR_ESTIMATE], radii=[0.03]),
               static=True)
    index = graph.index_of()
    loops = ~graph.is_odometry()
    if loops.any():
        i = np.array([index[int(v)] for v in graph.edge_from[loops]])
        j = np.array([index[int(v)] for v in graph.edge_to[loops]])
        segments = np.stack([p_opt[i], p_opt[j]], axis=1)
        stream.log("world/loop_closures",
                   rr.LineStrips3D(segments, colors=[COLOR_LOOP], radii=[0.01]), static=True)
    if ground_truth is not None:
        stream.log("world/ground_truth",
                   rr.LineStrips3D([ground_truth.world_t_body], colors=[COLOR_GROUND_TRUTH],
                                   radii=[0.02]), static=True)
    for k, poses in enumerate(poses_per_iteration):
        stream.set_time("iteration", sequence=k)
        stream.log("world/iterate", rr.LineStrips3D([positions(graph.dim, poses)],
                                                    colors=[COLOR_ESTIMATE], radii=[0.02]))
    if len(error_per_iteration):
        errors = np.asarray(error_per_iteration, dtype=float)
        stream.send_columns(
            "plots/error",
            indexes=[rr.TimeColumn("iteration", sequence=np.arange(len(errors)))],
            columns=rr.Scalars.columns(scalars=errors),
        )


class _Prefixed:
    """Log into a subtree ``<prefix>/...`` of a recording (one subtree per dataset)."""

    def __init__(self, stream: rr.RecordingStream, prefix: str):
        self._stream, self._prefix = stream, prefix

    def log(self, path: str, *args, **kwargs):
        return self._stream.log(f"{self._prefix}/{path}", *args, **kwargs)

    def send_columns(self, path: str, *args, **kwargs):
        return self._stream.send_columns(f"{self._prefix}/{path}", *args, **kwargs)

    def set_time(self, *args, **kwargs):
        return self._stream.set_time(*args, **kwargs)


def record_optimization(report, path=None, spawn: bool = False) -> None:
    """Record one ``slamkit.experiments.pose_graph.OptimizeReport`` (``slamkit optimize --rrd``)."""
    from slamkit.viz.recording import open_recording

    with open_recording(f"slamkit_optimize_{report.dataset}", path, spawn, blueprint(report)) as rec:
        log_pose_graph(rec.stream, report.graph, report.result.initial_poses, report.result.poses,
                       report.result.errors, report.iterates, report.ground_truth)


class PoseGraphPipelineObserver(OutputRecorder):
    """Records the ``pose_graph`` pipeline: the first run of every dataset under
    ``<dataset>/world/...`` and ``<dataset>/plots/error``."""

    payload_type = list[OptimizeReport]

    def on_output(self, output: PipelineOutput[list[OptimizeReport]]) -> None:
        from slamkit.viz.recording import open_recording

        reports, seen = [], set()
        for r in output.payload or ():
            if r.dataset not in seen:
                seen.add(r.dataset)
                reports.append(r)
        if not reports:
            return
        views = [world_view(f"{r.dataset}/world", r.dataset, r) for r in reports]
        series = [series_view(f"{r.dataset}/plots", f"{r.dataset} error", _error_max(r)) for r in reports]
        bp = rrb.Blueprint(rrb.Vertical(rrb.Grid(*views), rrb.Grid(*series), row_shares=[3, 1]),
                           collapse_panels=True)
        with open_recording("slamkit_pose_graph", self.path, self.spawn, bp) as rec:
            for r in reports:
                log_pose_graph(_Prefixed(rec.stream, r.dataset), r.graph, r.result.initial_poses,
                               r.result.poses, r.result.errors, (), r.ground_truth)
