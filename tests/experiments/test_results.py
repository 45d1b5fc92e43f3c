"""Results folder: shape, numbers, and atomicity."""

from __future__ import annotations

import json
import math

import pytest
import yaml

from slamkit.errors import ConfigError
from slamkit.experiments import pipeline as pipeline_mod
from slamkit.experiments.pipeline import PipelineOutput, run_pipeline
from slamkit.experiments.results import (ResultsFolder, RunRecord, mean_ci95, metric_direction, paired_comparisons,
                                         paired_difference, paired_markdown, summarise)


def test_mean_ci95_worked_example() -> None:
    # n = 3, mean 2, sample std 1, t(0.975, 2) = 4.302653 -> half width 4.302653 / sqrt(3) = 2.484138
    mean, (lo, hi), n = mean_ci95([1.0, 2.0, 3.0])
    assert n == 3 and mean == 2.0
    assert lo == pytest.approx(2.0 - 2.484138, abs=1e-6)
    assert hi == pytest.approx(2.0 + 2.484138, abs=1e-6)


def test_summary_groups_by_dataset_estimator_metric() -> None:
    runs = [RunRecord("sim", "ekf", {"ate_rmse_m": v}, seed=s) for s, v in enumerate([0.1, 0.3])]
    runs.append(RunRecord("sim", "isam2", {"ate_rmse_m": 0.05}, seed=0))
    summary = summarise(runs)
    ekf = next(s for s in summary if s["estimator"] == "ekf")
    assert ekf["mean"] == pytest.approx(0.2) and ekf["n"] == 2
    # t(0.975, 1) = 12.7062; std = 0.141421; half = 12.7062 * 0.141421 / sqrt(2) = 1.27062
    assert ekf["ci95"][1] - ekf["mean"] == pytest.approx(1.27062, rel=1e-4)
    assert next(s for s in summary if s["estimator"] == "isam2")["n"] == 1


def test_paired_difference_worked_example() -> None:
    # d = a - b = [0.5, -0.1, 0.3, 0.7, 0.2, 0.4]: mean 1/3, sample std sqrt(0.373333 / 5) = 0.273252,
    # t(0.975, 5) = 2.570582 -> half width 0.286760; |d| ranks 5, 1, 3, 6, 2, 4, the only negative has rank 1, so
    # W- = 1 and the exact two-sided p = 2 x #{subsets of 1..6 with rank sum <= 1} / 2^6 = 4/64
    b = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    a = [x + d for x, d in zip(b, [0.5, -0.1, 0.3, 0.7, 0.2, 0.4])]
    diff = paired_difference(a, b)
    assert diff["pairs"] == 6 and diff["mean_difference"] == pytest.approx(1 / 3)
    assert diff["ci95"] == pytest.approx([1 / 3 - 0.286760, 1 / 3 + 0.286760], abs=1e-6)
    assert diff["wilcoxon_p"] == pytest.approx(4 / 64)


def test_paired_difference_drops_ties_and_nan_pairs() -> None:
    # two ties and a NaN pair: the test runs on the six positive differences, p = 2 / 2^6
    a = [1.0, 1.0, float("nan"), 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]
    b = [1.0, 1.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0]
    diff = paired_difference(a, b)
    assert diff["pairs"] == 8 and diff["wilcoxon_p"] == pytest.approx(2 / 64)
    assert paired_difference([1.0, 2.0], [1.0, 2.0])["wilcoxon_p"] == 1.0
    with pytest.raises(ValueError, match="differ in length"):
        paired_difference([1.0], [1.0, 2.0])


def test_metric_direction_reads_the_unit_or_the_rate_in_the_name() -> None:
    assert [metric_direction(m) for m in ("ate_rmse_m", "rpe_rot_deg", "step_latency_median_ms", "total_time_s",
                                          "success_rate", "outlier_recall", "nees_mean", "keyframes")] == [
        "lower", "lower", "lower", "lower", "higher", "higher", None, None]


