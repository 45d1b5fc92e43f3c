"""``filter_vs_smoother`` reports: the Markdown tables of ``report.md`` and the matplotlib
figures of ``plots/`` (error over time with 3-sigma bounds, average NEES with its band, ATE
with its confidence interval)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from slamkit.experiments.filter_vs_smoother.config import NAME, FilterVsSmootherPipeline, ScenarioSpec, params_changed
from slamkit.experiments.filter_vs_smoother.monte_carlo import SETTINGS, TaskResult
from slamkit.experiments.filter_vs_smoother.score import FilterVsSmootherPayload, ScenarioOutcome
from slamkit.experiments.results import markdown_table, paired_markdown, summary_markdown
from slamkit.paths import file_in


def report_markdown(config: FilterVsSmootherPipeline, summary: list[dict[str, Any]], consistency: list[dict],
                    scenarios: list[ScenarioSpec], references: Mapping[str, str], notes: list[str],
                    results: list[TaskResult], paired: list[dict[str, Any]] | None = None) -> str:
    """``report.md``: scenarios, the metric summary, the paired comparisons, the consistency
    table and the notes."""
    seeds = {s.name: sum(1 for r in results if r.scenario == s.name) for s in scenarios}
    setting = {(rec.dataset, rec.estimator): rec.params.get("setting") for r in results for rec in r.records}
    text = f"# Filters against smoothers: {config.name or NAME}\n\n"
    text += ("Every estimator sees the same sequence. Cells are the mean over runs ± the half width "
             "of the 95% Student-t confidence interval. ATE and RPE after SE(2) (planar) or SE(3) (3D) alignment; NEES "
             "from the unaligned pose error and the estimator's own covariance (filters: filtered, "
             "smoothers: final marginals); latencies per `step` call.\n\n")
    lines = []
    for s in scenarios:
        what = (f"simulated preset `{s.preset}`" if s.preset else f"scenario `{s.scenario}`" if s.scenario
                else f"dataset `{s.dataset}`")
        params = ", ".join(f"{k}={v}" for k, v in params_changed(s).items())
        lines.append(f"- **{s.name}**: {what}{' (' + params + ')' if params else ''}, {seeds[s.name]} run(s), "
                     f"reference: {references.get(s.name, 'none')}")
        if "range_scale" in s.params:
            lines[-1] += "; " + range_scale_mode(s.params["range_scale"])
    text += headline_markdown(summary, consistency, setting)
    text += "## Scenarios\n\n" + "\n".join(lines) + "\n\n"
    text += "## Metrics\n\n" + by_setting(summary, setting, summary_markdown)
    paired = [r for r in paired or () if r["metric"] in PAIRED_REPORT_METRICS]
    if paired:
        text += ("## Paired differences to the best estimator\n\n"
                 "Every estimator saw the same data and seed as the best one (best mean of the metric), so "
                 "each run gives one paired difference (estimator - best): its mean with the 95% Student-t "
                 "interval and the two-sided Wilcoxon signed-rank p-value; significant at p < 0.05 (with "
                 "fewer than 6 runs the exact test cannot reach it). Overlapping intervals of the unpaired "
                 "means above do not decide a winner; these do. Accuracy and step latency here, every "
                 "ranked metric in `results.json` (`paired`).\n\n"
                 + by_setting(paired, lambda r: r.get("setting"), lambda rows: paired_markdown(rows, ["dataset"])))
    if consistency:
        text += ("## Consistency (pose NEES, d = 3 dof planar, 6 dof 3D)\n\n"
                 "Average NEES over the M runs at every step; a consistent estimator keeps its time "
                 "mean inside the two-sided 95% band of chi2(dM)/M (Bar-Shalom et al. 2001, sec. "
                 "5.4), and about 95% of the steps inside it. A recorded dataset is one run (M = 1): "
                 "its NEES is that run's against the ground truth and the band chi2(d)/1, not a "
                 "Monte-Carlo average.\n\n")
        text += by_setting(consistency, setting, consistency_markdown)
    text += inertial_markdown(summary)
    text += outside_references_markdown([r.model_dump() for r in config.outside_references], summary)
    failed = [(rec.dataset, rec.estimator, rec.seed, rec.params.get("failed"))
              for r in results for rec in r.records if rec.params.get("failed")]
    if failed:
        notes = notes + [f"{d} / {e} / seed {s}: {msg}" for d, e, s, msg in failed]
    if notes:
        text += "## Notes\n\n" + "\n".join(f"- {n}" for n in notes[:50]) + "\n"
    return text


#: the columns a reader compares first: (summary metric, column title, digits)
HEADLINE_METRICS = (("ate_rmse_m", "ATE RMSE (m)", 3), ("rpe_rmse_m", "RPE RMSE (m)", 3),
                    ("step_latency_median_ms", "latency median (ms)", 3))
SETTING_SHORT = {"localisation": "map known", "pose_only": "pose only", "slam": "map estimated"}


def headline_markdown(summary: list[dict[str, Any]], consistency: list[dict[str, Any]],
                      setting: Mapping[tuple[str, str], str | None]) -> str:
    """The headline table: per scenario and estimator, what it was given (map known, pose only,
    map estimated), ATE and RPE (mean ± 95% CI half width), the NEES verdict and the median step
    latency; the full tables follow under Metrics. Rows are grouped by setting so an estimator
    given the map is never read as beating one that estimates it."""
    cells: dict[tuple[str, str], dict[str, str]] = {}
    for row in summary:
        metric = next((m for m in HEADLINE_METRICS if m[0] == row["metric"]), None)
        if metric is None or row.get("mean") is None:
            continue
        half = None if row.get("ci95") is None or row["ci95"][0] is None else 0.5 * (row["ci95"][1] - row["ci95"][0])
        value = f"{row['mean']:.{metric[2]}g}" + (f" ± {half:.2g}" if half is not None and row.get("n", 1) > 1 else "")
        cells.setdefault((row["dataset"], row["estimator"]), {})[metric[0]] = value
    verdict = {(r["dataset"], r["estimator"]): r["verdict"] for r in consistency}
    if not cells:
        return ""
    order = {key: k for k, key in enumerate([*SETTINGS, None])}
    keys = sorted(cells, key=lambda k: (k[0], order.get(setting.get(k), len(order))))
    table = [[d, e, SETTING_SHORT.get(setting.get((d, e)), "")] + [cells[(d, e)].get(m[0], "") for m in HEADLINE_METRICS[:2]]
             + [verdict.get((d, e), "")] + [cells[(d, e)].get(HEADLINE_METRICS[2][0], "")] for d, e in keys]
    return ("## Headline\n\nThe columns to compare; every metric with its interval is under Metrics, the "
            "paired tests and the consistency bands after it. NEES verdict: the time mean of the "
            "average NEES inside, above (overconfident) or below (underconfident) its 95% chi-square band.\n\n"
            + markdown_table(["scenario", "estimator", "given", *[m[1] for m in HEADLINE_METRICS[:2]], "NEES verdict",
                              HEADLINE_METRICS[2][1]], table) + "\n\n")


def range_scale_mode(range_scale: Any) -> str:
    """How a range-only dataset's range scale was handled (the report says which mode ran)."""
    if range_scale == "estimate":
        return ("range scale **estimated** by every range-only estimator (prior N(1, 0.1^2), no "
                "ground truth; column `range_scale`)")
    return (f"ranges divided by range_scale = {range_scale} (**calibrated** mode: a scale fitted "
            f"against the ground truth of the run being scored, when not 1)")


