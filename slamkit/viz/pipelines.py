"""The recorders of the pipeline kinds, registered against their pipelines, and the observer
factory the CLI hands to ``run_pipeline``.

Importing this module registers, in the one pipeline table
(:data:`slamkit.experiments.pipeline.PIPELINES`), the recorder of every built-in pipeline (each
``RecorderClass(path, spawn=False)``; the viz module is imported only when that pipeline
records). A user's own pipeline registers its recorder the same way, with
:func:`~slamkit.experiments.pipeline.register_recorder`.
"""

from __future__ import annotations

from pathlib import Path

from slamkit.experiments.observers import NullObserver, PipelineObserver
from slamkit.experiments.pipeline import recorder_of, register_recorder

register_recorder("pose_graph", "slamkit.viz.pose_graph:PoseGraphPipelineObserver")
register_recorder("pose_graph_outliers", "slamkit.viz.pose_graph_outliers:PoseGraphOutliersObserver")
register_recorder("filter_vs_smoother", "slamkit.viz.filter_vs_smoother:FilterVsSmootherObserver")
register_recorder("local_planning", "slamkit.viz.control:LocalPlanningObserver")
register_recorder("lidar_slam", "slamkit.viz.lidar_slam:LidarSlamObserver")
register_recorder("visual_odometry", "slamkit.viz.visual_odometry:VisualOdometryObserver")
register_recorder("navigation", "slamkit.viz.navigation:NavigationObserver")


def observer_for(kind: str, path: Path, spawn: bool = False) -> PipelineObserver:
    """The recording observer of a pipeline kind (a NullObserver for kinds without one)."""
    factory = recorder_of(kind)
    return NullObserver() if factory is None else factory(path, spawn=spawn)
