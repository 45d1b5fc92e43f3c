"""One pose graph through the back-end, scored: the library behind ``slamkit optimize`` and each
combination of the ``pose_graph`` pipeline.

``optimize_source`` loads a registry name or a file, solves it with the back-end, scores it
(GTSAM error, chi2, the SE-Sync objective F so it compares with published optima, ATE against
ground truth when there is one), certifies it with SE-Sync's certificate when asked (retrying
from chordal / LAGO initialisation when it is not certified) and optionally writes a result
folder; ``slamkit.viz.pose_graph`` records it.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from slamkit.backend.certify import Certificate, CertifyConfig, certify
from slamkit.backend.objective import sesync_objective
from slamkit.backend.solvers import OptimizeConfig, OptimizeResult, optimize
from slamkit.data import registry
from slamkit.data.formats.g2o import write_g2o
from slamkit.data.formats.tum import write_tum
from slamkit.data.pose_graph import PoseGraph
from slamkit.data.trajectory import Trajectory
from slamkit.paths import file_in
from slamkit.errors import BackendError, ConfigError
from slamkit.experiments.results import ResultsFolder, check_output_folder, check_replace
from slamkit.metrics.evaluate import trajectory_from_pose_graph
from slamkit.metrics.trajectory_score import ate_paired_by_stamp


@dataclass(frozen=True)
class OptimizeReport:
    """Everything ``slamkit optimize --json`` prints, plus the arrays behind it."""

    dataset: str
    num_poses: int
    num_factors: int
    solver: str
    init: str
    robust: str
    initial_error: float
    final_error: float
    chi2: float
    sesync_objective: float
    iterations: int
    converged: bool
    time_load_s: float
    time_init_s: float
    time_solve_s: float
    time_total_s: float
    ate_rmse_m: float | None = None
    ate_align: str | None = None
    linear_solver: str = "cholesky"
    warnings: tuple[str, ...] = ()
    #: SE-Sync certificate of the solution (None when not certified: off, robust, too large)
    certificate: Certificate | None = field(default=None, repr=False)
    #: why no certificate was computed, when none was
    certify_skipped: str | None = None
    #: the re-solve from chordal (3D) / LAGO (2D) initialisation after a failed certificate
    retry: "OptimizeReport | None" = field(default=None, repr=False)
    #: what ``optimize_source(out=...)`` wrote: which poses -> files relative to the out folder
    #: (``solution``: the solver's; ``refined``: the poses the certificate is about; ``retry_*``)
    written: Mapping[str, list[str]] = field(default_factory=dict)
    graph: PoseGraph | None = field(default=None, repr=False)
    result: OptimizeResult | None = field(default=None, repr=False)
    ground_truth: Trajectory | None = field(default=None, repr=False)
    iterates: tuple[np.ndarray, ...] = field(default=(), repr=False)

    @property
    def certified(self) -> bool | None:
        return None if self.certificate is None else self.certificate.certified

    def summary(self) -> dict[str, Any]:
        """The JSON-ready numbers (no arrays); ``certificate`` and ``retry`` nested."""
        d = {k: getattr(self, k) for k in self.__dataclass_fields__
             if k not in ("graph", "result", "ground_truth", "iterates", "certificate", "retry")}
        d["warnings"] = list(self.warnings)
        d["written"] = {k: list(v) for k, v in self.written.items()}
        d["certified"] = self.certified
        d["certificate_verdict"] = None if self.certificate is None else self.certificate.verdict
        d["certificate"] = None if self.certificate is None else self.certificate.summary()
        d["retry"] = None if self.retry is None else self.retry.summary()
        return d

    def certificate_metrics(self) -> dict[str, float]:
        """The certificate's numbers as flat metrics (empty without a certificate)."""
        c = self.certificate
        if c is None:
            return {}
        return {"certified": float(c.certified), "certificate_min_eigenvalue": c.min_eigenvalue,
                "sesync_objective_refined": c.objective, "suboptimality_bound": c.suboptimality_bound,
                "time_certify_s": c.time_total_s, "time_certify_eig_s": c.time_eig_s}

    def estimate_trajectory(self) -> Trajectory:
        return trajectory_from_pose_graph(_with_poses(self.graph, self.result.poses))


def _with_poses(graph: PoseGraph, poses: np.ndarray) -> PoseGraph:
    return replace(graph, poses=poses, has_initial=True)


#: ``certify="auto"`` certifies graphs with at most this many rotation unknowns (d x poses):
#: every shared graph (ais2klinik, the largest, has 30,230); certification then costs about as
#: much as the solve (city10000: 1.3 s eigensolver vs 1.3 s LM)
CERTIFY_AUTO_MAX_UNKNOWNS = 40_000
CERTIFY_MODES = ("auto", "on", "off")
#: the initialisation a failed certificate is retried from, per dimension
RETRY_INIT = {2: "lago", 3: "chordal"}


def certify_decision(mode: str, graph: PoseGraph, config: OptimizeConfig) -> str | None:
    """None when ``graph`` solved with ``config`` should be certified under ``mode``, else why not."""
    if mode not in CERTIFY_MODES:
        raise ConfigError(f"certify must be one of {CERTIFY_MODES}, got {mode!r}")
    if mode == "off":
        return "certification off"
    if mode == "on":
        return None
    if config.robust != "none":
        return f"robust kernel {config.robust!r}: the certificate is for the least-squares objective"
    if graph.dim * graph.num_poses > CERTIFY_AUTO_MAX_UNKNOWNS:
        return (f"{graph.dim * graph.num_poses} rotation unknowns > {CERTIFY_AUTO_MAX_UNKNOWNS} "
                "(certify='on' forces it)")
    return None


