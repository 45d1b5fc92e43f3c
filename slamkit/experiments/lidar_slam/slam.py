"""One sequence through :class:`slamkit.systems.lidar_slam.LidarSlam`, timed and scored:
:func:`run_slam` and its :class:`LidarSlamResult` (keyframe ATE before and after loop closure and
of the odometry, map quality against a true grid, relation errors and map consistency on a
laser log, injected false loop closures), the published figures the report sets beside them
(:data:`PUBLISHED`, :data:`CARTOGRAPHER_REALTIME_FACTOR`), and the typed keyframe snapshot the
viewer gets (:class:`LidarSlamSnapshot`)."""

from __future__ import annotations

import resource
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from slamkit.data.pose_graph import PoseGraph
from slamkit.data.sequence import Odometry, Scan, Sequence
from slamkit.data.trajectory import Trajectory
from slamkit.errors import ConfigError
from slamkit.experiments.observers import StepSnapshot
from slamkit.frontend.loop_closure import LoopClosure
from slamkit.geometry import se2
from slamkit.maps.log_odds import LogOddsMap, MapQuality, map_quality
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.metrics.alignment import align
from slamkit.metrics.loop_closures import loop_closure_counts
from slamkit.metrics.map_consistency import map_consistency
from slamkit.metrics.relations import RelationErrors, relation_errors
from slamkit.metrics.trajectory_score import ate_at_stamps_m, poses_at_stamps
from slamkit.models import diff_drive
from slamkit.systems.lidar_slam import Keyframe, LidarSlam, LidarSlamConfig
from slamkit.systems.slam_map import config_for


#: mean +- std of the translational relation error (m) published by Kuemmerle et al., "On
#: measuring the accuracy of SLAM algorithms", Autonomous Robots 27(4), 2009 (as transcribed in
#: the datasets' MANIFEST): scan matching, RBPF (GMapping, 50 particles), graph mapping
PUBLISHED: dict[str, dict[str, tuple[float, float]]] = {
    "intel": {"scan matching": (0.220, 0.296), "RBPF (50 particles)": (0.070, 0.083),
              "graph mapping": (0.031, 0.026)},
    "fr079": {"scan matching": (0.258, 0.427), "RBPF (50 particles)": (0.061, 0.044),
              "graph mapping": (0.056, 0.042)},
    "mit-csail": {"scan matching": (0.106, 0.325), "RBPF (50 particles)": (0.049, 0.049),
                  "graph mapping": (0.004, 0.009)},
    "fr-clinic": {"scan matching": (0.434, 1.615), "RBPF (50 particles)": (0.637, 2.638),
                  "graph mapping": (0.143, 0.180)},
}

#: real-time factor (log duration / wall-clock time) of Cartographer (Hess et al., "Real-Time Loop
#: Closure in 2D LIDAR SLAM", ICRA 2016, sec. VI, one Xeon E5-1650): Intel 2691 s of data in
#: 179 s, FR079 1061 s in 62 s, MIT CSAIL 424 s in 35 s
CARTOGRAPHER_REALTIME_FACTOR: dict[str, float] = {"intel": 15.0, "fr079": 17.0, "mit-csail": 12.0}

#: relations whose translational error exceeds this are drawn on the map plots (m)
BAD_RELATION_M = 0.2

#: the map consistency figure scores every n-th end point (all of them are the reference):
#: measured on the hospital's first 2280 keyframes (front end), every end point 0.2196 m in 7.5 s
#: of CPU, every 4th 0.2190 m in 4.8 s
CONSISTENCY_QUERY_EVERY = 4