def test_paired_comparisons_pair_on_the_seed_against_the_best_treatment() -> None:
    # ekf = isam2 + 0.1 on seeds 0-5; ukf misses seed 5, so only seeds 0-4 are shared by all three
    runs = []
    for seed in range(6):
        runs.append(RunRecord("sim", "isam2", {"ate_rmse_m": 1.0 + seed, "success_rate": 0.5, "nees_mean": 3.0}, seed))
        runs.append(RunRecord("sim", "ekf", {"ate_rmse_m": 1.1 + seed, "success_rate": 0.9, "nees_mean": 3.0}, seed))
        if seed < 5:
            runs.append(RunRecord("sim", "ukf", {"ate_rmse_m": 1.0 + seed}, seed))
    runs.append(RunRecord("other", "ekf", {"ate_rmse_m": 1.0}, 0))  # one recording: no sample
    rows = paired_comparisons(runs, treatment=lambda r: r.estimator)
    assert {r["dataset"] for r in rows} == {"sim"} and "nees_mean" not in {r["metric"] for r in rows}
    ate = {r["treatment"]: r for r in rows if r["metric"] == "ate_rmse_m"}
    assert set(ate) == {"ekf", "ukf"} and ate["ekf"]["best"] == "isam2"
    assert ate["ekf"]["pairs"] == 5 and ate["ekf"]["mean_difference"] == pytest.approx(0.1)
    assert ate["ekf"]["wilcoxon_p"] == pytest.approx(2 / 32) and not ate["ekf"]["significant"]
    assert ate["ukf"]["wilcoxon_p"] == 1.0 and ate["ukf"]["mean_difference"] == 0.0
    success = [r for r in rows if r["metric"] == "success_rate"]
    assert len(success) == 1 and success[0]["best"] == "ekf" and success[0]["mean_difference"] == pytest.approx(-0.4)
    table = paired_markdown(rows, ["dataset"])
    assert "| sim | ate_rmse_m | ekf | isam2 | 5 | 0.1 | [0.1, 0.1] | 0.0625 | no |" in table


def _fake_pipeline(config, folder, progress, observer):
    advance = progress.task("fake", 2)
    runs = []
    for seed in range(2):
        if config.model_extra.get("fail_at") == seed:  # a pipeline without a model: its keys are extras
            raise RuntimeError("boom")
        runs.append(RunRecord("toy", "est", {"ate_rmse_m": 1.0 + seed}, seed=seed))
        advance()
    (folder.plots / "p.png").write_bytes(b"\x89PNG")
    return PipelineOutput(runs, "# toy\n")


@pytest.fixture
def toy():
    pipeline_mod.register_pipeline(pipeline_mod.Pipeline("toy", _fake_pipeline))
    yield
    pipeline_mod.PIPELINES.unregister("toy")


def test_run_pipeline_writes_the_documented_shape(tmp_path, toy) -> None:
    cfg = tmp_path / "toy.yaml"
    cfg.write_text(yaml.safe_dump({"pipeline": "toy", "seeds": 2}))
    result = run_pipeline(cfg, tmp_path / "out", progress=False)
    out = result.out_dir
    assert sorted(p.name for p in out.iterdir()) == [".slamkit-results", "config.yaml", "plots", "report.md",
                                                     "results.json"]
    assert json.loads((out / ".slamkit-results").read_text())["complete"] is True
    data = json.loads((out / "results.json").read_text())
    assert data["pipeline"] == "toy" and len(data["runs"]) == 2
    assert data["summary"][0]["mean"] == 1.5
    assert yaml.safe_load((out / "config.yaml").read_text())["seeds"] == 2


def test_failed_run_leaves_no_folder_and_keeps_previous(tmp_path, toy) -> None:
    out = tmp_path / "out"
    run_pipeline({"pipeline": "toy"}, out, progress=False)
    before = (out / "results.json").read_text()
    with pytest.raises(RuntimeError):
        run_pipeline({"pipeline": "toy", "fail_at": 1}, out, progress=False, overwrite=True)
    assert (out / "results.json").read_text() == before
    assert [p.name for p in tmp_path.iterdir()] == ["out"]  # no partial folder left behind
    with pytest.raises(RuntimeError):
        run_pipeline({"pipeline": "toy", "fail_at": 0}, tmp_path / "fresh", progress=False)
    assert not (tmp_path / "fresh").exists()


def test_bad_config_names_the_file_and_line(tmp_path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("pipeline: toy\nseeds: [1, 2\n")
    with pytest.raises(ConfigError, match=r"bad\.yaml:\d+"):
        run_pipeline(bad, tmp_path / "o", progress=False)
    with pytest.raises(ConfigError, match="unknown pipeline"):
        run_pipeline({"pipeline": "nope"}, tmp_path / "o", progress=False)


def test_nan_metrics_become_null_not_invalid_json(tmp_path) -> None:
    with ResultsFolder(tmp_path / "r") as folder:
        final = folder.commit("x", [RunRecord("d", "e", {"m": math.nan})], "")
    assert json.loads((final / "results.json").read_text())["runs"][0]["metrics"]["m"] is None
