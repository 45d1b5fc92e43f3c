"""The ``navigation`` pipeline's report: the benchmark tables, every metric per world, variant and
seed set, the variants paired by seed, the map sources, the runs; and the plots."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

from pydantic import BaseModel

from slamkit.experiments.navigation.config import NavigationPipeline, NavigationVariant
from slamkit.experiments.navigation.episode import Episode
from slamkit.experiments.navigation.map_source import RobotMap
from slamkit.experiments.results import markdown_table, paired_difference, summary_markdown
from slamkit.sim.navigation_world import NavigationScenario


#: what the paired table of :func:`paired_variants_markdown` compares
PAIRED_METRICS = ("success", "collision_static", "collision_moving", "min_clearance_static_m", "time_s",
                  "path_length_m", "localisation_error_max_m")


def paired_variants_markdown(variants: "Sequence[NavigationVariant | Mapping[str, Any]]",
                             episodes: list[Episode]) -> str:
    """Per world, every variant (of a config's ``variants``) with ``paired_with`` minus that
    variant, paired by seed (both saw the same scenario and noise seed): mean difference, its 95%
    CI and the Wilcoxon p-value of :func:`slamkit.experiments.results.paired_difference`; time
    over the seeds both reached."""
    plain = [v.model_dump(exclude_none=True) if isinstance(v, BaseModel) else v for v in variants]
    pairs = [(str(v["name"]), str(v["paired_with"])) for v in plain
             if isinstance(v, Mapping) and v.get("paired_with")]
    by = {(e.world, e.variant, e.seed): e.metrics for e in episodes}
    rows = []
    for world in dict.fromkeys(e.world for e in episodes):
        for a, b in pairs:
            seeds = sorted(s for (w, v, s) in by if w == world and v == a and (w, b, s) in by)
            for m in PAIRED_METRICS if seeds else ():
                d = paired_difference([by[world, a, s][m] for s in seeds], [by[world, b, s][m] for s in seeds])
                lo, hi = d["ci95"]
                rows.append([world, f"{a} - {b}", m, d["pairs"], d["mean_difference"],
                             f"[{lo:.3g}, {hi:.3g}]", d["wilcoxon_p"]])
    if not rows:
        return ""
    return "## Paired by seed\n\n" + markdown_table(
        ["world", "variants", "metric", "pairs", "mean difference", "95% CI", "Wilcoxon p"], rows) + "\n"


def report_markdown(config: "NavigationPipeline", episodes: list[Episode], summary: list[dict],
                    maps: Mapping[str, RobotMap] | None = None, benchmark: str = "") -> str:
    text = f"# Navigation: {config.name or 'navigation'}\n\n" + benchmark
    text += "## Every metric\n\n"
    text += ("MCL (likelihood field, 500 particles) on simulated lidar and wheel odometry, each "
             "variant's global planner (A* by default) and local planner on the estimated pose among "
             "lidar-tracked obstacles. "
             "Success: stopped within the goal tolerance (position and heading, by the truth) "
             "without a collision. Mean ± half the 95% CI over seeds, per world, variant and seed set "
             "(development or evaluation).\n\n")
    text += map_source_markdown(maps or {})
    lead = ["dataset", "estimator"] + (["seeds"] if summary and "seeds" in summary[0] else [])
    text += summary_markdown(summary, lead) + "\n\n" + paired_variants_markdown(config.variants, episodes) + "\n## Runs\n\n"
    rows = [[e.scenario, e.variant, e.metrics["success"], e.metrics["final_position_error_m"],
             e.metrics["collision_static"], e.metrics["collision_moving"], e.metrics["time_s"],
             e.metrics["localisation_error_max_m"], e.metrics["replans"]] for e in episodes]
    text += markdown_table(["scenario", "variant", "success", "final error (m)", "static hit", "moving hit",
                            "time (s)", "max loc. error (m)", "replans"], rows) + "\n"
    return text


def map_source_markdown(maps: Mapping[str, RobotMap]) -> str:
    """The robot's map: its source and, for a built map, its scores per scenario."""
    sources = sorted({m.source for m in maps.values()})
    if not maps or sources == ["truth"]:
        return "Robot's map: the world's own grid (the ground truth; Willow: the ROS map).\n\n"
    text = (f"Robot's map: {', '.join(sources)} (slamkit.experiments.navigation.map_source): lidar SLAM on a "
            "seeded mapping tour of each world, rasterised at 5 cm in SLAM's own frame; the simulator "
            "keeps the true world. Occupied cells matched within one cell on the observed cells:\n\n")
    keys = ("map_precision_1cell", "map_recall_1cell", "map_free_coverage", "map_tour_ate_m",
            "map_tour_error_max_m", "map_tour_length_m", "map_build_s")
    rows = [[name] + [m.metrics.get(k, float("nan")) for k in keys] for name, m in maps.items()]
    return markdown_table(["scenario", "precision", "recall", "free coverage", "tour ATE (m)",
                           "tour max error (m)", "tour length (m)", "build (s)"], rows) + "\n\n"


def plot(plots: Path, episodes: list[Episode], scenarios: Mapping[str, NavigationScenario]) -> None:
    """``trajectory.png``: per world, its first scenario on the whole map (truth and estimate of
    every variant, the crossing obstacles' lines, start and goal) above the localisation error
    along the run."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    firsts = list({e.world: e.scenario for e in reversed(episodes)}.items())[::-1]
    fig, axes = plt.subplots(2, len(firsts), figsize=(5.5 * len(firsts), 8.5), squeeze=False,
                             gridspec_kw={"height_ratios": [3, 1]})
    for col, (world, name) in enumerate(firsts):
        sc, ax, err = scenarios[name], axes[0, col], axes[1, col]
        g = sc.grid
        extent = (g.origin_xy_m[0], g.origin_xy_m[0] + g.width * g.resolution_m,
                  g.origin_xy_m[1], g.origin_xy_m[1] + g.height * g.resolution_m)
        ax.imshow(g.occupied, origin="lower", extent=extent, cmap="Greys", alpha=0.8)
        for ep in (e for e in episodes if e.scenario == name):
            ax.plot(ep.true_xytheta[:, 0], ep.true_xytheta[:, 1], lw=1.5, label=f"{ep.variant} truth")
            ax.plot(ep.estimated_xytheta[:, 0], ep.estimated_xytheta[:, 1], "--", lw=1,
                    label=f"{ep.variant} estimate")
            err.plot(ep.t_s, 100.0 * ep.position_error_m(), lw=1, label=ep.variant)
        for route in sc.obstacles.routes_xy_m():
            ax.plot(route[:, 0], route[:, 1], color="tab:red", lw=3, alpha=0.4)
        ax.plot(*sc.start_xytheta[:2], "bo", ms=7)
        ax.plot(*sc.goal_xytheta[:2], "g*", ms=12)
        ax.set_title(f"{name}: truth and estimate (red: crossing obstacles)", fontsize=9)
        ax.set_aspect("equal")
        ax.legend(loc="best", fontsize=7)
        err.set_xlabel("time (s)")
        err.set_ylabel("position error (cm)")
        err.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(plots / "trajectory.png", dpi=100)
    plt.close(fig)


#: the most particles a snapshot carries (the viewer draws them all)