@dataclass(frozen=True)
class LidarSlamResult:
    """Everything one run produced. Keyframe arrays are (K, 3); ``scan_stamps_s`` (N,) and
    ``scan_poses`` (N, 3) the trajectory of every scan; ``keyframe_points[k]`` keyframe k's
    despeckled scan end points in the body frame, ``keyframe_ranges_m[k]`` / ``keyframe_angles_rad[k]``
    its lidar ranges (NaN: no return) and beam angles. ``map`` / ``frontend_map`` are built from
    the optimised / front-end poses; when the world's grid is known they are built after the
    SE(2) alignment to the ground truth that ATE uses (so they can be scored cell by cell),
    otherwise in the estimate's frame (None when the run was asked not to build them).
    ``scan_step_s`` is the processing time of every scan."""

    name: str
    stamps_s: np.ndarray
    odometry_poses: np.ndarray
    frontend_poses: np.ndarray
    optimised_poses: np.ndarray
    ground_truth_poses: np.ndarray | None
    keyframe_points: tuple[np.ndarray, ...]
    graph: PoseGraph
    loops: tuple[LoopClosure, ...]
    false_loops: tuple[tuple[int, int], ...]
    map: LogOddsMap | None
    frontend_map: LogOddsMap | None
    metrics: Mapping[str, float]
    quality: MapQuality | None = None
    keyframe_angles_rad: tuple[np.ndarray, ...] = ()
    keyframe_ranges_m: tuple[np.ndarray, ...] = ()
    max_range_m: float = 20.0
    config: LidarSlamConfig = field(default_factory=LidarSlamConfig)
    truth: OccupancyGrid | None = None
    scan_stamps_s: np.ndarray | None = None
    scan_poses: np.ndarray | None = None
    scan_step_s: np.ndarray | None = None
    relations: RelationErrors | None = None
    label: str = ""
    body_xytheta_lidar: np.ndarray = field(default_factory=lambda: np.zeros(3))
    #: (R, 5) per scored relation: the estimated positions at its two stamps (x1, y1, x2, y2, m)
    #: and its translational error (m)
    relation_segments: np.ndarray | None = None

    def sensor_poses(self, world_xytheta_body: np.ndarray) -> np.ndarray:
        return se2.compose(np.asarray(world_xytheta_body, float).reshape(-1, 3), self.body_xytheta_lidar)


def false_loop_edges(poses: np.ndarray, n: int, rng: np.random.Generator, min_separation_m: float = 10.0,
                     information: np.ndarray | None = None) -> tuple[list[tuple[int, int]], np.ndarray, np.ndarray]:
    """``n`` wrong closures: pairs more than ``min_separation_m`` apart claimed to coincide."""
    info = np.diag([400.0, 400.0, 2500.0]) if information is None else information
    pairs: list[tuple[int, int]] = []
    tries = 0
    while len(pairs) < n and tries < 10000:
        tries += 1
        i, j = sorted(rng.choice(len(poses), size=2, replace=False))
        if np.hypot(*(poses[i, :2] - poses[j, :2])) > min_separation_m and (i, j) not in pairs:
            pairs.append((int(i), int(j)))
    return pairs, np.zeros((len(pairs), 3)), np.repeat(info[None], len(pairs), axis=0)


def align_se2(poses: np.ndarray, reference: np.ndarray, stamps_s: np.ndarray) -> np.ndarray:
    """``poses`` (K, 3) moved by the SE(2) Umeyama alignment onto ``reference`` (K, 3)."""
    a = align(Trajectory.from_se2(stamps_s, poses), Trajectory.from_se2(stamps_s, reference), "se2")
    R, t = a.rotation[:2, :2], a.translation[:2]
    yaw = np.arctan2(R[1, 0], R[0, 0])
    return np.column_stack([poses[:, :2] @ R.T + t, se2.compose(np.array([0.0, 0.0, yaw]), poses)[:, 2]])


def _frozen(a: Any) -> np.ndarray:
    """A read-only float copy (a snapshot never shares memory with the live system)."""
    out = np.array(a, dtype=float, copy=True)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class LidarSlamSnapshot:
    """The state of a ``lidar_slam`` step snapshot (issue 30, item 4: a type, not a dict of
    string keys), one per keyframe as it is added: its pose when added ``world_xytheta_body`` (3,)
    and its scan ``body_p_scan`` (N, 2) in the body frame -- read-only copies, never the live
    :class:`~slamkit.systems.lidar_slam.LidarSlam`."""

    world_xytheta_body: np.ndarray
    body_p_scan: np.ndarray

    @classmethod
    def of(cls, kf: Keyframe) -> "LidarSlamSnapshot":
        return cls(_frozen(kf.world_xytheta_body), _frozen(np.asarray(kf.body_xy_points).reshape(-1, 2)))


class _KeyframeSnapshots:
    """Adapter: the system's keyframe hook -> the pipeline observer's per-step snapshots, whose
    state is a :class:`LidarSlamSnapshot`."""

    def __init__(self, observer, name: str):
        self.observer, self.name = observer, name

    def on_keyframe(self, kf: Keyframe) -> None:
        self.observer.on_step(StepSnapshot("lidar_slam", self.name, kf.index, kf.stamp_s, LidarSlamSnapshot.of(kf)))

    def on_loop_closure(self, closure: LoopClosure) -> None:
        pass


