"""The ``lidar_slam`` pipeline's report: the simulated worlds' table, the laser logs' relation
errors beside the published ones, and the plots (each log's map with its trajectory and worst
relations, time per scan)."""

from __future__ import annotations

import numpy as np

from slamkit.experiments.lidar_slam.config import LidarSlamPipeline
from slamkit.experiments.lidar_slam.slam import (BAD_RELATION_M, CARTOGRAPHER_REALTIME_FACTOR, PUBLISHED,
                                                 LidarSlamResult)
from slamkit.experiments.results import RunRecord, markdown_table
from slamkit.maps.log_odds import LogOddsMap
from slamkit.paths import file_in


def report_markdown(config: LidarSlamPipeline, sim_runs: list[RunRecord], log_runs: list[RunRecord]) -> str:
    text = f"# Lidar SLAM: {config.name or 'lidar_slam'}\n\n"
    if sim_runs:
        header = ["world", "seed", "estimator", "keyframes", "loops", "false loops", "ATE odometry (m)",
                  "ATE before LC (m)", "ATE after LC (m)", "reduction", "map IoU", "precision", "recall",
                  "front-end map IoU", "MCL localized (rate)", "MCL converged after (median updates)"]
        rows = [[r.dataset, r.seed, r.estimator, int(r.metrics["num_keyframes"]),
                 int(r.metrics["num_loop_closures"]), int(r.metrics["num_false_loop_closures"]),
                 r.metrics.get("ate_odometry_m"), r.metrics.get("ate_frontend_m"), r.metrics.get("ate_rmse_m"),
                 r.metrics.get("ate_reduction"), r.metrics.get("map_iou"), r.metrics.get("map_precision"),
                 r.metrics.get("map_recall"), r.metrics.get("map_frontend_iou"),
                 r.metrics.get("mcl_success_rate"), r.metrics.get("mcl_converged_after_updates")]
                for r in sim_runs]
        text += ("## Simulated worlds\n\nATE: RMSE over keyframes after SE(2) alignment; 'before LC' "
                 "chains the scan matches, 'after LC' is the optimised pose graph. Map IoU: occupied "
                 "cells (p > 0.5) against the ground truth max-pooled to the map resolution, on the cells "
                 "the map observed. MCL: global localization from a uniform prior on the built map along "
                 "a second tour, once per filter seed: the fraction of runs that end within 0.3 m / "
                 "10 deg and stay so, and the median number of updates until they do (nan: none "
                 "within the budget).\n\n")
        text += markdown_table(header, rows) + "\n"
    if log_runs:
        text += _log_report(log_runs)
    return text


def _pm(mean: float | None, std: float | None, digits: int = 3) -> str:
    if mean is None:
        return ""
    return f"{mean:.{digits}f} +- {std:.{digits}f}"


