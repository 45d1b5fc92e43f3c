"""Rerun recording of the ``pose_graph_outliers`` pipeline: ATE against the number of false loop
closures, one series per dataset, outlier kind and back-end, on the ``outliers`` timeline:

    plots/ate_rmse_m/<dataset>/<kind>/<backend>        ATE RMSE (m), mean over seeds
    plots/outlier_recall/<dataset>/<kind>/<backend>    rejected false loop closures / all false ones
"""

from __future__ import annotations

from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from slamkit.experiments.pipeline import PipelineOutput
from slamkit.viz.filter_vs_smoother import PALETTE
from slamkit.viz.recording import OutputRecorder
from slamkit.viz.views import series_view

METRICS = ("ate_rmse_m", "outlier_recall")


class PoseGraphOutliersObserver(OutputRecorder):
    payload_type = list

    def on_output(self, output: PipelineOutput[list[dict[str, Any]]]) -> None:
        from slamkit.viz.recording import open_recording

        runs = output.payload or []
        if not runs:
            return
        series: dict[tuple[str, str, str, str], dict[int, list[float]]] = {}
        for r in runs:
            kinds = {r["params"]["kind"]} if r["params"]["outliers"] else {
                q["params"]["kind"] for q in runs if q["params"]["outliers"]} or {"none"}
            for kind in kinds:  # the outlier-free run starts every kind's curve
                for metric in METRICS:
                    value = r["metrics"].get(metric)
                    if value is not None and np.isfinite(value):
                        key = (metric, r["dataset"], kind, r["estimator"])
                        series.setdefault(key, {}).setdefault(r["params"]["outliers"], []).append(value)
        highest = {m: max((max(np.mean(v) for v in pts.values()) for (mm, *_), pts in series.items() if mm == m),
                          default=None) for m in METRICS}
        bp = rrb.Blueprint(rrb.Vertical(*(series_view(f"plots/{m}", m, highest[m]) for m in METRICS)),
                           collapse_panels=True)
        # one colour per back-end in both plots (the viewer's automatic colours can coincide)
        backends = list(dict.fromkeys(backend for (_, _, _, backend) in series))
        with open_recording("slamkit_pose_graph_outliers", self.path, self.spawn, bp) as rec:
            for (metric, dataset, kind, backend), points in series.items():
                color, name = PALETTE[backends.index(backend) % len(PALETTE)], f"{dataset} {kind} {backend}"
                rec.stream.log(f"plots/{metric}/{dataset}/{kind}/{backend}",
                               rr.SeriesLines(colors=[color], names=[name], widths=[2.0]),
                               rr.SeriesPoints(colors=[color], names=[name], markers=["circle"], marker_sizes=[3.0]),
                               static=True)
                counts = np.array(sorted(points))
                rec.stream.send_columns(f"plots/{metric}/{dataset}/{kind}/{backend}",
                                        indexes=[rr.TimeColumn("outliers", sequence=counts)],
                                        columns=rr.Scalars.columns(scalars=[np.mean(points[c]) for c in counts]))
