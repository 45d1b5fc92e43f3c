"""Evaluate an estimated trajectory file against a reference file: the library behind
``slamkit eval ate|rpe`` (evo's ``evo_ape`` / ``evo_rpe`` in one function).

This is the one place in ``slamkit.metrics`` that reads files (the edge of the layer); the
metrics themselves work on :class:`~slamkit.data.trajectory.Trajectory` objects.

Formats: ``tum``, ``kitti`` (stamps = line index), ``g2o`` (the vertices of a g2o pose graph,
stamps = vertex ids) or ``auto`` (``.g2o`` suffix -> g2o; a first data line with 12 numbers ->
kitti; otherwise tum). Trajectories are associated by stamp (``max_diff_s``, evo's default
0.01 s) before evaluation.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal


from slamkit.data.formats.g2o import read_g2o
from slamkit.data.formats.kitti import read_kitti
from slamkit.data.formats.tum import read_tum
from slamkit.data.pose_graph import PoseGraph
from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError
from slamkit.metrics.alignment import ALIGN_MODES, AlignMode, associate
from slamkit.metrics.ate import ate
from slamkit.metrics.rpe import DELTA_UNITS, DeltaUnit, rpe
from slamkit.metrics.stats import ErrorStats

TrajectoryFormat = Literal["auto", "tum", "kitti", "g2o"]
FORMATS = ("auto", "tum", "kitti", "g2o")
#: what the headline statistics measure
RELATIONS = ("trans", "angle_deg", "angle_rad")
_UNITS = {"trans": "m", "angle_deg": "deg", "angle_rad": "rad"}


def trajectory_from_pose_graph(graph: PoseGraph) -> Trajectory:
    """The vertices of a pose graph as a trajectory; stamps are the vertex ids."""
    stamps = graph.vertex_ids.astype(float)
    if graph.dim == 2:
        return Trajectory.from_se2(stamps, graph.poses)
    return Trajectory(stamps, graph.poses[:, :3], graph.poses[:, 3:7])


def detect_format(path: str | Path) -> str:
    path = Path(path)
    if path.suffix.lower() == ".g2o":
        return "g2o"
    try:
        with path.open() as handle:
            for line in handle:
                tokens = line.replace(",", " ").split()
                if tokens and not tokens[0].startswith("#"):
                    return "kitti" if len(tokens) == 12 else "tum"
    except (OSError, UnicodeDecodeError):
        pass  # let the reader raise the proper DataError
    return "tum"


def load_trajectory(path: str | Path, fmt: TrajectoryFormat = "auto") -> Trajectory:
    """Read a trajectory file in one of ``FORMATS``."""
    if fmt not in FORMATS:
        raise DataError(f"unknown trajectory format {fmt!r}; use one of {FORMATS}", path)
    if fmt == "auto":
        fmt = detect_format(path)
    if fmt == "tum":
        return read_tum(path)
    if fmt == "kitti":
        return read_kitti(path)
    return trajectory_from_pose_graph(read_g2o(path))


@dataclass(frozen=True)
class EvaluationResult:
    """Headline statistics of one ``eval`` run plus the full metric result in ``detail``."""

    metric: str
    relation: str
    unit: str
    stats: ErrorStats
    num_pairs: int
    align: str
    scale: float
    ref_path: str
    est_path: str
    num_ref_poses: int
    num_est_poses: int
    delta: float | None = None
    delta_unit: str | None = None
    detail: object = None

    def to_dict(self) -> dict:
        """JSON-ready: rmse, mean, median, std, min, max (and sse) at top level."""
        out = {"metric": self.metric, "relation": self.relation, "unit": self.unit}
        out.update({k: v for k, v in self.stats.to_dict().items() if k != "num"})
        out.update({"num_pairs": self.num_pairs, "align": self.align, "scale": self.scale,
                    "ref": self.ref_path, "est": self.est_path,
                    "num_ref_poses": self.num_ref_poses, "num_est_poses": self.num_est_poses})
        if self.metric == "rpe":
            out.update({"delta": self.delta, "delta_unit": self.delta_unit})
        return out


def _pick(result, relation: str) -> ErrorStats:
    return {"trans": result.translation_m, "angle_deg": result.rotation_deg,
            "angle_rad": result.rotation_rad}[relation]


def evaluate_trajectories(ref: Trajectory, est: Trajectory, metric: Literal["ate", "rpe"] = "ate",
                          align: AlignMode = "none", relation: str = "trans", delta: float = 1,
                          delta_unit: DeltaUnit = "frames", all_pairs: bool = False,
                          max_diff_s: float = 0.01, n_first: int | None = None,
                          ref_name: str = "reference", est_name: str = "estimate") -> EvaluationResult:
    """Associate by stamps, align, and compute ATE or RPE."""
    if metric not in ("ate", "rpe"):
        raise DataError(f"unknown metric {metric!r}; use 'ate' or 'rpe'")
    if relation not in RELATIONS:
        raise DataError(f"unknown pose relation {relation!r}; use one of {RELATIONS}")
    if align not in ALIGN_MODES:
        raise DataError(f"unknown alignment {align!r}; use one of {ALIGN_MODES}")
    if delta_unit not in DELTA_UNITS:
        raise DataError(f"unknown delta unit {delta_unit!r}; use one of {DELTA_UNITS}")
    pair = associate(ref, est, max_diff_s)
    if metric == "ate":
        result = ate(pair.ref, pair.est, align, n_first)
        extra = {}
    else:
        result = rpe(pair.ref, pair.est, delta, delta_unit, all_pairs, align, n_first)
        extra = {"delta": float(delta), "delta_unit": delta_unit}
    return EvaluationResult(
        metric=metric, relation=relation, unit=_UNITS[relation], stats=_pick(result, relation),
        num_pairs=result.num_pairs, align=align, scale=float(result.alignment.scale),
        ref_path=ref_name, est_path=est_name, num_ref_poses=len(ref), num_est_poses=len(est),
        detail=result, **extra,
    )


def evaluate_files(ref_path: str | Path, est_path: str | Path, metric: Literal["ate", "rpe"] = "ate",
                   fmt: TrajectoryFormat = "auto", align: AlignMode = "none",
                   relation: str = "trans", delta: float = 1, delta_unit: DeltaUnit = "frames",
                   all_pairs: bool = False, max_diff_s: float = 0.01,
                   n_first: int | None = None, est_fmt: TrajectoryFormat | None = None
                   ) -> EvaluationResult:
    """Read both files (``est_fmt`` defaults to ``fmt``) and evaluate (see the module docstring)."""
    ref = load_trajectory(ref_path, fmt)
    est = load_trajectory(est_path, est_fmt or fmt)
    return evaluate_trajectories(ref, est, metric, align, relation, delta, delta_unit, all_pairs,
                                 max_diff_s, n_first, str(ref_path), str(est_path))