def _log_report(runs: list[RunRecord]) -> str:
    text = ("## Laser logs\n\nRelation error (Kuemmerle et al., Autonomous Robots 27(4), 2009): for every "
            "manually verified relation, the error of the estimated displacement between the two scans "
            "(poses stamped with the scans' ipc timestamps); mean +- std over all relations, and how many "
            f"are off by more than {BAD_RELATION_M:g} m (drawn on the maps in plots/). Raw "
            "odometry is scored on the same relations. Map consistency (every log, no ground truth; "
            "slamkit.metrics.map_consistency): the distance of keyframe scans' end points to the walls "
            "that other visits of the same place drew, mean and 95th percentile (it grows where walls are "
            "doubled), the same mean along one pass (scans within 5 m of travel: no drift, only what the "
            "surfaces and the scan matcher give -- the floor to read the first against: hedges, clutter "
            "and people raise both, doubled walls only the first), and the share of end points seen on "
            "more than one visit. Real-time factor: log "
            "duration / wall-clock processing time (every scan matched, loop search, iSAM2, the final "
            "batch solve; map building excluded) on this machine, and against the process's CPU time "
            "(what the other processes on the machine cannot take from it). Loop precision / recall "
            "(slamkit.metrics.loop_closures): the share of verifiable closures (count) that agree with "
            "a relation to 0.2 m / the share of relations between revisits (count, >= 60 s apart) that a "
            "closure covers.\n\n")
    header = ["log", "estimator", "translation (m)", "rotation (deg)", "relations", f"> {BAD_RELATION_M:g} m",
              "raw odometry (m)", "map consistency mean / p95 (m)", "same pass (m)", "seen twice", "keyframes",
              "loops (online + final)", "loop precision / recall", "real-time factor (wall / CPU)", "time (s)",
              "time per scan median / p99 (ms)", "peak RSS (MB)"]
    rows = []
    for r in runs:
        m = r.metrics
        rows.append([r.dataset, r.estimator, _pm(m.get("relation_trans_mean_m"), m.get("relation_trans_std_m")),
                     _pm(m.get("relation_rot_mean_deg"), m.get("relation_rot_std_deg"), 2),
                     int(m["relation_count"]) if "relation_count" in m else "",
                     int(m["relations_over_0_2_m"]) if "relations_over_0_2_m" in m else "",
                     _pm(m.get("relation_trans_mean_m_odometry"), m.get("relation_trans_std_m_odometry"), 2),
                     (f"{m['map_consistency_mean_m']:.3f} / {m['map_consistency_p95_m']:.3f}"
                      if "map_consistency_mean_m" in m else ""),
                     (f"{m['map_consistency_same_pass_mean_m']:.3f}" if "map_consistency_same_pass_mean_m" in m else ""),
                     f"{100 * m['map_consistency_overlap']:.0f}%" if "map_consistency_overlap" in m else "",
                     int(m["num_keyframes"]),
                     f"{int(m['loop_closures_online'])} + {int(m['loop_closures_final'])}",
                     (f"{m['loop_precision']:.2f} ({int(m['loop_closures_verifiable'])}) / {m['loop_recall']:.2f} "
                      f"({int(m['revisit_relations'])})" if "loop_precision" in m else ""),
                     f"{m['real_time_factor']:.1f} / {m.get('real_time_factor_cpu', float('nan')):.1f}",
                     f"{m['time_total_s']:.1f}",
                     f"{m['time_per_scan_median_ms']:.1f} / {m['time_per_scan_p99_ms']:.1f}",
                     f"{m['peak_rss_mb']:.0f}"])
    text += markdown_table(header, rows) + "\n"
    timed = [r for r in runs if r.dataset in CARTOGRAPHER_REALTIME_FACTOR]
    if timed:
        text += ("\nReal-time factor beside Cartographer's (Hess et al., ICRA 2016: one Xeon E5-1650; "
                 "issue 29's goal is twice it):\n\n")
        rows = [[r.dataset, r.estimator, f"{r.metrics['real_time_factor']:.1f}",
                 f"{r.metrics.get('real_time_factor_cpu', float('nan')):.1f}",
                 f"{CARTOGRAPHER_REALTIME_FACTOR[r.dataset]:g}", f"{2 * CARTOGRAPHER_REALTIME_FACTOR[r.dataset]:g}",
                 f"{r.metrics['real_time_factor'] / CARTOGRAPHER_REALTIME_FACTOR[r.dataset]:.2f}"] for r in timed]
        text += markdown_table(["log", "estimator", "slamkit (wall)", "slamkit (CPU)", "Cartographer", "goal",
                                "slamkit / Cartographer"], rows) + "\n"
    names = sorted({r.dataset for r in runs if r.dataset in PUBLISHED})
    if names:
        text += ("\nPublished translational relation errors (m, mean +- std; Kuemmerle et al. 2009, "
                 "as transcribed in the datasets' MANIFEST) beside slamkit's:\n\n")
        methods = list(next(iter(PUBLISHED.values())))
        ours = {}
        for r in runs:
            if "relation_trans_mean_m" in r.metrics:
                ours.setdefault(r.dataset, []).append(
                    f"{_pm(r.metrics['relation_trans_mean_m'], r.metrics['relation_trans_std_m'])} "
                    f"({r.estimator.removeprefix('lidar_slam/')})")
        rows = [[n] + [_pm(*PUBLISHED[n][k]) for k in methods] + ["<br>".join(ours.get(n, []))] for n in names]
        text += markdown_table(["log"] + methods + ["slamkit"], rows) + "\n"
    return text