def by_setting(rows: list[dict[str, Any]], setting, render) -> str:
    """``render(rows)`` once per setting (localisation, then SLAM, then rows without one), each
    under its own heading, so no table puts an estimator given the map beside one estimating
    it. ``setting`` maps (dataset, estimator) to the setting, or is a function of the row."""
    def of(row):
        return setting(row) if callable(setting) else setting.get((row["dataset"], row["estimator"]))

    text = ""
    for key, title in [*SETTINGS.items(), (None, None)]:
        part = [r for r in rows if of(r) == key]
        if part:
            text += (f"### {title[0].upper() + title[1:]}\n\n" if title and len(part) < len(rows) else "") \
                + render(part) + "\n\n"
    return text


def consistency_markdown(consistency: list[dict[str, Any]]) -> str:
    table = [[r["dataset"], r["estimator"], r["runs"] if r["runs"] > 1 else "1 (one run, no Monte Carlo)", r["anees_mean"],
              f"[{r['band95'][0]:.3g}, {r['band95'][1]:.3g}]",
              r["verdict"] if r["verdict"] == "inside" else f"**{r['verdict']}**",
              r["steps_in_band_fraction"], r["degenerate_fraction"]] for r in consistency]
    return markdown_table(["scenario", "estimator", "runs M", "mean NEES", "95% band", "verdict",
                           "steps in band", "degenerate steps"], table)