def optimize_source(source: str | Path, config: OptimizeConfig = OptimizeConfig(),
                    out: str | Path | None = None, keep_iterates: bool = False,
                    certify_mode: str = "auto", retry_uncertified: bool = True, overwrite: bool = False
                    ) -> OptimizeReport:
    """Load ``source`` (registry name or path), optimise it, score it, optionally write ``out``
    (optimised g2o + TUM trajectory, config.yaml, metrics.json). ``keep_iterates`` keeps the
    poses after every iteration in ``report.iterates`` (for recordings).

    ``certify_mode`` (auto | on | off; see ``certify_decision``) attaches an SE-Sync certificate
    (``slamkit.backend.certify``). When the solution is not certified and ``retry_uncertified``,
    the graph is solved again from chordal (3D) or LAGO (2D) initialisation, certified too, and
    reported in ``retry`` (unless that was already the initialisation). An earlier optimize
    result at ``out`` is replaced only with ``overwrite``; that is checked before solving."""
    if out is not None:
        check_replace(check_output_folder(out), "optimize", overwrite)
    t0 = time.perf_counter()
    graph, entry = registry.load_pose_graph_source(source)
    note = registry.resolution_note(source)
    ground_truth = registry.ground_truth(entry.name) if entry is not None else None
    time_load_s = time.perf_counter() - t0
    report = _solve_and_score(graph, entry, ground_truth, config, keep_iterates, note, t0,
                              time_load_s, certify_mode)
    retry_init = RETRY_INIT[graph.dim]
    if (retry_uncertified and report.certified is False and report.init != retry_init
            and config.init != retry_init):
        retry = _solve_and_score(graph, entry, ground_truth, replace(config, init=retry_init), False,
                                 None, time.perf_counter(), 0.0, "on")
        report = replace(report, retry=retry)
    if out is not None:
        with ResultsFolder(out, pipeline="optimize", overwrite=overwrite) as folder:
            folder.write_config({"source": str(source), "certify": certify_mode, **asdict(config)})
            written = write_outputs(folder.trajectories, report)
            if report.retry is not None:
                retry_written = write_outputs(folder.trajectories, report.retry,
                                              f"{report.dataset}_retry_{report.retry.init}")
                written.update({f"retry_{k}": v for k, v in retry_written.items()})
            relative = {k: [f"{folder.trajectories.name}/{name}" for name in v] for k, v in written.items()}
            report = replace(report, written=relative)
            folder.write_json("metrics.json", report.summary())
            folder.finalize("optimize")
    return report


def _solve_and_score(graph, entry, ground_truth, config, keep_iterates, note, t0, time_load_s,
                     certify_mode) -> OptimizeReport:

    iterates: list[np.ndarray] = []
    hook = (lambda it, err, poses: iterates.append(poses)) if keep_iterates else None
    result = optimize(graph, config, on_iteration=hook)
    time_total_s = time.perf_counter() - t0

    report = OptimizeReport(
        dataset=entry.name if entry is not None else graph.name,
        num_poses=graph.num_poses, num_factors=result.num_factors, solver=result.solver,
        init=result.init, robust=config.robust, initial_error=result.initial_error,
        final_error=result.final_error, chi2=result.chi2,
        sesync_objective=float(sesync_objective(graph, result.poses)),
        iterations=result.iterations, converged=result.converged, time_load_s=time_load_s,
        time_init_s=result.time_init_s, time_solve_s=result.time_solve_s,
        time_total_s=time_total_s, linear_solver=result.linear_solver, warnings=((note,) if note else ()) + tuple(result.warnings),
        graph=graph, result=result, ground_truth=ground_truth, iterates=tuple(iterates),
    )
    if ground_truth is not None:
        rmse, mode = ate_paired_by_stamp(ground_truth, report.estimate_trajectory())
        report = replace(report, ate_rmse_m=rmse, ate_align=mode)
    skipped = certify_decision(certify_mode, graph, config)
    if skipped is None:
        try:
            report = replace(report, certificate=certify(graph, result.poses, CertifyConfig()))
        except BackendError as exc:  # e.g. no translation information: F has no unique optimum
            report = replace(report, certify_skipped=f"certificate unavailable: {exc}")
    else:
        report = replace(report, certify_skipped=skipped)
    return report


def write_outputs(trajectories: Path, report: OptimizeReport, stem: str | None = None) -> dict[str, list[str]]:
    """The optimised graph (g2o) and its trajectory (TUM, stamps = vertex ids) as ``<stem>.*``,
    and, when a certificate refined the solution, the poses the certificate is about as
    ``<stem>_refined.*`` (they differ: the solver minimises GTSAM's error, the certificate speaks
    about SE-Sync's F). Returns which poses went to which file names."""
    stem = stem or report.dataset
    written = {}
    poses = {"solution": report.result.poses}
    if report.certificate is not None and report.certificate.solution == "refined":
        poses["refined"] = report.certificate.poses
    for label, values in poses.items():
        name = stem if label == "solution" else f"{stem}_{label}"
        graph = _with_poses(report.graph, values)
        g2o = file_in(trajectories, name, ".g2o", "dataset name")
        tum = file_in(trajectories, name, ".tum", "dataset name")
        write_g2o(g2o, graph)
        write_tum(tum, trajectory_from_pose_graph(graph))
        written[label] = [g2o.name, tum.name]
    return written