def _plot(plots, results: list[LidarSlamResult]) -> None:
    if not results:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for k, res in enumerate(results):
        if res.ground_truth_poses is None:
            _plot_log(plt, plots, res)
            continue
        fig, axes = plt.subplots(1, 2, figsize=(12, 6))
        m = res.map
        for ax, mp, poses, title in ((axes[0], res.frontend_map, res.frontend_poses, "before loop closure"),
                                     (axes[1], res.map, res.optimised_poses, "after loop closure")):
            ax.imshow(1.0 - mp.probability(), cmap="gray", origin="lower", extent=_extent(m), vmin=0, vmax=1)
            if res.ground_truth_poses is not None:
                ax.plot(res.ground_truth_poses[:, 0], res.ground_truth_poses[:, 1], color="tab:green",
                        lw=0.8, label="ground truth")
            ax.plot(poses[:, 0], poses[:, 1], color="tab:blue", lw=0.8, label="estimate")
            for lc in res.loops:
                a, b = res.optimised_poses[lc.i], res.optimised_poses[lc.j]
                ax.plot([a[0], b[0]], [a[1], b[1]], color="tab:red", lw=0.5)
            ax.set_title(title)
            ax.legend(loc="upper right", fontsize=7)
        fig.suptitle(f"{res.name}: {res.metrics.get('ate_frontend_m', float('nan')):.3f} m -> "
                     f"{res.metrics.get('ate_rmse_m', float('nan')):.3f} m ATE, "
                     f"IoU {res.metrics.get('map_iou', float('nan')):.3f}")
        fig.tight_layout()
        fig.savefig(file_in(plots, f"map_{k:02d}_{res.name}", ".png", "world name"), dpi=100)
        plt.close(fig)


def _extent(m: LogOddsMap) -> list[float]:
    h, w = m.shape
    return [m.origin_xy_m[0], m.origin_xy_m[0] + w * m.resolution_m,
            m.origin_xy_m[1], m.origin_xy_m[1] + h * m.resolution_m]


def _scale_bar_m(width_m: float) -> float:
    """A round length (1, 2 or 5 x 10^k m) of about a fifth of ``width_m``."""
    target = max(width_m / 5.0, 1e-3)
    k = 10.0 ** np.floor(np.log10(target))
    return float(max(m * k for m in (1.0, 2.0, 5.0) if m * k <= target))


def log_map_title(res: LidarSlamResult) -> str:
    """Log, motion prior, relation error when the log has relations, map consistency, real-time factor."""
    m = res.metrics
    head = f"{res.name}, motion prior {res.config.motion_prior}"
    if "relation_trans_mean_m" in m:
        bad = int(m.get("relations_over_0_2_m", 0))
        worst = float(np.max(res.relations.errors_m)) if res.relations is not None else float("nan")
        rel = (f"relation error {m['relation_trans_mean_m']:.3f} +- {m['relation_trans_std_m']:.3f} m over "
               f"{int(m['relation_count'])} relations; {bad} above {BAD_RELATION_M:g} m (max {worst:.2f} m)")
    else:
        rel = "no relations shipped for this log"
    cons = (f"map consistency {m.get('map_consistency_mean_m', float('nan')):.3f} m "
            f"(95%: {m.get('map_consistency_p95_m', float('nan')):.3f} m, "
            f"along one pass {m.get('map_consistency_same_pass_mean_m', float('nan')):.3f} m, "
            f"{100 * m.get('map_consistency_overlap', 0.0):.0f}% of end points seen twice); "
            f"real-time factor {m.get('real_time_factor', float('nan')):.1f}")
    return f"{head}\n{rel}\n{cons}"


