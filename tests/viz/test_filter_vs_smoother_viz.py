"""The filter_vs_smoother recorder streams: each snapshot is in the recording (file or viewer)
as soon as the runner sends it, the finished run's data follows with the output, and a run that
fails leaves no recording."""

from __future__ import annotations

import os
import re
import subprocess

from slamkit.experiments.filter_vs_smoother import assemble, run_monte_carlo
from slamkit.viz.filter_vs_smoother import FilterVsSmootherObserver

CONFIG = {"seeds": 2, "workers": 1, "scenarios": [{"preset": "mild", "params": {"duration_s": 3.0}}],
          "estimators": {"ekf": {}, "pf_small": {"type": "pf", "n_particles": 100}}}
LIVE = {"/mild/world/estimate/ekf/pose", "/mild/world/estimate/ekf/ellipse",
        "/mild/world/estimate/ekf/associations", "/mild/world/estimate/pf_small/particles"}
FINISHED = {"/mild/world/ground_truth", "/mild/world/landmarks", "/mild/world/estimate/ekf",
            "/mild/plots/error/ekf", "/mild/plots/nees/ekf", "/mild/plots/nees/band_upper"}


def _entities(rerun_cli: str, path) -> set[str]:
    stats = subprocess.run([rerun_cli, "rrd", "stats", str(path)], capture_output=True, text=True,
                           timeout=120, env=dict(os.environ, RERUN_ANALYTICS="0"))
    assert stats.returncode == 0, stats.stderr
    section = stats.stdout.split("Num chunks per entity", 1)[1].split("\n\n", 1)[0]
    return set(re.findall(r"^(/[^:\s]+):", section, flags=re.M))


def test_snapshots_are_recorded_as_they_arrive(tmp_path, rerun_cli, verify_rrd) -> None:
    path = tmp_path / "recording.rrd"
    observer = FilterVsSmootherObserver(path)
    results, scenarios, choices = run_monte_carlo(CONFIG, observer=observer)
    # the run is over, its output not yet assembled: what streamed is already in the file
    observer.recording.stream.flush()
    partial = _entities(rerun_cli, observer.recording._tmp_path)
    assert LIVE <= partial, LIVE - partial
    assert not FINISHED & partial  # ground truth and plots need the finished run
    assert not path.exists()
    observer.on_output(assemble(CONFIG, results, scenarios, choices))
    observer.close()
    entities = verify_rrd(path)
    assert LIVE | FINISHED <= entities, (LIVE | FINISHED) - entities


def test_a_run_without_output_leaves_no_recording(tmp_path) -> None:
    path = tmp_path / "recording.rrd"
    observer = FilterVsSmootherObserver(path)
    run_monte_carlo({**CONFIG, "seeds": 1, "estimators": {"ekf": {}}}, observer=observer)
    observer.close()  # what run_pipeline does when the pipeline raised
    assert list(tmp_path.iterdir()) == []