#: the metrics whose paired comparisons ``report.md`` shows (results.json has every ranked one)
PAIRED_REPORT_METRICS = ("ate_rmse_m", "ate_rot_rmse_rad", "rpe_rmse_m", "landmark_rmse_m", "step_latency_median_ms")


def outside_references_markdown(references: list[Mapping[str, Any]], summary: list[dict[str, Any]]) -> str:
    """The config's ``outside_references`` (figures measured elsewhere on the same setting), each
    beside slamkit's mean and 95% CI of the same scenario and metric."""
    rows = []
    for ref in references:
        for s in summary:
            if (s["dataset"] == ref["scenario"] and s["metric"] == ref["metric"] and s["mean"] is not None
                    and (not ref.get("estimators") or s["estimator"] in ref["estimators"])):
                ci = s.get("ci95") or [None, None]
                rows.append([ref["scenario"], ref["metric"], ref["source"], ref["value"], s["estimator"], s["mean"],
                             "" if ci[0] is None else f"[{ci[0]:.4g}, {ci[1]:.4g}]", s["mean"] / ref["value"]
                             if ref["value"] else None])
    if not rows:
        return ""
    return ("## Beside outside references\n\nFigures measured elsewhere on the same setting (the config's "
            "`outside_references`), each beside slamkit's mean over the runs; ratio = slamkit / reference.\n\n"
            + markdown_table(["scenario", "metric", "reference", "value", "slamkit estimator", "slamkit mean",
                              "95% CI", "ratio"], rows) + "\n\n")


#: the inertial metrics (slamkit.metrics.inertial) the report tabulates on their own
OUTAGE_METRICS = ("outage_windows", "outage_rmse_m", "outage_end_error_mean_m", "outage_max_error_m")
BIAS_METRICS = ("accel_bias_rmse_mps2", "gyro_bias_rmse_radps", "bias_within_3sigma_fraction")


def inertial_markdown(summary: list[dict[str, Any]]) -> str:
    """The GPS-outage and bias tables of inertial scenarios (empty when there are none)."""
    text = ""
    for title, intro, metrics in (
            ("GPS outages", "Position error at the GPS fixes withheld in outage windows (estimate "
             "interpolated to each fix; filters online, smoothers their final estimate).", OUTAGE_METRICS),
            ("IMU biases", "Bias error against the simulator's truth (RMS over the second half) and the "
             "fraction of bias components inside their 3-sigma bounds.", BIAS_METRICS)):
        cells: dict[tuple[str, str], dict[str, Any]] = {}
        for r in summary:
            if r["metric"] in metrics:
                cells.setdefault((r["dataset"], r["estimator"]), {})[r["metric"]] = r["mean"]
        if not cells:
            continue
        rows = [[d, e] + [v.get(m) for m in metrics] for (d, e), v in cells.items()]
        text += f"## {title}\n\n{intro}\n\n" + markdown_table(["scenario", "estimator", *metrics], rows) + "\n\n"
    return text


# plots