def log_map_figure(plt, res: LidarSlamResult):
    """The map in metres (one pixel per cell up to 25 inches), the trajectory of every scan, a
    scale bar, and the relations whose error exceeds :data:`BAD_RELATION_M` as segments between
    the estimated poses at their two stamps, coloured by their error (a dot at each, so that a
    relation between close poses shows too): where the map is wrong."""
    from matplotlib.collections import LineCollection
    from matplotlib.colors import Normalize
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    m = res.map
    h, w = m.shape
    # the map's inches at 100 dpi, and the figure's: margins for the axes' labels, the colour bar
    # and three lines of title
    map_w, map_h = np.array([w, h]) * min(1.0, 2500.0 / max(w, h)) / 100.0
    fig_w, fig_h = max(map_w, 6.0) + 2.4, map_h + 1.5
    fig = plt.figure(figsize=(fig_w, fig_h), dpi=100)
    ax = fig.add_axes((0.9 / fig_w, 0.6 / fig_h, map_w / fig_w, map_h / fig_h))
    extent = _extent(m)
    # a map shrunk to fit (the hospital: 7000 cells across) is averaged, so one-cell walls stay grey
    # lines instead of vanishing between the pixels nearest-neighbour sampling keeps
    ax.imshow(1.0 - m.probability(), cmap="gray", origin="lower", extent=extent, vmin=0, vmax=1,
              interpolation="antialiased")
    ax.plot(res.scan_poses[:, 0], res.scan_poses[:, 1], color="tab:blue", lw=0.6, alpha=0.7, label="trajectory")
    seg = res.relation_segments
    if seg is not None and len(seg):
        bad = seg[seg[:, 4] > BAD_RELATION_M]
        if len(bad):
            norm = Normalize(BAD_RELATION_M, max(float(bad[:, 4].max()), 2 * BAD_RELATION_M))
            cmap = plt.get_cmap("autumn_r")
            lines = LineCollection(bad[:, :4].reshape(-1, 2, 2), cmap=cmap, norm=norm, linewidths=2.0, zorder=3)
            lines.set_array(bad[:, 4])
            ax.add_collection(lines)
            ax.scatter(np.r_[bad[:, 0], bad[:, 2]], np.r_[bad[:, 1], bad[:, 3]], c=np.r_[bad[:, 4], bad[:, 4]],
                       cmap=cmap, norm=norm, s=14, edgecolors="k", linewidths=0.3, zorder=4,
                       label=f"{len(bad)} relation{'s' * (len(bad) != 1)} off by > {BAD_RELATION_M:g} m")
            cax = fig.add_axes(((1.0 + map_w) / fig_w, 0.6 / fig_h, 0.15 / fig_w, 0.6 * map_h / fig_h))
            fig.colorbar(lines, cax=cax, label="relation error (m)")
    bar_m = _scale_bar_m(extent[1] - extent[0])
    ax.add_artist(AnchoredSizeBar(ax.transData, bar_m, f"{bar_m:g} m", "lower right", pad=0.6, color="k",
                                  frameon=True, size_vertical=(extent[3] - extent[2]) / 300.0))
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="upper left", fontsize=8)
    fig.suptitle(log_map_title(res), fontsize=10, x=(0.9 + 0.5 * map_w) / fig_w, y=1.0 - 0.05 / fig_h, va="top")
    return fig


def _plot_log(plt, plots, res: LidarSlamResult) -> None:
    """The map with the trajectory and the wrong relations over it (:func:`log_map_figure`), and
    the time per scan along the log."""
    fig = log_map_figure(plt, res)
    fig.savefig(file_in(plots, f"map_{res.label}", ".png", "log name"), dpi=100)
    plt.close(fig)
    step_ms = 1e3 * np.asarray(res.scan_step_s)
    fig, ax = plt.subplots(figsize=(9, 3.5))
    t = res.scan_stamps_s - res.scan_stamps_s[0]
    ax.plot(t, step_ms, ".", ms=1.5, alpha=0.4, color="0.5", label="per scan")
    window = max(1, len(step_ms) // 100)
    ax.plot(t[window - 1:], np.convolve(step_ms, np.ones(window) / window, mode="valid"), color="tab:blue",
            label=f"mean over {window} scans")
    period_ms = 1e3 * float(np.median(np.diff(res.scan_stamps_s)))
    ax.axhline(period_ms, color="tab:red", lw=0.8, label="scan period (real time)")
    ax.axhline(period_ms / 10, color="tab:red", lw=0.8, ls="--", label="scan period / 10")
    ax.set_yscale("log")
    ax.set_xlabel("log time (s)")
    ax.set_ylabel("processing time (ms)")
    ax.set_title(f"{res.label}: time per scan (real-time factor {res.metrics['real_time_factor']:.1f})")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(file_in(plots, f"time_per_scan_{res.label}", ".png", "log name"), dpi=100)
    plt.close(fig)
