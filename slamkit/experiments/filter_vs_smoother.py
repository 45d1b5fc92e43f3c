"""Pipeline ``filter_vs_smoother``: filters and smoothers on the same sequences, scored by the
same metrics, Monte-Carlo over seeds.

Config (``pipelines/filter_vs_smoother.yaml``)::

    pipeline: filter_vs_smoother
    seeds: 4                 # an int n (seeds 0..n-1) or a list of seeds
    workers: 2               # local processes (default min(2, cpu count)); 1 runs in-process
    scenarios:
      - preset: mild         # simulated landmark world: mild | strong (slamkit.sim.landmark_world)
        name: mild           # optional label
        params: {duration_s: 40}   # LandmarkScenario fields; sensor: {RangeBearingSensor fields}
      - dataset: citytrees10000    # a registry name (slamkit.data.formats.landmark_datasets)
        params: {max_poses: 300}
    estimators:              # registry name -> params (or a list of names); ``type`` lets one
      ekf: {}                # estimator appear twice: pf_small: {type: pf, n_particles: 200}
      pf: {n_particles: 500}
      batch: {}

Simulated scenarios are drawn once per seed; datasets are deterministic and run once (seed 0
seeds the particle methods). A dataset without ground truth is scored against the batch
solution when ``batch`` is configured (NEES is then not computed: the batch solution is not the
truth).

Output: ``results.json`` (runs + mean and 95% CI per scenario x estimator x metric, plus
``consistency``: the Monte-Carlo average NEES against its chi2(3M)/M band), ``report.md``,
``plots/`` (error over time with 3-sigma bounds, average NEES with its band, ATE with CI),
``trajectories/<scenario>_<estimator>_seed<k>.tum``. The payload handed to the observer holds,
per scenario, the first seed's sequence, runs and error series.
"""

from __future__ import annotations

import dataclasses
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from slamkit.data.sequence import Sequence
from slamkit.paths import file_in, path_component
from slamkit.errors import ConfigError, DataError
from slamkit.experiments.estimators import REGISTRY, factory
from slamkit.experiments.results import RunRecord, markdown_table, summarise, summary_markdown
from slamkit.experiments.runner import EstimatorRun, ErrorSeries, monte_carlo_nees, run_estimators, score


# --------------------------------------------------------------------------------------------
# config


@dataclass(frozen=True)
class ScenarioSpec:
    name: str
    preset: str | None = None
    dataset: str | None = None
    params: Mapping[str, Any] = field(default_factory=dict)

    @property
    def simulated(self) -> bool:
        return self.preset is not None


@dataclass(frozen=True)
class EstimatorChoice:
    label: str
    type: str
    params: Mapping[str, Any] = field(default_factory=dict)


def parse_scenarios(config: Mapping[str, Any]) -> list[ScenarioSpec]:
    raw = config.get("scenarios")
    if not raw:
        raise ConfigError("filter_vs_smoother: 'scenarios' must list simulated presets or datasets")
    out: list[ScenarioSpec] = []
    for k, item in enumerate(raw):
        if isinstance(item, str):
            item = {"preset": item} if item in ("mild", "strong") else {"dataset": item}
        if not isinstance(item, Mapping) or (("preset" in item) == ("dataset" in item)):
            raise ConfigError(f"filter_vs_smoother: scenarios[{k}] needs exactly one of 'preset' or "
                              f"'dataset', got {item!r}")
        unknown = set(item) - {"preset", "dataset", "name", "params"}
        if unknown:
            raise ConfigError(f"filter_vs_smoother: scenarios[{k}] has unknown key(s) {sorted(unknown)}")
        if "preset" in item and item["preset"] not in ("mild", "strong"):
            raise ConfigError(f"filter_vs_smoother: scenarios[{k}].preset must be mild or strong, "
                              f"got {item['preset']!r}")
        name = path_component(str(item.get("name") or item.get("preset") or item.get("dataset")),
                              f"filter_vs_smoother: scenarios[{k}] name")
        out.append(ScenarioSpec(name, item.get("preset"), item.get("dataset"), dict(item.get("params") or {})))
    names = [s.name for s in out]
    if len(set(names)) != len(names):
        raise ConfigError(f"filter_vs_smoother: scenario names must be unique, got {names} (set 'name')")
    return out


