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
from slamkit.viz.recording import OutputRecorder

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
        bp = rrb.Blueprint(rrb.Vertical(*(rrb.TimeSeriesView(origin=f"plots/{m}", name=m) for m in METRICS)),
                           collapse_panels=True)
        with open_recording("slamkit_pose_graph_outliers", self.path, self.spawn, bp) as rec:
            for (metric, dataset, kind, backend), points in series.items():
                counts = np.array(sorted(points))
                rec.stream.send_columns(f"plots/{metric}/{dataset}/{kind}/{backend}",
                                        indexes=[rr.TimeColumn("outliers", sequence=counts)],
                                        columns=rr.Scalars.columns(scalars=[np.mean(points[c]) for c in counts]))
