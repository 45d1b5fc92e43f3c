"""The ``visual_odometry`` pipeline's run: each sequence through :func:`~.vo.run_vo` with bundle
adjustment (and without), the trajectories written as TUM files."""

from __future__ import annotations

from dataclasses import replace


from slamkit.config import build
from slamkit.data.formats.image_sequence import load_image_sequence
from slamkit.data.formats.tum import write_tum
from slamkit.experiments.observers import PipelineObserver
from slamkit.experiments.pipeline import PipelineOutput, StepProgress
from slamkit.experiments.results import ResultsFolder, RunRecord
from slamkit.experiments.visual_odometry.config import VisualOdometryPipeline
from slamkit.experiments.visual_odometry.report import _plot, _report
from slamkit.experiments.visual_odometry.vo import VoPayload, VoRun, run_vo
from slamkit.paths import file_in
from slamkit.systems.visual_odometry import VisualOdometryConfig


def run(config: VisualOdometryPipeline, folder: ResultsFolder, progress: StepProgress,
        observer: PipelineObserver) -> PipelineOutput[VoPayload]:
    """Pipeline ``visual_odometry`` on its validated, resolved model: every sequence with bundle
    adjustment (and without, when ``compare_without_ba``), scored against its ground truth."""
    vo_config = build(VisualOdometryConfig, config.vo, "visual_odometry.vo")
    variants = [("mono_vo_ba", vo_config)]
    if config.compare_without_ba and vo_config.window:
        variants.append(("mono_vo", replace(vo_config, window=0)))
    sequences = [load_image_sequence(s if isinstance(s, str) else s.model_dump(exclude_none=True), config.max_frames)
                 for s in config.sequences]
    runs: list[VoRun] = []
    records: list[RunRecord] = []
    for seq in sequences:
        for label, cfg in variants:
            advance = progress.task(f"{seq.name} {label}", len(seq.images))
            result = run_vo(seq, cfg, label, on_frame=lambda _f: advance())
            runs.append(result)
            records.append(RunRecord(seq.name, label, result.metrics, params={"window": cfg.window}))
            stem = seq.name if label == "mono_vo_ba" else f"{seq.name}_no_ba"
            write_tum(file_in(folder.trajectories, stem, ".tum", "sequence name"), result.trajectory())
    _plot(folder.plots, runs)
    return PipelineOutput(records, _report(config, runs), payload=VoPayload(tuple(runs)))
