"""Robust back-ends under false loop closures: the ``pose_graph_outliers`` pipeline.

For every dataset x outlier kind x outlier count x seed, ``slamkit.sim.outliers`` adds seeded
Vertigo-style false loop closures and every back-end of ``slamkit.backend.robust`` solves the
corrupted graph. Scores per run: ATE against ground truth (``ate_rmse_m``; datasets without one
are scored against their outlier-free least-squares optimum), the ratio to the outlier-free
solution's ATE (``ate_ratio``, ground-truth datasets only), ATE against that optimum (``ate_to_clean_rmse_m``), outlier
recall (rejected false loop closures / all false ones), outlier precision (false among rejected),
inlier recall (true edges kept), iterations and solve time. Count 0 runs once per dataset.

Back-end ``pcm`` composes the front-end check ``slamkit.frontend.pcm`` (pairwise consistency
with the first-order cycle covariance, exact maximum clique) with least squares on the accepted
edges; ``pcm_gnc`` with GNC. Every back-end re-admits the rejected loop closures inside the chi2 gate at its solution (the
``readmit`` option of ``RobustSolveConfig``), PCM's rejections included.

Modules (a pipeline is a small package, issue 30): :mod:`.config` (the config model), :mod:`.run`
(the cells and back-ends) and :mod:`.report` (Markdown and plots); this module composes them into
``PIPELINE``.
"""

from __future__ import annotations

from typing import Any

from slamkit.experiments.pipeline import Pipeline
from slamkit.experiments.pose_graph_outliers.config import PoseGraphOutliersPipeline
from slamkit.experiments.pose_graph_outliers.run import BACKENDS, _solve, _trajectory
from slamkit.experiments.pose_graph_outliers.run import run as _run

__all__ = ["BACKENDS", "PIPELINE", "PoseGraphOutliersPipeline", "_solve", "_trajectory"]


PIPELINE: Pipeline[PoseGraphOutliersPipeline, list[dict[str, Any]]] = Pipeline(
    "pose_graph_outliers", _run, PoseGraphOutliersPipeline, list,
    "robust back-ends x Vertigo-style false loop closures (counts, kinds, seeds)")
