"""The ``pose_graph`` pipeline's report: the table of every combination (with SE-Sync's
published optima beside the certified ones) and the plots."""

from __future__ import annotations

from pathlib import Path

from slamkit.data import registry
from slamkit.errors import ConfigError
from slamkit.experiments.pose_graph.config import PoseGraphPipeline
from slamkit.experiments.pose_graph.optimize import RETRY_INIT, OptimizeReport
from slamkit.experiments.results import markdown_table
from slamkit.paths import file_in


def published_fstar(dataset: str) -> float | None:
    """SE-Sync's published certified optimum f* of a registry dataset (None for files and for
    datasets without one)."""
    try:
        entry = registry.get(dataset)
    except (ConfigError, registry.DatasetNotFoundError):
        return None
    return next((ref.value for ref in entry.references if ref.kind == "sesync_fstar" and ref.published), None)


def _report_markdown(config: PoseGraphPipeline, reports: list[OptimizeReport], skipped: list[str]
                     ) -> str:
    header = ["dataset", "solver", "init", "poses", "initial error", "final error", "SE-Sync F",
              "iterations", "time (s)", "ATE RMSE (m)", "certified", "certified F", "published f*",
              "certified F / f*", "lambda_min", "certify time (s)"]
    rows = []
    for report in reports:
        for r, label in ((report, report.init), (report.retry, f"retry: {RETRY_INIT[report.graph.dim]}")):
            if r is None:
                continue
            c = r.certificate
            fstar = published_fstar(r.dataset)
            rows.append([r.dataset, r.solver, label, r.num_poses, r.initial_error, r.final_error,
                         r.sesync_objective, r.iterations, r.time_total_s, r.ate_rmse_m,
                         "-" if c is None else {"certified": "yes", "not optimal": "NO"}.get(c.verdict, c.verdict),
                         None if c is None else c.objective, fstar,
                         None if c is None or fstar is None else c.objective / fstar,
                         None if c is None else c.min_eigenvalue, None if c is None else c.time_total_s])
    text = f"# Pose-graph optimisation: {config.name or 'pose_graph'}\n\n"
    text += ("Final error is GTSAM's (one half of the weighted squared residuals); SE-Sync F is "
             "Rosen et al.'s objective evaluated on the solution, comparable with published optima. "
             "Certified: SE-Sync's optimality certificate (slamkit.backend.certify) after refining the "
             "solution on F; certified F is that refined optimum, lambda_min the certificate matrix's "
             "smallest eigenvalue (certified when >= -1e-3; 'not verified' when the eigensolver did not "
             "converge, which proves nothing either way). A solution that is not certified is "
             "solved again from chordal (3D) / LAGO (2D) initialisation (rows 'retry'). Published f*: SE-Sync's "
             "certified optimum from the dataset registry (Rosen et al. 2019, 4 significant digits). "
             "`trajectories/` holds each solution (`<dataset>_<solver>_<init>.g2o`, `.tum`) and, where "
             "a certificate was computed, the refined poses it is about (`..._refined.g2o`, `.tum`).\n\n")
    text += markdown_table(header, rows) + "\n"
    notes = [f"- {r.dataset} ({r.solver}/{r.init}): {w}" for r in reports for w in r.warnings]
    notes += [f"- {r.dataset} ({r.solver}/{r.init}): not certified: {r.certify_skipped}"
              for r in reports if r.certify_skipped]
    if skipped:
        notes.insert(0, f"- {len(skipped)} dataset x solver x init combinations do not apply and were "
                        f"skipped (LAGO is for 2D graphs, chordal for 3D ones), e.g. {skipped[0]}")
    if notes:
        text += "\n## Notes\n\n" + "\n".join(notes) + "\n"
    return text


def _plot(plots: Path, reports: list[OptimizeReport]) -> None:
    if not reports:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = [f"{r.dataset}\n{r.solver}/{r.init}" for r in reports]
    fig, axes = plt.subplots(1, 2, figsize=(max(8, 0.9 * len(reports) + 4), 4.5))
    axes[0].bar(labels, [max(r.final_error, 1e-12) for r in reports], color="tab:blue")
    axes[0].set_yscale("log")
    axes[0].set_ylabel("final GTSAM error")
    axes[1].bar(labels, [r.time_total_s for r in reports], color="tab:orange")
    axes[1].set_ylabel("time (s), load + build + solve")
    for ax in axes:
        ax.tick_params(axis="x", labelrotation=60, labelsize=7)
    fig.tight_layout()
    fig.savefig(plots / "final_error_and_time.png", dpi=120)
    plt.close(fig)
    seen: set[str] = set()
    for r in reports:
        if r.dataset in seen:
            continue
        seen.add(r.dataset)
        fig, ax = plt.subplots(figsize=(6, 6))
        p0, p1 = r.result.initial_poses, r.result.poses
        ax.plot(p0[:, 0], p0[:, 1], color="0.6", lw=0.6, label="initial")
        if r.ground_truth is not None:
            gt = r.ground_truth.world_t_body
            ax.plot(gt[:, 0], gt[:, 1], color="tab:green", lw=0.8, label="ground truth")
        ax.plot(p1[:, 0], p1[:, 1], color="tab:blue", lw=0.8, label=f"{r.solver}/{r.init}")
        ax.set_aspect("equal")
        ax.set_title(r.dataset)
        ax.legend(loc="best", fontsize=8)
        fig.tight_layout()
        fig.savefig(file_in(plots, f"trajectory_{r.dataset}", ".png", "dataset name"), dpi=110)
        plt.close(fig)