def run_slam(sequence: Sequence, truth: OccupancyGrid | None = None,
             config: LidarSlamConfig = LidarSlamConfig(), observer=None, false_loop_closures: int = 0,
             false_loop_seed: int = 0, relations=None, label: str = "", build_maps: bool = True) -> LidarSlamResult:
    """Feed ``sequence`` to a :class:`LidarSlam` (timing every event), inject
    ``false_loop_closures`` wrong edges, finish, build the maps (covering ``truth``'s area when
    given) and score: ATE against the ground truth, map quality against ``truth``, relation
    errors against ``relations`` (a :class:`~slamkit.metrics.relations.Relations`).
    ``build_maps`` False (only without ``truth``, which they are scored against) leaves the maps
    out of the result: a perturbed twin of a log is scored, not drawn, and the Freiburg hospital's
    two maps (400 m x 300 m at 5 cm, rays to 82 m) take about 6 minutes of a run's 7."""
    if not build_maps and truth is not None:
        raise ConfigError("run_slam: the maps are scored against truth, so build_maps must be True with it")
    config = config_for(sequence, config)
    hooks = _KeyframeSnapshots(observer, sequence.name) if observer is not None and observer.wants_steps else None
    system = LidarSlam(config, sequence.initial_world_xytheta_body, hooks, name=sequence.name)
    odom = (np.zeros(3) if sequence.initial_world_xytheta_body is None
            else np.asarray(sequence.initial_world_xytheta_body, float).reshape(3))
    odom_at_scan, scan_step = [], []
    clock = time.perf_counter
    cpu_start = time.process_time()
    t_start = clock()
    for ev in sequence:
        t0 = clock()
        system.step(ev)
        if isinstance(ev, Scan):
            scan_step.append(clock() - t0)
            odom_at_scan.append(odom)
        elif isinstance(ev, Odometry):
            odom = np.asarray(diff_drive.motion(odom, np.array([ev.v_mps, ev.omega_radps]), ev.dt_s))
    before = system.estimate()
    rng = np.random.default_rng(false_loop_seed)
    false_pairs, false_meas, false_info = false_loop_edges(before.keyframe_poses, false_loop_closures, rng)
    for (i, j), z, info in zip(false_pairs, false_meas, false_info):
        system.add_constraint(i, j, z, info)
    t_finish = clock()
    est = system.finish()
    t_end = clock()
    cpu_s = time.process_time() - cpu_start
    points, ranges, angles = system.keyframe_scans()
    stamps = est.keyframe_stamps_s
    poses, fe_poses = est.keyframe_poses, est.frontend_poses
    odom_at_scan = np.asarray(odom_at_scan).reshape(-1, 3)
    # the system skips nothing: scan n of the sequence is scan n of the estimate
    odo_kf = odom_at_scan[est.keyframe_scans]
    gt_poses = None
    map_poses, fe_map_poses = poses, fe_poses
    if sequence.ground_truth is not None:
        gt_poses = poses_at_stamps(sequence.ground_truth, stamps)
        if truth is not None:
            # SLAM fixes the map only up to a rigid motion: score it in the frame of the same SE(2)
            # alignment ATE uses (an early heading error would otherwise count on every wall)
            map_poses = align_se2(poses, gt_poses, stamps)
            fe_map_poses = align_se2(fe_poses, gt_poses, stamps)
    t_map = clock()
    slam_map = system.map(config.map, map_poses, like=truth) if build_maps else None
    fe_map = system.map(config.map, fe_map_poses, like=truth) if build_maps else None
    time_map = clock() - t_map
    c = est.counters
    metrics: dict[str, float] = {
        "num_keyframes": float(len(poses)), "num_scans": float(len(est.stamps_s)),
        "num_loop_closures": float(len(est.loops)),
        "loop_closures_online": float(c.loop_closures_online),
        "loop_closures_final": float(c.loop_closures_final),
        "loop_candidates": float(c.loop_candidates),
        "loop_closures_rejected": float(c.loop_closures_rejected),
        "num_false_loop_closures": float(len(false_pairs)),
        "icp_iterations_mean": c.icp_iterations / max(c.matched_scans, 1),
        "icp_fallbacks": float(c.match_fallbacks),
        "wide_searches": float(c.wide_searches),
        "correlative_searches": float(c.correlative_searches),
        "correlative_wins": float(c.correlative_wins),
        # the global loop search's share, the odometry checks and iSAM2's QR fallbacks
        "loop_candidates_global": float(c.loop_candidates_global),
        "loop_closures_global": float(c.loop_closures_global),
        "odometry_checks": float(c.odometry_checks),
        "odometry_check_wins": float(c.odometry_check_wins),
        "isam2_qr_fallbacks": float(c.isam2_qr_fallbacks),
        "lost_restarts": float(c.lost_restarts),
        "loop_global_far_rejected": float(c.loop_global_far_rejected),
        "loop_global_ambiguous_rejected": float(c.loop_global_ambiguous_rejected),
    }
    duration = float(est.stamps_s[-1] - est.stamps_s[0])
    total = t_end - t_start
    step = np.asarray(scan_step)
    tenth = max(1, len(step) // 10)
    if build_maps:
        metrics["time_map_s"] = time_map
    metrics.update(time_total_s=total, time_finish_s=t_end - t_finish,
                   real_time_factor=duration / total, log_duration_s=duration,
                   time_cpu_s=cpu_s, real_time_factor_cpu=duration / cpu_s,
                   time_per_scan_median_ms=1e3 * float(np.median(step)),
                   time_per_scan_p99_ms=1e3 * float(np.percentile(step, 99)),
                   time_per_scan_last_over_first=float(np.mean(step[-tenth:]) / np.mean(step[:tenth])),
                   peak_rss_mb=_peak_rss_mb())
    if sequence.ground_truth is not None:
        before_m = ate_at_stamps_m(sequence.ground_truth, stamps, fe_poses)
        after_m = ate_at_stamps_m(sequence.ground_truth, stamps, poses)
        metrics.update(ate_odometry_m=ate_at_stamps_m(sequence.ground_truth, stamps, odo_kf),
                       ate_frontend_m=before_m, ate_rmse_m=after_m, ate_reduction=before_m / max(after_m, 1e-12))
    if sequence.name in CARTOGRAPHER_REALTIME_FACTOR:
        # how many times faster than real time, against Cartographer's published factor
        metrics["real_time_factor_vs_cartographer"] = metrics["real_time_factor"] / CARTOGRAPHER_REALTIME_FACTOR[sequence.name]
    # the map consistency figure (no ground truth) of the scans in the map's frame
    t_consistency = clock()
    consistency = map_consistency(se2.compose(map_poses, np.asarray(config.body_xytheta_lidar, float)), angles,
                                  ranges, config.max_range_m, query_every=CONSISTENCY_QUERY_EVERY)
    metrics.update(consistency.as_metrics(), time_consistency_s=clock() - t_consistency)
    quality = None
    if truth is not None:
        quality = map_quality(slam_map, truth)
        metrics.update(quality.as_metrics("map_"))
        metrics["map_frontend_iou"] = map_quality(fe_map, truth).iou
    rel = segments = None
    if relations is not None:
        rel = relation_errors(est.stamps_s, est.world_xytheta_body, relations)
        metrics.update({k: float(v) for k, v in rel.to_dict().items()})
        metrics["relations_over_0_2_m"] = float(np.sum(rel.errors_m > BAD_RELATION_M))
        segments = _relation_segments(est.stamps_s, est.world_xytheta_body, relations, rel)
        # the loop closures' precision and recall against the relations between revisits
        ij = np.array([[lc.i, lc.j] for lc in est.loops], dtype=int).reshape(-1, 2)
        counts = loop_closure_counts(stamps[ij], np.array([lc.i_T_j for lc in est.loops], float).reshape(-1, 3),
                                     est.stamps_s, est.world_xytheta_body, relations)
        metrics.update({k: float(v) for k, v in counts.to_dict().items()})
        odo_rel = relation_errors(est.stamps_s, odom_at_scan, relations)
        metrics.update(relation_trans_mean_m_odometry=odo_rel.translation_m.mean,
                       relation_trans_std_m_odometry=odo_rel.translation_m.std,
                       relation_rot_mean_deg_odometry=odo_rel.rotation_deg.mean,
                       relation_rot_std_deg_odometry=odo_rel.rotation_deg.std)
    return LidarSlamResult(sequence.name, stamps, odo_kf, fe_poses, poses, gt_poses, points,
                           system.graph(), est.loops, tuple(false_pairs), slam_map, fe_map, metrics,
                           quality, angles, ranges, system.max_range_m, config, truth, est.stamps_s,
                           est.world_xytheta_body, step, rel, label or sequence.name,
                           np.asarray(config.body_xytheta_lidar, float), segments)


def _relation_segments(stamps_s: np.ndarray, poses: np.ndarray, relations, errors: RelationErrors) -> np.ndarray:
    """(R, 5): x1, y1, x2, y2 of the estimated poses nearest each scored relation's two stamps
    (the scans' ipc stamps, as the relation error matched them) and its error (m)."""
    order = np.argsort(stamps_s, kind="stable")
    t, xy = np.asarray(stamps_s)[order], np.asarray(poses)[order, :2]
    k = errors.index

    def at(query):
        i = np.clip(np.searchsorted(t, query), 1, len(t) - 1)
        return xy[np.where(np.abs(query - t[i - 1]) <= np.abs(t[i] - query), i - 1, i)]

    return np.column_stack([at(relations.t1_s[k]), at(relations.t2_s[k]), errors.errors_m])


def _peak_rss_mb() -> float:
    """The process's peak resident memory so far (MB; Linux reports ru_maxrss in KiB)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024.0 ** 2 if sys.platform == "darwin" else 1024.0)