def parse_estimators(config: Mapping[str, Any]) -> list[EstimatorChoice]:
    raw = config.get("estimators")
    if not raw:
        raise ConfigError("filter_vs_smoother: 'estimators' must name registry estimators "
                          f"({', '.join(REGISTRY)})")
    items: list[tuple[str, Mapping[str, Any]]] = []
    if isinstance(raw, Mapping):
        items = [(str(k), dict(v or {})) for k, v in raw.items()]
    else:
        for entry in raw:
            if isinstance(entry, str):
                items.append((entry, {}))
            elif isinstance(entry, Mapping) and len(entry) == 1:
                (k, v), = entry.items()
                items.append((str(k), dict(v or {})))
            else:
                raise ConfigError(f"filter_vs_smoother: bad estimators entry {entry!r}")
    out = []
    for label, params in items:
        params = dict(params)
        kind = str(params.pop("type", label))
        if kind not in REGISTRY:
            raise ConfigError(f"filter_vs_smoother: unknown estimator {kind!r} (for {label!r}); known: "
                              f"{', '.join(REGISTRY)}")
        out.append(EstimatorChoice(path_component(label, "filter_vs_smoother: estimator label"), kind, params))
    return out


def parse_seeds(config: Mapping[str, Any]) -> list[int]:
    """The run's seeds (one rule for every pipeline: :func:`config_models.seed_list`)."""
    from slamkit.experiments.config_models import seed_list

    return seed_list(config.get("seeds", 1))


def default_workers() -> int:
    return max(1, min(2, os.cpu_count() or 1))


# --------------------------------------------------------------------------------------------
# sequences


def build_sequence(scenario: ScenarioSpec, seed: int) -> Sequence:
    """The sequence of one scenario and seed (datasets ignore the seed)."""
    if scenario.simulated:
        from slamkit.sim.landmark_world import PRESETS, simulate_landmark_sequence

        params = dict(scenario.params)
        if "sensor" in params and isinstance(params["sensor"], Mapping):
            base = PRESETS[scenario.preset]().sensor
            params["sensor"] = dataclasses.replace(base, **params["sensor"])
        for key in ("path_size_m", "initial_pose_sigma"):
            if key in params:
                params[key] = tuple(params[key])
        if "profile" in params:
            params["profile"] = tuple(tuple(p) for p in params["profile"])
        try:
            config = PRESETS[scenario.preset](**{"name": scenario.name, **params})
        except TypeError as exc:
            raise ConfigError(f"filter_vs_smoother: scenario {scenario.name!r}: {exc}") from None
        return simulate_landmark_sequence(config, np.random.default_rng(seed))
    from slamkit.data.formats.landmark_datasets import load_landmark_sequence

    return load_landmark_sequence(scenario.dataset, **dict(scenario.params))


# --------------------------------------------------------------------------------------------
# one Monte-Carlo task


@dataclass(frozen=True)
class Task:
    scenario: ScenarioSpec
    seed: int
    estimators: tuple[EstimatorChoice, ...]
    trajectories_dir: str | None
    keep_full: bool = False


@dataclass(frozen=True)
class TaskResult:
    scenario: str
    seed: int
    records: list[RunRecord]
    series: dict[str, ErrorSeries]
    notes: list[str]
    reference: str
    #: only with keep_full (the run the recording shows)
    sequence: Sequence | None = None
    runs: dict[str, EstimatorRun] | None = None


def run_task(task: Task, observer: Any = None) -> TaskResult:
    """Build the sequence, run every estimator, score them (and write their trajectories)."""
    sequence = build_sequence(task.scenario, task.seed)
    factories = {c.label: factory(c.type, c.params, seed=task.seed) for c in task.estimators}
    runs = run_estimators(sequence, factories, observer=observer,
                          run_label=f"{task.scenario.name}/seed{task.seed}")
    reference, reference_name, is_truth = sequence.ground_truth, "ground_truth", True
    batch = next((r for c, r in zip(task.estimators, runs.values())
                  if c.type == "batch" and r.estimate is not None), None)
    if reference is None and batch is not None:
        reference, reference_name, is_truth = batch.estimate.trajectory, f"{batch.name} solution", False
    records, series, notes = [], {}, []
    for choice in task.estimators:
        run = runs[choice.label]
        scored = score(run, reference, sequence.world_p_landmarks, reference_is_truth=is_truth)
        params = {"type": choice.type, "kind": run.kind, "reference": reference_name, **choice.params}
        if run.failed:
            params["failed"] = run.failed
        records.append(RunRecord(task.scenario.name, choice.label, scored.metrics, task.seed, params))
        notes.extend(scored.notes)
        if scored.series is not None:
            series[choice.label] = scored.series
        if task.trajectories_dir is not None and run.estimate is not None:
            from slamkit.data.formats.tum import write_tum

            write_tum(file_in(task.trajectories_dir, f"{task.scenario.name}_{choice.label}_seed{task.seed}", ".tum",
                              "scenario name / estimator label"),
                      run.estimate.trajectory)
    return TaskResult(task.scenario.name, task.seed, records, series, notes, reference_name,
                      sequence if task.keep_full else None, runs if task.keep_full else None)


