"""Pipeline kind -> the observer that records it (handed to ``run_pipeline`` by the CLI)."""

from __future__ import annotations

import importlib
from pathlib import Path

from slamkit.experiments.observers import NullObserver, PipelineObserver

#: pipeline kind -> "module:class" of its recorder; each takes (path, spawn=False)
RECORDERS: dict[str, str] = {
    "pose_graph": "slamkit.viz.pose_graph:PoseGraphPipelineObserver",
    "filter_vs_smoother": "slamkit.viz.filter_vs_smoother:FilterVsSmootherObserver",
    "local_planning": "slamkit.viz.control:LocalPlanningObserver",
    "lidar_slam": "slamkit.viz.lidar_slam:LidarSlamObserver",
}


def observer_for(kind: str, path: Path, spawn: bool = False) -> PipelineObserver:
    """The recording observer of a pipeline kind (a NullObserver for kinds without one)."""
    target = RECORDERS.get(kind)
    if target is None:
        return NullObserver()
    module_name, cls_name = target.split(":")
    return getattr(importlib.import_module(module_name), cls_name)(path, spawn=spawn)
