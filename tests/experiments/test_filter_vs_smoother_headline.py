"""The filter_vs_smoother report's headline table and ATE chart (issue 32 item 6): worked
examples with hand-made summary rows."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from slamkit.experiments.filter_vs_smoother.report import SETTING_COLORS, headline_markdown, plot_ate  # noqa: E402


def _row(dataset, estimator, metric, mean, ci=None, n=3):
    return {"dataset": dataset, "estimator": estimator, "metric": metric, "mean": mean, "ci95": ci, "n": n}


SUMMARY = [
    _row("strong", "batch", "ate_rmse_m", 0.506, [0.096, 0.916]),
    _row("strong", "batch", "rpe_rmse_m", 0.111, [0.094, 0.128]),
    _row("strong", "ekf", "ate_rmse_m", 0.25, [0.14, 0.36]),
    _row("strong", "ekf", "rpe_rmse_m", 0.316, [0.206, 0.426]),
    _row("strong", "ekf", "step_latency_median_ms", 0.0912, [0.0792, 0.1032]),
    _row("strong", "ekf", "nees_mean", 2.9, [2.0, 3.8]),  # not a headline column
]
SETTING = {("strong", "batch"): "slam", ("strong", "ekf"): "localisation"}
CONSISTENCY = [{"dataset": "strong", "estimator": "ekf", "verdict": "inside"},
               {"dataset": "strong", "estimator": "batch", "verdict": "above: overconfident"}]


def test_the_headline_table_groups_map_known_before_map_estimated_with_the_compared_columns() -> None:
    text = headline_markdown(SUMMARY, CONSISTENCY, SETTING)
    lines = [line for line in text.splitlines() if line.startswith("| strong")]
    assert lines == [
        "| strong | ekf | map known | 0.25 ± 0.11 | 0.316 ± 0.11 | inside | 0.0912 ± 0.012 |",
        "| strong | batch | map estimated | 0.506 ± 0.41 | 0.111 ± 0.017 | above: overconfident |  |",
    ]
    assert "| scenario | estimator | given | ATE RMSE (m) | RPE RMSE (m) | NEES verdict | latency median (ms) |" in text
    assert headline_markdown([], [], {}) == ""


def test_a_single_run_shows_no_interval() -> None:
    text = headline_markdown([_row("plaza2", "ekf", "ate_rmse_m", 0.424, [0.424, 0.424], n=1)], [], {("plaza2", "ekf"): "localisation"})
    assert "| plaza2 | ekf | map known | 0.424 |  |  |  |" in text


def test_the_ate_chart_colours_bars_by_setting_and_separates_the_groups() -> None:
    fig = plot_ate(SUMMARY, plt, SETTING)
    ax = fig.axes[0]
    bars = sorted(ax.patches, key=lambda b: b.get_x())
    assert [matplotlib.colors.to_hex(b.get_facecolor()) for b in bars] == [
        matplotlib.colors.to_hex(SETTING_COLORS["localisation"]), matplotlib.colors.to_hex(SETTING_COLORS["slam"])]
    # ekf at x = 0, a one-bar gap, batch at x = 2
    assert [round(b.get_x() + b.get_width() / 2, 6) for b in bars] == [0.0, 2.0]
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["map known", "map estimated"]
    assert ax.get_ylim()[1] == 1.35 * 0.916  # headroom above the highest interval for the legend
    plt.close(fig)