# --------------------------------------------------------------------------------------------
# the pipeline


@dataclass(frozen=True)
class ScenarioOutcome:
    """What the observer and the plots need of one scenario."""

    name: str
    sequence: Sequence
    runs: dict[str, EstimatorRun]
    series: dict[str, ErrorSeries]
    #: estimator -> (stamps, Monte-Carlo average NEES, (band lower, band upper), M)
    anees: dict[str, tuple[np.ndarray, np.ndarray, tuple[float, float], int]]


@dataclass(frozen=True)
class FilterVsSmootherPayload:
    scenarios: list[ScenarioOutcome]
    estimators: list[str]


def run_monte_carlo(config: Mapping[str, Any], trajectories_dir: Path | None = None, progress=None,
                    observer: Any = None) -> tuple[list[TaskResult], list[ScenarioSpec], list[EstimatorChoice]]:
    """Every scenario x seed (datasets once); the first seed of every scenario runs in this
    process with ``observer`` (and keeps its sequence and estimates), the rest in the pool."""
    scenarios = parse_scenarios(config)
    choices = tuple(parse_estimators(config))
    seeds = parse_seeds(config)
    workers = int(config.get("workers", default_workers()))
    if workers < 1:
        raise ConfigError(f"filter_vs_smoother: workers must be >= 1, got {workers}")
    tdir = None if trajectories_dir is None else str(trajectories_dir)
    tasks = [Task(s, seed, choices, tdir, keep_full=(k == 0))
             for s in scenarios for k, seed in enumerate(seeds if s.simulated else seeds[:1])]
    advance = progress.task("filter vs smoother", len(tasks)) if progress is not None else (lambda n=1: None)
    main_tasks = [t for t in tasks if t.keep_full]
    pool_tasks = [t for t in tasks if not t.keep_full]
    results: list[TaskResult] = []
    if workers == 1 or not pool_tasks:
        for t in main_tasks:
            results.append(run_task(t, observer))
            advance()
        for t in pool_tasks:
            results.append(run_task(t))
            advance()
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            futures = [pool.submit(run_task, t) for t in pool_tasks]
            for t in main_tasks:
                results.append(run_task(t, observer))
                advance()
            for f in futures:
                results.append(f.result())
                advance()
    order = {(t.scenario.name, t.seed): k for k, t in enumerate(tasks)}
    results.sort(key=lambda r: order[(r.scenario, r.seed)])
    return results, scenarios, list(choices)


#: above this fraction of steps without a positive-definite covariance no verdict is given
DEGENERATE_VERDICT_LIMIT = 0.1


def nees_verdict(anees_mean: float, band: tuple[float, float], degenerate_fraction: float) -> str:
    """inside / above: overconfident / below: conservative, or 'degenerate' when too many steps
    have a covariance that is not positive definite (a collapsed particle set is not conservative)."""
    if degenerate_fraction > DEGENERATE_VERDICT_LIMIT or not np.isfinite(anees_mean):
        return f"degenerate covariance ({100 * degenerate_fraction:.0f}% of steps)"
    if band[0] <= anees_mean <= band[1]:
        return "inside"
    return "above: overconfident" if anees_mean > band[1] else "below: conservative"