def plot_all(plots: Path, payload: FilterVsSmootherPayload, summary: list[dict[str, Any]],
             setting: Mapping[tuple[str, str], str | None] | None = None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for outcome in payload.scenarios:
        if outcome.series:
            fig = plot_errors(outcome, plt)
            fig.savefig(file_in(plots, f"error_{outcome.name}", ".png", "scenario name"), dpi=100)
            plt.close(fig)
        if any(_lidar_updates(run) is not None for run in outcome.runs.values()):
            fig = plot_error_norms(outcome, plt)
            fig.savefig(file_in(plots, f"error_norm_{outcome.name}", ".png", "scenario name"), dpi=100)
            plt.close(fig)
        if outcome.anees:
            fig = plot_nees(outcome, plt)
            fig.savefig(file_in(plots, f"nees_{outcome.name}", ".png", "scenario name"), dpi=100)
            plt.close(fig)
    fig = plot_ate(summary, plt, setting or {})
    if fig is not None:
        fig.savefig(plots / "ate_rmse.png", dpi=100)
        plt.close(fig)


def plot_errors(outcome: ScenarioOutcome, plt):
    """x, y, heading error of the first run of every estimator with its +-3 sigma bounds (for
    3D estimates the x, y, z position error)."""
    names = list(outcome.series)
    fig, axes = plt.subplots(len(names), 3, figsize=(12, 2.0 * len(names) + 0.8), squeeze=False,
                             sharex=True)
    planar = all(outcome.series[n].dof == 3 for n in names)
    labels = ("x error (m)", "y error (m)", "heading error (rad)" if planar else "z error (m)")
    for row, name in enumerate(names):
        s = outcome.series[name]
        for col in range(3):
            ax = axes[row, col]
            ax.plot(s.stamps_s, s.error[:, col], lw=0.8, color="tab:blue")
            if s.sigma is not None:
                b = 3.0 * s.sigma[:, col]
                ax.fill_between(s.stamps_s, -b, b, color="tab:orange", alpha=0.25, lw=0)
            ax.axhline(0.0, color="0.5", lw=0.5)
            if row == 0:
                ax.set_title(labels[col], fontsize=9)
            if col == 0:
                ax.set_ylabel(name, fontsize=9)
    for col in range(3):
        axes[-1, col].set_xlabel("time (s)")
    fig.suptitle(f"{outcome.name}: error and ±3σ bounds (first run)", fontsize=10)
    fig.tight_layout()
    return fig


def _lidar_updates(run) -> np.ndarray | None:
    """The stamps of a run's lidar updates (filters that report ``lidar_update_stamps_s``)."""
    if run is None or run.estimate is None:
        return None
    stamps = run.estimate.extras.get("lidar_update_stamps_s")
    return None if stamps is None else np.asarray(stamps, dtype=float)


def plot_error_norms(outcome: ScenarioOutcome, plt):
    """Position and heading error over time of every estimator (log scale, first run), the lidar
    updates of each marked as ticks under the curves and the simulator's slip windows shaded."""
    names = list(outcome.series)
    fig = plt.figure(figsize=(11, 9))
    grid = fig.add_gridspec(3, 1, height_ratios=[1, 1, 0.9])
    axes = [fig.add_subplot(grid[0])]
    axes.append(fig.add_subplot(grid[1], sharex=axes[0]))
    zoom = fig.add_subplot(grid[2])
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    windows = (outcome.sequence.metadata.get("truth") or {}).get("slip_windows_s", [])
    for k, name in enumerate(names):
        s, color = outcome.series[name], colors[k % len(colors)]
        pos = np.maximum(np.linalg.norm(s.error[:, :2], axis=1), 1e-5)
        head = np.maximum(np.degrees(np.abs(s.error[:, 2])), 1e-4)
        axes[0].plot(s.stamps_s, pos * 100.0, lw=0.8, color=color, label=name)
        axes[1].plot(s.stamps_s, head, lw=0.8, color=color, label=name)
        stamps = _lidar_updates(outcome.runs.get(name))
        if stamps is not None and len(stamps):
            for ax, floor in ((axes[0], 1e-3), (axes[1], 1e-4)):
                ax.plot(stamps, np.full(len(stamps), floor * 1.5 ** (k + 1)), "|", ms=5, color=color,
                        alpha=0.6, label=f"{name}: lidar updates" if ax is axes[0] else None)
    for ax in axes:
        for a, b in windows:
            ax.axvspan(a, b, color="tab:red", alpha=0.1, lw=0)
        ax.set_yscale("log")
    axes[0].set_ylabel("position error (cm)")
    axes[1].set_ylabel("heading error (deg)")
    axes[1].set_xlabel("time (s)")
    # a 3 s close-up (from the first slip window, else from 10 s) of the estimators with lidar
    # updates, each update a vertical line
    start = float(min(a for a, _ in windows)) if len(windows) else 10.0
    for k, name in enumerate(names):
        s, stamps = outcome.series[name], _lidar_updates(outcome.runs.get(name))
        if stamps is None or not len(stamps):
            continue
        inside = (s.stamps_s >= start) & (s.stamps_s <= start + 3.0)
        color = colors[k % len(colors)]
        zoom.plot(s.stamps_s[inside], 100.0 * np.linalg.norm(s.error[inside, :2], axis=1), ".-", lw=0.8, ms=3,
                  color=color, label=name)
        for t in stamps[(stamps >= start) & (stamps <= start + 3.0)]:
            zoom.axvline(t, color=color, lw=0.4, alpha=0.5)
    for a, b in windows:
        zoom.axvspan(a, b, color="tab:red", alpha=0.1, lw=0)
    zoom.set_xlim(start, start + 3.0)
    zoom.set_ylabel("position error (cm)")
    zoom.set_xlabel("time (s), close-up: vertical lines are lidar updates")
    zoom.legend(fontsize=7, loc="upper left", ncol=3)
    axes[0].legend(fontsize=7, loc="upper left", ncol=2)
    title = f"{outcome.name}: error over time (first run), lidar updates as ticks"
    fig.suptitle(title + (", slip windows shaded" if windows else ""), fontsize=10)
    fig.tight_layout()
    return fig


def plot_nees(outcome: ScenarioOutcome, plt):
    """The Monte-Carlo average NEES of every estimator against its 95% band and its expected
    value d, the pose dimension (log scale)."""
    fig, ax = plt.subplots(figsize=(9, 4))
    curve = None
    for name, curve in outcome.anees.items():
        ax.plot(curve.stamps_s, curve.anees, lw=0.8, label=f"{name} (M={curve.runs})")
    if curve is not None:
        ax.axhspan(curve.band[0], curve.band[1], color="tab:green", alpha=0.15, label="95% band")
        ax.axhline(curve.dof, color="tab:green", lw=0.6)
    ax.set_yscale("log")
    # runs that start from the exact prior have NEES ~ 0 at first: a floor keeps the band readable
    lowest = min((float(np.nanmin(c.anees[c.anees > 0])) for c in outcome.anees.values() if np.any(c.anees > 0)),
                 default=1e-2)
    ax.set_ylim(bottom=max(1e-2, 0.5 * lowest))
    ax.set_xlabel("time (s)")
    dofs = sorted({c.dof for c in outcome.anees.values()})
    ax.set_ylabel(f"average pose NEES ({', '.join(map(str, dofs))} dof)")
    runs = {c.runs for c in outcome.anees.values()}
    ax.set_title(f"{outcome.name}: NEES of one run against the ground truth (no Monte-Carlo average)"
                 if runs == {1} else f"{outcome.name}: NEES averaged over runs")
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    return fig


#: bar colour per setting, so map-known and map-estimated estimators are never read as one ranking
SETTING_COLORS = {"localisation": "tab:green", "pose_only": "tab:gray", "slam": "tab:blue", None: "tab:purple"}


def plot_ate(summary: list[dict[str, Any]], plt, setting: Mapping[tuple[str, str], str | None] | None = None):
    """Mean ATE RMSE per scenario and estimator with its 95% confidence interval, grouped and
    coloured by setting (map known, pose only, map estimated) with a gap between the groups."""
    setting = setting or {}
    rows = [s for s in summary if s["metric"] == "ate_rmse_m" and s["mean"] is not None]
    if not rows:
        return None
    datasets = list(dict.fromkeys(r["dataset"] for r in rows))
    estimators = list(dict.fromkeys(r["estimator"] for r in rows))
    order = {key: k for k, key in enumerate([*SETTINGS, None])}
    fig, axes = plt.subplots(1, len(datasets), figsize=(4.5 * len(datasets), 4.3), squeeze=False)
    for ax, d in zip(axes[0], datasets):
        sub = {r["estimator"]: r for r in rows if r["dataset"] == d}
        names = sorted((e for e in estimators if e in sub), key=lambda e: order.get(setting.get((d, e)), len(order)))
        groups = [setting.get((d, e)) for e in names]
        # a gap of one bar between settings
        x = np.cumsum([0] + [1 + (groups[k] != groups[k - 1]) for k in range(1, len(names))]).astype(float)
        means = np.array([sub[e]["mean"] for e in names])
        lo = np.array([sub[e]["ci95"][0] if sub[e]["ci95"][0] is not None else sub[e]["mean"] for e in names])
        hi = np.array([sub[e]["ci95"][1] if sub[e]["ci95"][1] is not None else sub[e]["mean"] for e in names])
        for g in dict.fromkeys(groups):
            k = [i for i, gi in enumerate(groups) if gi == g]
            ax.bar(x[k], means[k], yerr=np.vstack([means[k] - lo[k], hi[k] - means[k]]), capsize=4,
                   color=SETTING_COLORS.get(g, "tab:purple"), label=SETTING_SHORT.get(g, "other"))
        ax.set_xticks(x, names)
        ax.set_title(d, fontsize=10)
        ax.set_ylabel("ATE RMSE (m), mean and 95% CI")
        ax.tick_params(axis="x", labelrotation=45, labelsize=8)
        ax.set_ylim(0.0, 1.35 * float(np.max(hi)))  # the legend sits in the headroom, off the bars
        ax.legend(fontsize=8, loc="upper left", title="given", title_fontsize=8)
    fig.tight_layout()
    return fig
