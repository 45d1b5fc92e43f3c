"""The ``local_planning`` pipeline's report: the summary and run tables and the plots."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np

from slamkit.experiments.closed_loop.config import LocalPlanningPipeline
from slamkit.experiments.closed_loop.episode import Episode, Scenario
from slamkit.experiments.results import markdown_table, summary_markdown


def report_markdown(config: "LocalPlanningPipeline", episodes: list[Episode], summary: list[dict]) -> str:
    text = f"# Local planning: {config.name or 'local_planning'}\n\n"
    text += ("Controllers track an A* path through a static map while moving circles cross it "
             "(perfect perception within range). Mean ± half the 95% CI over scenarios; "
             "time to goal over successful runs only.\n\n")
    text += summary_markdown(summary) + "\n\n## Runs\n\n"
    rows = [[e.scenario, e.controller, e.metrics["success"], e.metrics["time_to_goal_s"],
             e.metrics["min_clearance_m"], e.metrics["collisions"], e.metrics["step_latency_median_ms"]]
            for e in episodes]
    text += markdown_table(["scenario", "controller", "success", "time to goal (s)",
                            "min clearance (m)", "collisions", "latency median (ms)"], rows) + "\n"
    return text


def plot(plots: Path, episodes: list[Episode], scenarios: Mapping[str, Scenario]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    first = episodes[0].scenario
    sc = scenarios[first]
    fig, ax = plt.subplots(figsize=(7, 7))
    g = sc.grid
    extent = (g.origin_xy_m[0], g.origin_xy_m[0] + g.width * g.resolution_m,
              g.origin_xy_m[1], g.origin_xy_m[1] + g.height * g.resolution_m)
    ax.imshow(g.occupied, origin="lower", extent=extent, cmap="Greys", alpha=0.8)
    ax.plot(sc.path_xy_m[:, 0], sc.path_xy_m[:, 1], "k--", lw=1, label="global path")
    for e in episodes:
        if e.scenario == first:
            ax.plot(e.poses_xytheta[:, 0], e.poses_xytheta[:, 1], lw=1.5,
                    label=f"{e.controller} ({'ok' if e.reached_goal else 'fail'})")
    for a, b in zip(sc.obstacles.a_xy_m, sc.obstacles.b_xy_m):
        ax.plot([a[0], b[0]], [a[1], b[1]], color="tab:red", lw=3, alpha=0.4)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"{first}: trajectories (red: obstacle crossing segments)")
    ax.set_aspect("equal")
    fig.savefig(plots / "trajectories.png", dpi=110, bbox_inches="tight")
    plt.close(fig)

    names = list(dict.fromkeys(e.controller for e in episodes))
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    for ax, metric, label in zip(axes, ("success", "time_to_goal_s", "min_clearance_m"),
                                 ("success rate", "time to goal (s)", "min clearance (m)")):
        vals = []
        for n in names:
            v = np.array([e.metrics[metric] for e in episodes if e.controller == n], dtype=float)
            vals.append(float(v[np.isfinite(v)].mean()) if np.isfinite(v).any() else 0.0)
        ax.bar(names, vals, color="tab:blue")
        ax.set_title(label)
    fig.savefig(plots / "metrics.png", dpi=110, bbox_inches="tight")
    plt.close(fig)