def consistency_table(results: list[TaskResult], scenarios: list[ScenarioSpec],
                      choices: list[EstimatorChoice]) -> tuple[list[dict[str, Any]], dict]:
    """Per scenario x estimator: the time-mean of the Monte-Carlo average NEES, its chi2(3M)/M
    95% band, whether it lies inside, and the fraction of steps whose average NEES does."""
    rows: list[dict[str, Any]] = []
    curves: dict = {}
    for s in scenarios:
        for c in choices:
            series = [r.series[c.label] for r in results
                      if r.scenario == s.name and c.label in r.series and r.series[c.label].nees is not None]
            if not series:
                continue
            try:
                stamps, anees, band = monte_carlo_nees(series)
            except DataError:
                continue
            degenerate = float(np.mean([np.mean(~np.isfinite(x.nees)) for x in series]))
            finite = np.isfinite(anees)
            mean = float(np.mean(anees[finite])) if finite.any() else float("nan")
            inside = float(np.mean((anees[finite] >= band[0]) & (anees[finite] <= band[1]))) if finite.any() else 0.0
            rows.append({"dataset": s.name, "estimator": c.label, "runs": len(series),
                         "anees_mean": mean, "band95": [band[0], band[1]],
                         "inside_band": bool(finite.any() and band[0] <= mean <= band[1]),
                         "steps_in_band_fraction": inside, "degenerate_fraction": degenerate,
                         "verdict": nees_verdict(mean, band, degenerate)})
            curves[(s.name, c.label)] = (stamps, anees, band, len(series))
    return rows, curves


def run(config: Mapping[str, Any], folder, progress, observer) -> "PipelineOutput":
    """Pipeline ``filter_vs_smoother`` (see the module docstring)."""
    from slamkit.experiments.pipeline import PipelineOutput

    results, scenarios, choices = run_monte_carlo(config, folder.trajectories, progress, observer)
    output = assemble(config, results, scenarios, choices)
    plot_all(folder.plots, output.payload, output.summary)
    return output


def assemble(config: Mapping[str, Any], results: list[TaskResult], scenarios: list[ScenarioSpec],
             choices: list[EstimatorChoice]) -> "PipelineOutput":
    from slamkit.experiments.pipeline import PipelineOutput

    records = [rec for r in results for rec in r.records]
    summary = summarise(records)
    rows, curves = consistency_table(results, scenarios, choices)
    outcomes = []
    for s in scenarios:
        full = next(r for r in results if r.scenario == s.name and r.sequence is not None)
        outcomes.append(ScenarioOutcome(
            s.name, full.sequence, full.runs, full.series,
            {c: curves[(s.name, c)] for (sn, c) in curves if sn == s.name}))
    payload = FilterVsSmootherPayload(outcomes, [c.label for c in choices])
    notes = sorted({n for r in results for n in r.notes})
    references = {r.scenario: r.reference for r in results}
    report = report_markdown(config, summary, rows, scenarios, references, notes, results)
    return PipelineOutput(records, report, summary, {"consistency": rows}, payload)


def report_markdown(config: Mapping[str, Any], summary: list[dict[str, Any]], consistency: list[dict],
                    scenarios: list[ScenarioSpec], references: Mapping[str, str], notes: list[str],
                    results: list[TaskResult]) -> str:
    seeds = {s.name: sum(1 for r in results if r.scenario == s.name) for s in scenarios}
    text = f"# Filters against smoothers: {config.get('name', 'filter_vs_smoother')}\n\n"
    text += ("Every estimator sees the same sequence. Cells are the mean over runs ± the half width "
             "of the 95% Student-t confidence interval. ATE and RPE after SE(2) alignment; NEES "
             "from the unaligned pose error and the estimator's own covariance (filters: filtered, "
             "smoothers: final marginals); latencies per `step` call.\n\n")
    lines = []
    for s in scenarios:
        what = f"simulated preset `{s.preset}`" if s.simulated else f"dataset `{s.dataset}`"
        params = ", ".join(f"{k}={v}" for k, v in s.params.items())
        lines.append(f"- **{s.name}**: {what}{' (' + params + ')' if params else ''}, {seeds[s.name]} run(s), "
                     f"reference: {references.get(s.name, 'none')}")
    text += "## Scenarios\n\n" + "\n".join(lines) + "\n\n"
    text += "## Metrics\n\n" + summary_markdown(summary) + "\n\n"
    if consistency:
        text += ("## Consistency (pose NEES, 3 dof)\n\n"
                 "Average NEES over the M runs at every step; a consistent estimator keeps its time "
                 "mean inside the two-sided 95% band of chi2(3M)/M (Bar-Shalom et al. 2001, sec. "
                 "5.4), and about 95% of the steps inside it.\n\n")
        table = [[r["dataset"], r["estimator"], r["runs"], r["anees_mean"],
                  f"[{r['band95'][0]:.3g}, {r['band95'][1]:.3g}]",
                  r["verdict"] if r["verdict"] == "inside" else f"**{r['verdict']}**",
                  r["steps_in_band_fraction"], r["degenerate_fraction"]] for r in consistency]
        text += markdown_table(["scenario", "estimator", "runs M", "mean NEES", "95% band", "verdict",
                                "steps in band", "degenerate steps"], table) + "\n\n"
    failed = [(rec.dataset, rec.estimator, rec.seed, rec.params.get("failed"))
              for r in results for rec in r.records if rec.params.get("failed")]
    if failed:
        notes = notes + [f"{d} / {e} / seed {s}: {msg}" for d, e, s, msg in failed]
    if notes:
        text += "## Notes\n\n" + "\n".join(f"- {n}" for n in notes[:50]) + "\n"
    return text


# --------------------------------------------------------------------------------------------
# plots


def plot_all(plots: Path, payload: FilterVsSmootherPayload, summary: list[dict[str, Any]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for outcome in payload.scenarios:
        if outcome.series:
            fig = plot_errors(outcome, plt)
            fig.savefig(file_in(plots, f"error_{outcome.name}", ".png", "scenario name"), dpi=100)
            plt.close(fig)
        if outcome.anees:
            fig = plot_nees(outcome, plt)
            fig.savefig(file_in(plots, f"nees_{outcome.name}", ".png", "scenario name"), dpi=100)
            plt.close(fig)
    fig = plot_ate(summary, plt)
    if fig is not None:
        fig.savefig(plots / "ate_rmse.png", dpi=100)
        plt.close(fig)


def plot_errors(outcome: ScenarioOutcome, plt):
    """x, y, heading error of the first run of every estimator with its +-3 sigma bounds."""
    names = list(outcome.series)
    fig, axes = plt.subplots(len(names), 3, figsize=(12, 2.0 * len(names) + 0.8), squeeze=False,
                             sharex=True)
    labels = ("x error (m)", "y error (m)", "heading error (rad)")
    for row, name in enumerate(names):
        s = outcome.series[name]
        for col in range(3):
            ax = axes[row, col]
            ax.plot(s.stamps_s, s.error_xytheta[:, col], lw=0.8, color="tab:blue")
            if s.sigma_xytheta is not None:
                b = 3.0 * s.sigma_xytheta[:, col]
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


def plot_nees(outcome: ScenarioOutcome, plt):
    fig, ax = plt.subplots(figsize=(9, 4))
    band = None
    for name, (stamps, anees, b, m) in outcome.anees.items():
        ax.plot(stamps, anees, lw=0.8, label=f"{name} (M={m})")
        band = b
    if band is not None:
        ax.axhspan(band[0], band[1], color="tab:green", alpha=0.15, label="95% band")
        ax.axhline(3.0, color="tab:green", lw=0.6)
    ax.set_yscale("log")
    # the first steps start from the exact prior (NEES ~ 0); a floor keeps the band readable
    ax.set_ylim(bottom=1e-2)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("average pose NEES (3 dof)")
    ax.set_title(f"{outcome.name}: NEES averaged over runs")
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    return fig


def plot_ate(summary: list[dict[str, Any]], plt):
    rows = [s for s in summary if s["metric"] == "ate_rmse_m" and s["mean"] is not None]
    if not rows:
        return None
    datasets = list(dict.fromkeys(r["dataset"] for r in rows))
    estimators = list(dict.fromkeys(r["estimator"] for r in rows))
    fig, axes = plt.subplots(1, len(datasets), figsize=(4.5 * len(datasets), 4), squeeze=False)
    for ax, d in zip(axes[0], datasets):
        sub = {r["estimator"]: r for r in rows if r["dataset"] == d}
        names = [e for e in estimators if e in sub]
        means = np.array([sub[e]["mean"] for e in names])
        lo = np.array([sub[e]["ci95"][0] if sub[e]["ci95"][0] is not None else sub[e]["mean"] for e in names])
        hi = np.array([sub[e]["ci95"][1] if sub[e]["ci95"][1] is not None else sub[e]["mean"] for e in names])
        ax.bar(names, means, yerr=np.vstack([means - lo, hi - means]), capsize=4, color="tab:blue")
        ax.set_title(d, fontsize=10)
        ax.set_ylabel("ATE RMSE (m), mean and 95% CI")
        ax.tick_params(axis="x", labelrotation=45, labelsize=8)
    fig.tight_layout()
    return fig
