"""Lidar SLAM as a running system: fed 2D scans (and wheel odometry when there is any), it keeps
a keyframe pose graph, closes loops and returns the trajectory of every scan and an occupancy
map. It knows nothing of ground truth, files or reports (``slamkit.experiments.lidar_slam``
feeds it a Sequence and scores it).

The method is graph-based SLAM with a scan-matching front-end (Lu & Milios, "Globally
consistent range scan alignment", Autonomous Robots 4, 1997; Grisetti et al., "A tutorial on
graph-based SLAM", IEEE ITS Magazine 2010; the local/global split of Cartographer, Hess et al.,
"Real-time loop closure in 2D LIDAR SLAM", ICRA 2016):

1. Every scan is despeckled (``slamkit.frontend.preprocess``), turned into body-frame points
   (``body_xytheta_lidar``: where the lidar sits on the robot) and matched by point-to-line ICP
   (``slamkit.frontend.icp``) against a local submap -- the last ``submap_keyframes`` keyframes'
   points in the newest keyframe's frame, placed at their graph or front-end poses
   (``submap_poses``) and optionally reduced to one point per ``icp.target_voxel_m`` cell so
   that the normals span the walls -- starting from the ``motion_prior``: the wheel
   odometry since the previous scan (``odometry``), the previous scan-to-scan motion
   (``constant_velocity``, lidar only) or no motion (``identity``). Lidar only, the heading of
   the start is searched first (``rotation_search_deg``), and an uncertain match can be retried
   from a correlative search over (dx, dy, dtheta) (``slamkit.frontend.correlative``; off by
   default). With odometry, a match that fits poorly or whose odometry disagrees with the
   constant-velocity prediction (``odometry_check_deg`` / ``_m``: odometry that froze, then jumped)
   is repeated from the best heading around the odometry, the prediction and the previous pose,
   the fitter kept. A match whose fitness is below ``min_match_fitness`` keeps the prior instead
   (lidar only: the previous scan's pose; after ``lost_restart_s`` of failed matches in a row
   the scan becomes a keyframe there anyway, on a weak edge, and the submap restarts from it).
2. Keyframes by travelled distance/rotation (``slamkit.frontend.keyframes``) of the matched
   pose. A new keyframe becomes a pose-graph vertex with an edge from the previous keyframe
   (the ICP result and its covariance). Every other scan is stored relative to its keyframe, so
   its pose follows the keyframe's when the graph moves.
3. Loop closures, at every new keyframe j: the earlier keyframes within ``loops.search_radius_m``
   of j in the current estimate (a KD-tree over keyframe positions, rebuilt only when the
   estimate moved), at least ``loops.min_path_gap_m`` of path back, the closest
   ``loops.max_candidates_per_keyframe``, each verified by ICP of j's scan against a submap
   around i (fitness, plausibility: ``slamkit.frontend.loop_closure.verify_loop``). When none is
   accepted (or always, ``loops.global_after_local_closure``) and the drift bound of the
   scan-match chain and the closures (``slamkit.frontend.loop_closure.DriftRegion``) makes the
   ``loops.region_probability`` chi-square region (0: off, the default) reach beyond that radius, the region's most likely candidates
   (``loops.max_global_candidates_per_keyframe``, within ``loops.max_search_radius_m``) are
   matched globally: branch and bound over the region's window (metres, tens of degrees;
   ``slamkit.frontend.branch_and_bound``), its optimum seeding the same ICP verification, and the
   closure kept only if it lies inside the region (and, with ``loops.global_far_max_rival``, a far
   one only if no other place of the window fits almost as well: off by default). When still none
   is accepted and ``loops.scan_context`` is set (off by default), place recognition proposes candidates beyond
   any window: keyframe j's Scan Context (``slamkit.frontend.scan_context``; the scans of its
   last few metres stacked in its frame) against every earlier keyframe's, among those the drift
   region (uncapped) admits, matched by branch and bound around the place and the descriptor's
   yaw and verified by ICP like a far global closure. Accepted closures enter the graph with the
   ``robust`` kernel (Cauchy by default), so a wrong one that slipped through is bounded.
4. The graph is solved incrementally with iSAM2 (``slamkit.backend.Isam2PoseGraph``) at every
   keyframe. ``finish()`` runs ``loop_rounds`` more rounds of loop search over all keyframe pairs
   in the final estimate and one batch Levenberg-Marquardt solve with the robust kernel on the
   loop closures (the scan-match chain stays least squares, as in iSAM2); a loop
   closure still in strong disagreement with the solution (whitened residual above
   ``loop_chi2_max``) is dropped and the graph solved once more (the consistency check).
5. ``map()``: a log-odds grid (``slamkit.maps.log_odds``) from the keyframe scans at their
   estimated sensor poses.

Observers (the recorder) subscribe through :class:`LidarSlamObserver`: ``on_keyframe`` and
``on_loop_closure``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field, replace
from typing import Literal, Protocol

import numpy as np
from scipy.spatial import cKDTree

from slamkit.backend.isam2 import Isam2Params, Isam2PoseGraph
from slamkit.backend.solvers import OptimizeConfig, optimize
from slamkit.data.sequence import Event, Odometry, Scan, Sequence
from slamkit.errors import ConfigError, DataError
from slamkit.frontend.correlative import CorrelativeConfig, CorrelativeGrid, correlative_search
from slamkit.frontend.icp import IcpConfig, IcpResult, IcpTarget, icp, rotation_search, scan_to_points
from slamkit.frontend.keyframes import KeyframeConfig
from slamkit.frontend.branch_and_bound import MaxGridPyramid, branch_and_bound_search, rival_search
from slamkit.frontend.loop_closure import (DriftRegion, LoopClosure, LoopClosureConfig, chi2_quantile, loop_candidates,
                                          verify_loop)
from slamkit.frontend.preprocess import despeckle, voxel_downsample
from slamkit.frontend.scan_context import ScanContextDatabase, scan_context
from slamkit.geometry import se2
from slamkit.maps.log_odds import LogOddsConfig, LogOddsMap
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.models import diff_drive

MOTION_PRIORS = ("odometry", "constant_velocity", "identity")
#: without odometry, a scan match below this fitness is retried with a four times wider heading search
WIDE_SEARCH_BELOW_FITNESS = 0.5
#: the odometry check (``LidarSlamConfig.odometry_check_deg``) only between scans at most this far
#: apart in time (Intel's ipc stamps put consecutive scans up to 3.5 s apart, FR079 0.64 s, MIT
#: 0.22 s: none of them is affected). Why: Intel with four 45 s lidar blackouts (tests/systems, the
#: revisits after drift) measured 1.585 m relation error with the check after every gap (0.074 m
#: before the check)
ODOMETRY_CHECK_MAX_GAP_S = 5.0


@dataclass(frozen=True)
class LidarSlamConfig:
    keyframes: KeyframeConfig = KeyframeConfig()
    #: scan-to-submap matching: the new scan sees places the submap does not (and vice versa),
    #: so the worst 10% of correspondences are trimmed (measured on a 20 m warehouse tour:
    #: front-end ATE 0.011 m trimmed vs 0.154 m untrimmed)
    icp: IcpConfig = IcpConfig(trim_fraction=0.9)
    loops: LoopClosureConfig = LoopClosureConfig(icp=IcpConfig(trim_fraction=0.9))
    #: rounds of loop search over all keyframe pairs in ``finish()`` (each followed by a solve)
    loop_rounds: int = 2
    robust: str = "cauchy"
    submap_keyframes: int = 3
    #: the scan-matching submap's keyframes are placed at their ``graph`` poses (moved by loop
    #: closures) or at their ``frontend`` poses (the chained matches, as Cartographer's local
    #: SLAM: a wrong loop closure that pulls two recent keyframes apart cannot double the walls
    #: the next scans are matched against)
    submap_poses: Literal["graph", "frontend"] = "graph"
    #: the consistency check of ``finish()``: a loop closure whose whitened squared residual at the
    #: robust solution exceeds this (the 99.9% quantile of chi-square with 3 dof) is dropped
    #: (with ``robust: none`` the graph is plain least squares: no check either)
    loop_chi2_max: float = 16.27
    #: keyframes on either side of i in the loop-closure target (0: keyframe i's scan alone)
    loop_submap_keyframes: int = 0
    #: a scan match is replaced by the motion prior when its fitness is below this
    min_match_fitness: float = 0.3
    #: ``odometry`` (wheel odometry since the previous scan), ``constant_velocity`` (the previous
    #: scan-to-scan motion, scaled to the time since the previous scan) or ``identity``
    motion_prior: Literal["odometry", "constant_velocity", "identity"] = "odometry"
    #: ``constant_velocity`` repeats the previous motion per ``second`` (scaled to the time since
    #: the previous scan) or per ``scan`` (unscaled: for stamps that do not say when a scan was
    #: taken, such as the CARMEN logs' ipc receive stamps -- on Intel 10% of the scans are < 1 ms
    #: apart, the time between scans and the motion between them correlate at 0.11, and the
    #: previous motion predicts the next one to 0.023 m mean unscaled, 0.055 m scaled)
    constant_velocity_per: Literal["second", "scan"] = "second"
    #: without odometry (``motion_prior`` other than ``odometry``), search the heading within
    #: +- this many degrees before ICP, from the prior and from the previous scan's pose (the
    #: robot may have stopped), and start from the better (``slamkit.frontend.icp.rotation_search``;
    #: 0: off). Measured on the first 120 s of Intel lidar only: relation error 0.066 +- 0.129 m
    #: without (a turn on the spot matched 18 deg off), 0.036 +- 0.052 m with +-10 deg
    rotation_search_deg: float = 10.0
    #: with odometry, the match from the odometry prior is checked: when its fitness is below
    #: 0.5 or the odometry disagrees with the constant-velocity prediction (the previous matched
    #: scan-to-scan motion) by more than ``odometry_check_deg`` or ``odometry_check_m``, the match
    #: is repeated from the best heading (+-``rotation_search_deg``) around the odometry, the
    #: prediction and the previous scan's pose, and the fitter of the two kept (0 and 0: only the
    #: fitness test). Why: MIT CSAIL's scan-synchronous odometry freezes for a few scans during
    #: turns and then jumps (scans 1580-1584: 0, 0, 0, then 85 deg where the scans turned 14-17 deg
    #: each), and ICP from 70 deg off matched a corridor backwards (-164 deg, fitness 0.74); a
    #: revisit was drawn twice. Whole logs, odometry: MIT map consistency 0.143 -> 0.062 m (427
    #: checks, 82 won), Intel 0.0152 m relation error (118 checks), FR079 0.0311 m (was 0.0313)
    odometry_check_deg: float = 5.0
    odometry_check_m: float = 0.1
    #: without odometry, a match (after the heading searches) is uncertain when its fitness is
    #: below ``correlative_below_fitness`` or it turned more than ``correlative_above_turn_deg``
    #: from the previous scan (Intel: up to 50 deg between two ipc stamps); it is then retried
    #: from the best pose of a correlative search around the guess (``slamkit.frontend.correlative``,
    #: window ``correlative``) and the match with the higher fitness is kept. Off by default
    #: (fitness 0, turn 180): on the whole Intel log it did not help (see pipelines/lidar_slam_logs.yaml)
    correlative: CorrelativeConfig = CorrelativeConfig()
    correlative_below_fitness: float = 0.0
    correlative_above_turn_deg: float = 180.0
    #: match every scan (True) or only the scans that the prior already makes keyframes
    match_every_scan: bool = True
    #: search loop closures at every new keyframe (False: only in ``finish()``)
    online_loop_closure: bool = True
    #: the lidar's pose in the body frame (x, y, theta)
    body_xytheta_lidar: tuple[float, float, float] = (0.0, 0.0, 0.0)
    despeckle_jump_m: float = 0.3
    #: returns beyond this are not used for matching or mapping (None: up to the sensor maximum)
    max_range_m: float | None = None
    #: iSAM2 relinearisation threshold (tangent units) and skip
    isam2: Isam2Params = Isam2Params(relinearize_threshold=0.01, relinearize_skip=1, final_updates=0)
    #: the information of an edge that fell back to the motion prior: sigmas (m, m, rad)
    fallback_sigmas: tuple[float, float, float] = (0.05, 0.05, 0.02)
    #: without odometry, a scan whose match failed stays where the previous one was; after
    #: ``lost_restart_s`` of failed matches in a row (0: never) the robot is lost and the scan
    #: becomes a keyframe there anyway, joined to the previous one by an edge of ``lost_sigmas``
    #: (m, m, rad): the submap restarts from what the robot sees now and the next scans match
    #: again; loop closures place the new piece later (the weak edge lets them). Why (issue 29):
    #: the Freiburg hospital at 2223 s, four scans at a doorway that match neither the submap nor
    #: each other -- standing, the robot's scans never overlapped the submap again, every match
    #: failed until it came back 340 s later, and 100 m of corridor were missing from the map.
    #: Coasting on the constant-velocity prediction while lost instead of standing was measured
    #: and not kept: a 0.30-fitness match in the middle of a turn was coasted for 4 scans and the
    #: map after it turned 180 deg (hospital, whole log: 10 s windows more than 1 m off the
    #: odometry run's motion 16 against 20 standing, but the end 534 m off it against 277 m)
    lost_restart_s: float = 0.0
    lost_sigmas: tuple[float, float, float] = (1.0, 1.0, 0.2)
    map: LogOddsConfig = LogOddsConfig(resolution_m=0.1)

    def __post_init__(self) -> None:
        if self.robust not in ("none", "huber", "cauchy"):
            raise ConfigError(f"lidar_slam.robust must be none, huber or cauchy, got {self.robust!r}")
        if self.motion_prior not in MOTION_PRIORS:
            raise ConfigError(f"lidar_slam.motion_prior must be one of {MOTION_PRIORS}, got {self.motion_prior!r}")
        if self.submap_poses not in ("graph", "frontend"):
            raise ConfigError(f"lidar_slam.submap_poses must be graph or frontend, got {self.submap_poses!r}")
        if self.constant_velocity_per not in ("second", "scan"):
            raise ConfigError(f"lidar_slam.constant_velocity_per must be second or scan, got {self.constant_velocity_per!r}")
        if self.loop_rounds < 0 or self.submap_keyframes < 1 or self.loop_submap_keyframes < 0:
            raise ConfigError("lidar_slam: loop_rounds and loop_submap_keyframes must be >= 0, "
                              "submap_keyframes >= 1")
        if self.odometry_check_deg < 0 or self.odometry_check_m < 0:
            raise ConfigError("lidar_slam: odometry_check_deg and odometry_check_m must be >= 0")
        if not 0 <= self.rotation_search_deg <= 90:
            raise ConfigError(f"lidar_slam.rotation_search_deg must lie in [0, 90], got {self.rotation_search_deg}")
        if not 0 <= self.correlative_below_fitness <= 1 or not 0 <= self.correlative_above_turn_deg <= 180:
            raise ConfigError("lidar_slam: correlative_below_fitness must lie in [0, 1] and "
                              "correlative_above_turn_deg in [0, 180]")
        if self.max_range_m is not None and not self.max_range_m > 0:
            raise ConfigError(f"lidar_slam.max_range_m must be > 0, got {self.max_range_m}")
        # a NaN or infinite sigma would give an edge no information (an indeterminate graph)
        sigmas_ok = all(len(s) == 3 and all(0 < v < np.inf for v in s)
                        for s in (self.fallback_sigmas, self.lost_sigmas))
        if len(self.body_xytheta_lidar) != 3 or not sigmas_ok:
            raise ConfigError("lidar_slam: body_xytheta_lidar is (x, y, theta), fallback_sigmas and lost_sigmas "
                              "three positive finite sigmas")
        if not 0 <= self.lost_restart_s <= 3600:
            raise ConfigError(f"lidar_slam.lost_restart_s must lie in [0, 3600] s, got {self.lost_restart_s}")


@dataclass(frozen=True)
class Keyframe:
    """What an observer sees when keyframe ``index`` is added: its stamp, its pose when added and
    its scan (body-frame points)."""

    index: int
    stamp_s: float
    world_xytheta_body: np.ndarray
    body_xy_points: np.ndarray


@dataclass(frozen=True)
class LidarSlamCounters:
    """What a :class:`LidarSlam` counted so far (issue 30: a type, not a dict read by string keys):
    scans seen and matched, matches replaced by the motion prior (``match_fallbacks``), ICP
    iterations, the heading / correlative searches and the odometry checks with how often the
    retry won, loop-closure candidates and closures by source (local ``loop_candidates`` /
    ``loop_closures_online``, the drift region's ``*_global``, Scan Context's ``*_place``), the
    closures of ``finish()``'s rounds (``loop_closures_final``) and those its consistency check
    dropped (``loop_closures_rejected``), far global closures refused for low fitness or for a
    rival place in their window (``loop_global_ambiguous_rejected``), the largest
    correction a global closure made (m), iSAM2's QR fallbacks and the submaps restarted after
    ``lost_restart_s`` of failed matches (``lost_restarts``)."""

    scans: int = 0
    matched_scans: int = 0
    match_fallbacks: int = 0
    icp_iterations: int = 0
    wide_searches: int = 0
    correlative_searches: int = 0
    correlative_wins: int = 0
    odometry_checks: int = 0
    odometry_check_wins: int = 0
    loop_candidates: int = 0
    loop_closures_online: int = 0
    loop_closures_final: int = 0
    loop_closures_rejected: int = 0
    loop_candidates_global: int = 0
    loop_closures_global: int = 0
    loop_global_far_rejected: int = 0
    loop_global_ambiguous_rejected: int = 0
    loop_global_correction_max_m: float = 0.0
    loop_candidates_place: int = 0
    loop_closures_place: int = 0
    isam2_qr_fallbacks: int = 0
    lost_restarts: int = 0


@dataclass(frozen=True)
class LidarSlamEstimate:
    """The trajectory of every scan (``stamps_s`` (N,), ``world_xytheta_body`` (N, 3)); the
    keyframes (``keyframe_scans`` indexes into the scans; poses (K, 3); ``frontend_poses``: the
    chained scan matches before any loop closure); the accepted loop closures and the edges that
    were injected from outside (``add_constraint``)."""

    stamps_s: np.ndarray
    world_xytheta_body: np.ndarray
    keyframe_scans: np.ndarray
    keyframe_stamps_s: np.ndarray
    keyframe_poses: np.ndarray
    frontend_poses: np.ndarray
    loops: tuple[LoopClosure, ...]
    injected: tuple[tuple[int, int], ...]
    counters: LidarSlamCounters


class LidarSlamObserver(Protocol):
    def on_keyframe(self, keyframe: Keyframe) -> None: ...

    def on_loop_closure(self, closure: LoopClosure) -> None: ...


class NullLidarSlamObserver:
    def on_keyframe(self, keyframe: Keyframe) -> None:
        pass

    def on_loop_closure(self, closure: LoopClosure) -> None:
        pass


@dataclass
class _KeyframeStore:
    stamps: list[float] = field(default_factory=list)
    scans: list[int] = field(default_factory=list)
    points: list[np.ndarray] = field(default_factory=list)
    ranges: list[np.ndarray] = field(default_factory=list)
    angles: list[np.ndarray] = field(default_factory=list)
    frontend: list[np.ndarray] = field(default_factory=list)
    path_m: list[float] = field(default_factory=list)


class LidarSlam:
    """Streaming lidar SLAM (see the module docstring): ``step(event)`` with Scan and Odometry
    events in time order, ``estimate()``, ``finish()`` (final loop rounds and batch solve) and
    ``map()``. ``initial_world_xytheta_body`` is the pose of the first scan."""

    def __init__(self, config: LidarSlamConfig = LidarSlamConfig(),
                 initial_world_xytheta_body: np.ndarray | None = None,
                 observer: LidarSlamObserver | None = None, name: str = "lidar_slam"):
        self.config = config
        self.observer = observer if observer is not None else NullLidarSlamObserver()
        self._initial = np.zeros(3) if initial_world_xytheta_body is None else \
            np.asarray(initial_world_xytheta_body, float).reshape(3)
        self._body_T_lidar = np.asarray(config.body_xytheta_lidar, dtype=float)
        self._graph = Isam2PoseGraph(config.robust, params=config.isam2, name=name)
        self._graph_qr = config.isam2.factorization == "qr"
        self._kf = _KeyframeStore()
        # per scan: stamp, anchor keyframe, anchor_T_scan
        self._scan_stamps: list[float] = []
        self._scan_anchor: list[int] = []
        self._scan_rel: list[np.ndarray] = []
        self._odom = self._initial.copy()        # integrated wheel odometry at the latest event
        self._odom_at_scan: np.ndarray | None = None
        self._last_motion = np.zeros(3)           # previous scan-to-scan motion (body frame)
        self._last_stamp: float | None = None
        self._last_dt_s = 0.0
        self._lost_since: float | None = None    # stamp of the first of the failed matches in a row
        self._target: IcpTarget | None = None     # submap in the newest keyframe's frame
        self._likelihood: CorrelativeGrid | None = None  # its correlative grid, built on demand
        self._loops: list[LoopClosure] = []
        self._region = DriftRegion(config.loops)
        self._pyramids: dict[int, MaxGridPyramid] = {}   # global-match targets by keyframe, newest last
        self._loop_targets: dict[tuple, IcpTarget | None] = {}   # loop-verification targets, newest last
        sc = config.loops.scan_context
        self._places = ScanContextDatabase(sc) if sc is not None else None
        #: every place-recognition candidate tried: (i, j, descriptor distance, yaw (rad), accepted)
        self.place_candidates: list[tuple[int, int, float, float, bool]] = []
        self._tried: set[tuple[int, int]] = set()
        self._injected: list[tuple[int, int]] = []
        self._edge_kind: list[str] = []
        self._pruned_graph = None
        self._tree: cKDTree | None = None
        self._tree_size = 0
        self._moved_m = 0.0
        self._finished = False
        self._max_range = 0.0                     # the sensor's range, known from the first scan
        #: the running tally behind :attr:`counters` (one entry per LidarSlamCounters field)
        self._counts: dict[str, float] = {f.name: f.default for f in dataclasses.fields(LidarSlamCounters)}

    # ---- streaming ---------------------------------------------------------------------------

    def step(self, event: Event) -> None:
        if isinstance(event, Odometry):
            self._odom = np.asarray(diff_drive.motion(self._odom, np.array([event.v_mps, event.omega_radps]),
                                                      event.dt_s))
        elif isinstance(event, Scan):
            self._scan(event)

    def run(self, sequence: Sequence) -> "LidarSlam":
        """Feed every event of ``sequence``; returns self (call ``finish()`` next)."""
        for event in sequence:
            self.step(event)
        return self

    def _points(self, scan: Scan) -> tuple[np.ndarray, np.ndarray, float]:
        r = despeckle(scan.ranges_m, self.config.despeckle_jump_m)
        max_range = float(scan.max_range_m)
        if self.config.max_range_m is not None:
            max_range = min(max_range, self.config.max_range_m)
            r = np.where(r < max_range, r, np.nan)
        pts = scan_to_points(r, scan.angles_rad, max_range)
        if np.any(self._body_T_lidar != 0):
            pts = se2.transform_points(self._body_T_lidar, pts)
        return pts, r.astype(np.float32), max_range

    def _prior(self, stamp_s: float) -> np.ndarray:
        """The motion since the previous scan that the matcher starts from (body frame)."""
        kind = self.config.motion_prior
        if kind == "odometry":
            return se2.between(self._odom_at_scan, self._odom)
        if kind == "constant_velocity" and self.config.constant_velocity_per == "scan":
            return self._last_motion.copy()
        if kind == "constant_velocity" and self._last_dt_s > 0:
            # scans are not evenly spaced: scale the previous motion to this interval, at most 3x
            return self._last_motion * min((stamp_s - self._last_stamp) / self._last_dt_s, 3.0)
        return np.zeros(3)

    def _scan(self, scan: Scan) -> None:
        if self._finished:
            raise DataError("LidarSlam.step after finish(): start a new LidarSlam")
        cfg = self.config
        pts, ranges, max_range = self._points(scan)
        self._max_range = max_range
        stamp = float(scan.stamp_s)
        n = len(self._scan_stamps)
        self._counts["scans"] += 1
        if not self._kf.stamps:
            self._odom_at_scan = self._odom.copy()
            self._last_stamp = stamp
            self._add_keyframe(n, stamp, pts, ranges, scan.angles_rad, self._initial, None, None)
            self._record_scan(stamp, 0, np.zeros(3))
            return
        prior = self._prior(stamp)
        k = len(self._kf.stamps) - 1
        prev_rel = self._scan_rel[-1] if self._scan_anchor[-1] == k else np.zeros(3)
        guess = se2.compose(prev_rel, prior)       # keyframe k -> this scan
        rel, info = guess, None
        lidar_only = cfg.motion_prior != "odometry"
        attempted = cfg.match_every_scan or self._is_keyframe(guess, stamp)
        # the constant-velocity prediction is one scan period's motion: after a gap in the scans
        # (a lidar blackout) it predicts nothing, and the odometry is not checked against it
        check = not lidar_only and abs(stamp - self._last_stamp) <= ODOMETRY_CHECK_MAX_GAP_S
        if attempted:
            rel, info = self._match(pts, guess, prev_rel if lidar_only else None,
                                    (se2.compose(prev_rel, self._last_motion), prev_rel) if check else None)
        failed = attempted and info is None
        restart = False
        if lidar_only and failed:
            # without odometry a failed match leaves nothing to go on: the scan stays where the
            # previous one was, and its prediction does not feed the next one; lost for
            # lost_restart_s, it becomes a keyframe there (the submap restarts)
            self._lost_since = stamp if self._lost_since is None else self._lost_since
            rel = prev_rel
            if cfg.lost_restart_s > 0 and stamp - self._lost_since >= cfg.lost_restart_s:
                restart, self._lost_since = True, None
                self._counts["lost_restarts"] += 1
        elif attempted:
            self._lost_since = None
        self._odom_at_scan = self._odom.copy()
        self._last_motion = se2.between(prev_rel, rel)
        self._last_dt_s = stamp - self._last_stamp
        self._last_stamp = stamp
        if restart or (self._is_keyframe(rel, stamp) and not (lidar_only and failed)):
            world_T_k = self._graph.poses()[k]
            matched = info is not None
            if info is None:
                info = np.diag(np.asarray(cfg.lost_sigmas, float) ** -2) if restart else self._fallback_information()
            self._add_keyframe(n, stamp, pts, ranges, scan.angles_rad, se2.compose(world_T_k, rel), rel, info,
                               matched)
            self._record_scan(stamp, k + 1, np.zeros(3))
        else:
            self._record_scan(stamp, k, rel)

    def _record_scan(self, stamp: float, anchor: int, rel: np.ndarray) -> None:
        self._scan_stamps.append(stamp)
        self._scan_anchor.append(anchor)
        self._scan_rel.append(np.asarray(rel, float))

    def _is_keyframe(self, k_T_scan: np.ndarray, stamp_s: float) -> bool:
        """The rule of ``slamkit.frontend.keyframes`` on the motion since the newest keyframe,
        the matched one (``k_T_scan``), also when there is wheel odometry. Measured (issue 11):
        the rule on the odometry since the keyframe instead gives 0.189 +- 0.743 m relation error
        on the whole Intel log with odometry (0.0155 +- 0.0136 m on the match); fr079 and the
        simulated worlds do not tell the two apart beyond the scatter of which scans become
        keyframes (12 simulated runs: mean ATE 0.0060 m odometry, 0.0062 m match)."""
        return self.config.keyframes.exceeded_by(k_T_scan, stamp_s - self._kf.stamps[-1])

    def _fallback_information(self) -> np.ndarray:
        return np.diag(np.asarray(self.config.fallback_sigmas, float) ** -2)

    def _match(self, pts: np.ndarray, guess: np.ndarray, hold: np.ndarray | None = None,
               check: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """Scan points against the submap from ``guess`` (or ``hold``, the previous scan's pose,
        when its heading search scores better): (k_T_scan, information) or the guess and None
        when the match is not trusted. ``check``: (constant-velocity prediction, previous scan's
        pose) to test an odometry ``guess`` against (``odometry_check_deg``)."""
        cfg = self.config
        if self._target is None or len(pts) < cfg.icp.min_correspondences:
            self._counts["match_fallbacks"] += 1
            return guess, None
        search = cfg.rotation_search_deg > 0 and hold is not None
        if search:
            guess = self._heading(pts, (guess, hold), cfg.rotation_search_deg)
        res = icp(pts, self._target, guess, cfg.icp)
        self._counts["matched_scans"] += 1
        self._counts["icp_iterations"] += res.iterations
        if search and res.fitness < WIDE_SEARCH_BELOW_FITNESS:
            # a turn faster than the window (Intel: up to 40 deg between two scans): once more
            # over a window four times as wide, keep the better match
            wide = icp(pts, self._target, self._heading(pts, (guess, hold), 4 * cfg.rotation_search_deg), cfg.icp)
            self._counts["wide_searches"] += 1
            if wide.fitness > res.fitness:
                res = wide
        if check is not None and self._odometry_doubtful(res, guess, check[0]):
            start = self._heading(pts, (guess, *check), cfg.rotation_search_deg)
            other = icp(pts, self._target, start, cfg.icp)
            self._counts["odometry_checks"] += 1
            self._counts["icp_iterations"] += other.iterations
            if other.fitness > res.fitness:
                self._counts["odometry_check_wins"] += 1
                res = other
        if search and self._uncertain(res, hold):
            res = self._correlative(pts, guess, res)
        if res.fitness < cfg.min_match_fitness or not np.all(np.isfinite(res.covariance)):
            self._counts["match_fallbacks"] += 1
            return guess, None
        info = np.linalg.inv(res.covariance)
        return res.target_T_source, 0.5 * (info + info.T)

    def _odometry_doubtful(self, res: IcpResult, odometry: np.ndarray, predicted: np.ndarray) -> bool:
        cfg = self.config
        d = se2.between(odometry, predicted)
        return bool(res.fitness < WIDE_SEARCH_BELOW_FITNESS
                    or (cfg.odometry_check_deg > 0 and abs(d[2]) > np.deg2rad(cfg.odometry_check_deg))
                    or (cfg.odometry_check_m > 0 and np.hypot(d[0], d[1]) > cfg.odometry_check_m))

    def _uncertain(self, res: IcpResult, hold: np.ndarray) -> bool:
        turn = abs(se2.between(hold, res.target_T_source)[2])
        return bool(res.fitness < self.config.correlative_below_fitness
                    or turn > np.deg2rad(self.config.correlative_above_turn_deg))

    def _correlative(self, pts: np.ndarray, guess: np.ndarray, res: IcpResult) -> IcpResult:
        """ICP from the best pose of the correlative search around ``guess``, if it fits better
        than ``res``."""
        if self._likelihood is None:
            self._likelihood = CorrelativeGrid(self._target.points, self.config.correlative)
        start = correlative_search(pts, self._likelihood, guess).target_T_source
        other = icp(pts, self._target, start, self.config.icp)
        self._counts["correlative_searches"] += 1
        self._counts["icp_iterations"] += other.iterations
        if other.fitness > res.fitness:
            self._counts["correlative_wins"] += 1
            return other
        return res

    def _heading(self, pts: np.ndarray, starts, half_window_deg: float) -> np.ndarray:
        """The start (prior, or the previous pose: without odometry the robot may have stopped)
        whose best heading within +-``half_window_deg`` fits the submap best, at that heading."""
        found = [rotation_search(pts, self._target, g, np.deg2rad(half_window_deg)) for g in starts]
        return min(found, key=lambda f: f[1])[0]

    def _add_keyframe(self, scan_index: int, stamp: float, pts: np.ndarray, ranges: np.ndarray,
                      angles: np.ndarray, world_T_k: np.ndarray, rel: np.ndarray | None,
                      info: np.ndarray | None, matched: bool = True) -> None:
        kf = self._kf
        k = len(kf.stamps)
        self._graph.add_pose(k, world_T_k)
        if rel is not None:
            self._graph.add_edge(k - 1, k, rel, info, robust_edge=False)
            self._edge_kind.append("odometry")
            self._region.add(kf.frontend[-1], rel, np.linalg.inv(info), matched)
            kf.frontend.append(se2.compose(kf.frontend[-1], rel))
            kf.path_m.append(kf.path_m[-1] + float(np.hypot(rel[0], rel[1])))
        else:
            self._region.start(world_T_k)
            kf.frontend.append(world_T_k.copy())
            kf.path_m.append(0.0)
        kf.stamps.append(stamp)
        kf.scans.append(scan_index)
        kf.points.append(pts)
        kf.ranges.append(ranges)
        kf.angles.append(np.asarray(angles, float))
        extra = 0
        if self.config.online_loop_closure and k > 0:
            found = self._close_loops_at(k)
            extra = 2 if found else 0
        self._update(extra)
        self.observer.on_keyframe(Keyframe(k, stamp, self._graph.poses()[k].copy(), pts))
        local = kf.frontend if self.config.submap_poses == "frontend" else self._graph.poses()
        self._target = self._submap_at(k, range(max(0, k - self.config.submap_keyframes + 1), k + 1),
                                       local, self.config.icp)
        self._likelihood = None

    def _update(self, extra: int = 0) -> None:
        """iSAM2's update; when its Cholesky gives up, the graph is moved to a QR iSAM2 (same
        factors, the current estimate) and solved there from then on.

        Why: GTSAM's Cholesky calls a clique underconstrained when the last two diagonal entries
        of its factor differ by 2^12 or more (gtsam/base/cholesky.cpp,
        ``underconstrainedExponentDifference``), i.e. when a new scan-match edge is ~4096x more
        precise (in sigma) than the newest pose's marginal. A chain without loop closures reaches
        that: the hospital's first 2349 keyframes (927 m, 7 local closures) put the newest pose's
        marginal at 24 m / 0.14 rad while its edge is 5 mm / 1.6 mrad. The system is not
        indeterminate: every keyframe has its edge, every edge's information is positive definite
        (condition <= 3942), the same factors solve with QR, and the failure is
        scale-free (all information x 1e-3 or x 1e3: the same keyframe; the newest edge / 10:
        none). QR is kept as the fallback only: as the whole config it measured 0.066 m on Intel
        with odometry (0.0156 with Cholesky) and 1.5x the CPU."""
        try:
            self._graph.update(extra)
            return
        except RuntimeError as err:
            if "ndeterminant" not in str(err) and "ndeterminate" not in str(err):
                raise
            if self._graph_qr:
                raise
        old = self._graph
        g = old.graph()
        self._graph = Isam2PoseGraph(self.config.robust, params=replace(self.config.isam2, factorization="qr"),
                                     name=old.name)
        for k, pose in enumerate(old.poses()):
            self._graph.add_pose(k, pose)
        for (i, j, z, info), kind in zip(zip(g.edge_from, g.edge_to, g.measurements, g.information), self._edge_kind):
            self._graph.add_edge(int(i), int(j), z, info, robust_edge=kind != "odometry")
        self._graph_qr = True
        self._counts["isam2_qr_fallbacks"] += 1
        self._graph.update(extra)

    # ---- loop closure ------------------------------------------------------------------------

    #: keyframes added between rebuilds of the candidate KD-tree, and the radius margin that
    #: covers how far the estimate may have moved since (positions are re-checked exactly)
    TREE_REBUILD_EVERY = 64
    TREE_MARGIN_M = 1.0

    def _candidates_for(self, j: int) -> list[int]:
        """Earlier keyframes within the search radius of keyframe j in the current estimate, at
        least the index and path gaps back, closest first. A KD-tree over the positions is
        rebuilt every ``TREE_REBUILD_EVERY`` keyframes (O(K log K) each time, so O(log K)
        amortised per keyframe); it is queried with a margin, the keyframes added since are
        checked directly, and every hit is re-checked against the current positions. Loop
        closures that corrected the estimate by more than half the margin in total since the
        last rebuild (the graph may have moved that much) force a rebuild."""
        cfg = self.config.loops
        poses = self._graph.poses()
        if (self._tree is None or j - self._tree_size >= self.TREE_REBUILD_EVERY
                or self._moved_m > 0.5 * self.TREE_MARGIN_M):
            self._tree, self._tree_size, self._moved_m = cKDTree(poses[:j, :2]), j, 0.0
        near = self._tree.query_ball_point(poses[j, :2], cfg.search_radius_m + self.TREE_MARGIN_M)
        near = np.concatenate([np.asarray(near, dtype=np.int64), np.arange(self._tree_size, j)])
        d = np.hypot(*(poses[near, :2] - poses[j, :2]).T)
        path = self._kf.path_m
        ok = [(float(dist), int(i)) for i, dist in zip(near, d)
              if dist <= cfg.search_radius_m and j - i >= cfg.min_index_gap
              and path[j] - path[i] >= cfg.min_path_gap_m and (int(i), j) not in self._tried]
        return [i for _, i in sorted(ok)[:cfg.max_candidates_per_keyframe]]

    def _verify(self, i: int, j: int, poses: np.ndarray) -> LoopClosure | None:
        cfg = self.config
        pts_j = self._kf.points[j]
        if min(len(self._kf.points[i]), len(pts_j)) < cfg.loops.icp.min_correspondences:
            return None
        self._tried.add((i, j))
        self._counts["loop_candidates"] += 1
        s = cfg.loop_submap_keyframes
        K = len(self._kf.points)
        target = self._loop_submap(i, range(max(0, i - s), min(K, i + s + 1)), poses)
        if target is None:
            return None
        ok, res = verify_loop(target, pts_j, se2.between(poses[i], poses[j]), cfg.loops)
        return LoopClosure(i, j, res.target_T_source, res) if ok else None

    def _submap_at(self, k: int, members, poses, icp_config: IcpConfig) -> IcpTarget | None:
        """Keyframes ``members``' points in keyframe k's frame (``poses``: the keyframes' poses,
        (K, 3) or a list of (3,)), prepared for ICP with
        ``icp_config``'s normals and voxel filter (None: too few points)."""
        pts = np.concatenate([se2.transform_points(se2.between(poses[k], poses[m]), self._kf.points[m])
                              for m in members])
        pts = voxel_downsample(pts, icp_config.target_voxel_m)
        if len(pts) < max(3, icp_config.normal_neighbours):
            return None
        return IcpTarget(pts, icp_config.normal_neighbours)

    #: loop-verification targets kept (keyed by the members' exact poses, so a hit is the target
    #: that would be built again: the graph often leaves old keyframes' poses bit for bit alone)
    LOOP_TARGET_CACHE = 64

    def _loop_submap(self, i: int, members: range, poses) -> IcpTarget | None:
        """``_submap_at(i, members, poses, loops.icp)``, reused when the same members were
        prepared at the same poses before (the points of a keyframe never change)."""
        key = (i, members.start, members.stop, np.asarray([poses[m] for m in members], dtype=float).tobytes())
        if key in self._loop_targets:
            target = self._loop_targets.pop(key)
        else:
            target = self._submap_at(i, members, poses, self.config.loops.icp)
        _keep_newest(self._loop_targets, key, target, self.LOOP_TARGET_CACHE)
        return target

    def _accept(self, closure: LoopClosure, poses: np.ndarray) -> None:
        correction = se2.between(se2.between(poses[closure.i], poses[closure.j]), closure.i_T_j)
        self._moved_m += float(np.hypot(correction[0], correction[1]))
        self._graph.add_edge(closure.i, closure.j, closure.i_T_j, closure.result.information, robust_edge=True)
        self._edge_kind.append("loop")
        self._region.closed(closure.i, closure.j)
        self._loops.append(closure)
        self.observer.on_loop_closure(closure)

    def _close_loops_at(self, j: int) -> int:
        poses = self._graph.poses()
        found = 0
        for i in self._candidates_for(j):
            closure = self._verify(i, j, poses)
            if closure is not None:
                self._accept(closure, poses)
                found += 1
        # ``loops.global_after_local_closure``: the keyframes near j in the estimate may all be
        # from the drifted stretch, the place it revisits beyond them
        globals_ = [] if found and not self.config.loops.global_after_local_closure else \
            self._global_candidates_for(j, poses)
        for i, window_xy_m, window_theta_rad, cov in globals_:
            closure = self._verify_global(i, j, poses, window_xy_m, window_theta_rad, cov)
            if closure is not None:
                self._accept(closure, poses)
                self._counts["loop_closures_global"] += 1
                found += 1
                break
        if self._places is not None:
            descriptor = self._describe(j)
            if not found:
                found += self._close_place_at(j, descriptor, poses)
            self._places.add(j, descriptor)
        self._counts["loop_closures_online"] += found
        return found

    def _describe(self, j: int) -> np.ndarray:
        """Keyframe j's Scan Context: the keyframes within its last ``submap_path_m`` of travel
        (at most ``submap_max_keyframes``, evenly spread, j always) at their chained scan-match
        poses, in j's frame."""
        sc = self.config.loops.scan_context
        path = np.asarray(self._kf.path_m)
        first = int(np.searchsorted(path[:j + 1], path[j] - sc.submap_path_m, side="left"))
        members = np.unique(np.linspace(j, first, min(sc.submap_max_keyframes, j - first + 1)).round().astype(np.int64))
        fe = self._kf.frontend
        pts = np.concatenate([se2.transform_points(se2.between(fe[j], fe[m]), self._kf.points[m]) for m in members])
        return scan_context(pts, sc)

    def _close_place_at(self, j: int, descriptor: np.ndarray, poses: np.ndarray) -> int:
        """Place recognition's candidates for keyframe j (``loops.scan_context``): the best Scan
        Context matches among the keyframes at least the index and path gaps back, beyond
        ``search_radius_m`` in the estimate (nearer, the local search has them) and inside the
        drift region of ``scan_context.region_probability`` without its cap (a corridor looks
        the same all along: on the hospital log, of the 1772 keyframes whose best match is within
        0.2, all but 25 matched a keyframe of the same pass down the same corridor, which the
        chain puts further away than it can have drifted); each not tried yet is matched
        globally around the place and the descriptor's yaw, the first verified one kept."""
        lc = self.config.loops
        sc = lc.scan_context
        if sc.max_candidates_per_keyframe == 0 or len(self._places) == 0:
            return 0
        path = np.asarray(self._kf.path_m)
        stored = np.arange(len(self._places))      # keyframes are added in order, one each
        allowed = (j - stored >= lc.min_index_gap) & (path[j] - path[stored] >= lc.min_path_gap_m)
        offsets = poses[stored, :2] - poses[j, :2]
        allowed &= np.hypot(offsets[:, 0], offsets[:, 1]) > lc.search_radius_m
        if not allowed.any():
            return 0
        q = chi2_quantile(sc.region_probability, 2)
        cand = stored[allowed]
        cov = self._region.covariances(cand, j) + (lc.search_radius_m ** 2 / q) * np.eye(2)
        d = offsets[allowed]
        allowed[cand] = np.einsum("ni,nij,nj->n", d, np.linalg.inv(cov), d) <= q
        tried = 0
        for match in self._places.query(descriptor, allowed):
            i = match.index
            if (i, j) in self._tried:
                continue
            if tried == sc.max_candidates_per_keyframe:
                break
            tried += 1
            closure = self._verify_place(i, j, poses, match.yaw_rad)
            self.place_candidates.append((i, j, match.distance, match.yaw_rad, closure is not None))
            if closure is not None:
                self._accept(closure, poses)
                self._counts["loop_closures_place"] += 1
                return 1
        return 0

    def _verify_place(self, i: int, j: int, poses: np.ndarray, yaw_rad: float) -> LoopClosure | None:
        """Keyframe j's scan against the submap around i by branch and bound within the place
        window around (0, 0, ``yaw_rad``) in i's frame -- the estimate says nothing here --
        then ICP (``verify_loop``) with the far closures' fitness (``global_far_min_fitness``)."""
        sc = self.config.loops.scan_context
        res = self._match_global(i, j, poses, np.array([0.0, 0.0, yaw_rad]), sc.window_xy_m, sc.window_theta_rad,
                                 "loop_candidates_place")
        if res is None or res.fitness < self.config.loops.global_far_min_fitness:
            return None
        return LoopClosure(i, j, res.target_T_source, res, source="place")

    def _global_candidates_for(self, j: int, poses: np.ndarray):
        """The uncertainty region's candidates for keyframe j (``DriftRegion``): earlier
        keyframes (index and path gaps as the local search) whose estimated position offset lies
        in the chi-square ellipse of the drift accumulated since the last closure, where that
        ellipse reaches beyond ``search_radius_m`` (inside it the local ICP search has them),
        most likely (smallest Mahalanobis distance) first, at most
        ``max_global_candidates_per_keyframe``. Each comes with its match window: the region's
        radius along its major axis (capped) and the heading's chi-square interval."""
        cfg = self.config.loops
        if cfg.region_probability <= 0 or cfg.max_global_candidates_per_keyframe == 0 or j < 1:
            return []
        path = np.asarray(self._kf.path_m)
        near = self._tree.query_ball_point(poses[j, :2], cfg.max_search_radius_m + self.TREE_MARGIN_M)
        near = np.unique(np.concatenate([np.asarray(near, dtype=np.int64), np.arange(self._tree_size, j)]))
        near = near[(j - near >= cfg.min_index_gap) & (path[j] - path[near] >= cfg.min_path_gap_m)]
        near = np.array([i for i in near if (int(i), j) not in self._tried], dtype=np.int64)
        if len(near) == 0:
            return []
        inside, m2, radius = self._region.members(near, j, poses[near, :2] - poses[j, :2])
        keep = inside & (radius > cfg.search_radius_m)
        q1 = chi2_quantile(cfg.region_probability, 1)
        theta = np.clip(np.sqrt(q1) * self._region.heading_sigmas(near, j),
                        cfg.global_min_window_theta_rad, cfg.global_max_window_theta_rad)
        cov = self._region.covariances(near, j)
        order = [k for k in np.argsort(m2, kind="stable") if keep[k]][:cfg.max_global_candidates_per_keyframe]
        return [(int(near[k]), float(min(radius[k], cfg.max_search_radius_m)), float(theta[k]), cov[k])
                for k in order]

    #: global-match targets kept (a revisit tries the same old keyframes for several new ones)
    PYRAMID_CACHE = 16

    def _verify_global(self, i: int, j: int, poses: np.ndarray, window_xy_m: float, window_theta_rad: float,
                       cov_xy: np.ndarray) -> LoopClosure | None:
        """Keyframe j's scan against the submap around i by branch and bound over the window
        around the estimate, the optimum seeding ICP (``verify_loop``: fitness, and a correction
        within ``max_correction_m`` of the seed); accepted when the closure's position also lies
        in the region (its correction from the estimate within the chi-square ellipse)."""
        lc = self.config.loops
        guess = se2.between(poses[i], poses[j])
        res = self._match_global(i, j, poses, guess, window_xy_m, window_theta_rad, "loop_candidates_global")
        if res is None:
            return None
        moved = se2.between(guess, res.target_T_source)
        far = np.hypot(moved[0], moved[1]) > lc.global_far_m
        if far and res.fitness < lc.global_far_min_fitness:
            self._counts["loop_global_far_rejected"] += 1
            return None
        if far and self._rivalled(i, j, guess, window_xy_m, window_theta_rad):
            self._counts["loop_global_ambiguous_rejected"] += 1
            return None
        # the correction in the world frame, tested against the region (widened by the floor)
        q = chi2_quantile(lc.region_probability, 2)
        c, sn = np.cos(poses[i][2]), np.sin(poses[i][2])
        shift = np.array([[c, -sn], [sn, c]]) @ (res.target_T_source[:2] - guess[:2])
        wide = cov_xy + (lc.search_radius_m ** 2 / q) * np.eye(2)
        if float(shift @ np.linalg.solve(wide, shift)) > q:
            return None
        # how far the estimate had drifted from the revisit it found
        self._counts["loop_global_correction_max_m"] = max(self._counts["loop_global_correction_max_m"],
                                                            float(np.hypot(shift[0], shift[1])))
        return LoopClosure(i, j, res.target_T_source, res, source="region")

    def _match_global(self, i: int, j: int, poses: np.ndarray, guess: np.ndarray, window_xy_m: float,
                      window_theta_rad: float, counter: str) -> IcpResult | None:
        """Branch and bound of keyframe j's scan against the submap around i (at ``poses``) over
        the window around ``guess`` (i_T_j), its optimum seeding ``verify_loop``; the verified
        ICP result, or None. Marks (i, j) tried and counts it in ``counter``. The targets'
        pyramids (which do not depend on the window) are kept for the next candidates at i."""
        cfg = self.config
        lc = cfg.loops
        pts_j = self._kf.points[j]
        if min(len(self._kf.points[i]), len(pts_j)) < lc.icp.min_correspondences:
            return None
        self._tried.add((i, j))
        self._counts[counter] += 1
        s = cfg.loop_submap_keyframes
        K = len(self._kf.points)
        members = range(max(0, i - s), min(K, i + s + 1))
        match = lc.global_match(window_xy_m, window_theta_rad)
        pyramid = self._pyramids.pop(i, None)
        # the ICP target (KD-tree, normals) is built only when it is needed: for a pyramid not
        # kept, or to verify what the search found (most searches find nothing)
        target = None
        if pyramid is None:
            target = self._loop_submap(i, members, poses)
            if target is None:
                return None
            pyramid = MaxGridPyramid(target.points, match)
        _keep_newest(self._pyramids, i, pyramid, self.PYRAMID_CACHE)
        source = voxel_downsample(pts_j, lc.global_resolution_m)
        found = branch_and_bound_search(source, pyramid, guess, match)
        if found is None:
            return None
        if target is None:
            target = self._loop_submap(i, members, poses)
            if target is None:
                return None
        ok, res = verify_loop(target, pts_j, found.target_T_source, lc)
        return res if ok else None

    def _rivalled(self, i: int, j: int, guess: np.ndarray, window_xy_m: float, window_theta_rad: float) -> bool:
        """Whether keyframe j's scan fits another place of the window around ``guess`` (the
        submap around i) almost as well as the branch-and-bound optimum: a candidate more than
        ``loops.global_far_rival_m`` from it scoring more than ``loops.global_far_max_rival`` of
        its score (``slamkit.frontend.branch_and_bound.rival_search``; never when that is >= 1).
        The pyramid is the one the search just used (kept in the cache)."""
        lc = self.config.loops
        if lc.global_far_max_rival >= 1.0:
            return False
        pyramid = self._pyramids[i]
        match = lc.global_match(window_xy_m, window_theta_rad)
        source = voxel_downsample(self._kf.points[j], lc.global_resolution_m)
        best = branch_and_bound_search(source, pyramid, guess, match)
        rival = rival_search(source, pyramid, guess, best.target_T_source, lc.global_far_max_rival * best.score,
                             lc.global_far_rival_m, match)
        return rival is not None and rival.score > lc.global_far_max_rival * best.score

    def add_constraint(self, i: int, j: int, i_xytheta_j: np.ndarray, information: np.ndarray) -> None:
        """An edge between keyframes ``i`` and ``j`` from outside the system (a user's prior
        knowledge, or an injected false closure in a robustness test); robust like a loop."""
        K = len(self._kf.stamps)
        if not (0 <= i < K and 0 <= j < K):
            raise DataError(f"add_constraint: keyframes {i}, {j} out of range (0..{K - 1})")
        self._graph.add_edge(i, j, i_xytheta_j, information, robust_edge=True)
        self._edge_kind.append("injected")
        self._injected.append((int(i), int(j)))
        self._update()

    def finish(self) -> LidarSlamEstimate:
        """``loop_rounds`` rounds of loop search over all keyframe pairs of the current
        estimate, each followed by a batch Levenberg-Marquardt solve with the robust kernel
        (the online iSAM2 estimate is the initial guess); returns the final estimate."""
        if len(self._kf.stamps) < 2:
            raise DataError("lidar SLAM needs at least 2 keyframes (scans with motion between them)")
        cfg = self.config
        poses = self._graph.poses().copy()
        # the kernel on the loop closures only: the scan-match chain is least squares, as online.
        # Why (issue 28): with every edge robust, a tear of the chain was cheap. On the Intel log
        # lidar only, started one scan later, the final loop search closed a 2 m drift of
        # keyframes 2443-2530 while three online closures taken at the drifted poses held
        # keyframes 2479-2526 in place: the solve tore two scan-match edges (chi2 774 and 7633)
        # rather than move them, relation error 0.062 +- 0.236 m. With the chain trusted the same
        # graph solves to 0.025 +- 0.050 m from the online estimate and from the chained matches
        # alike (the same objective, 1899.43)
        opt = OptimizeConfig(robust=cfg.robust, max_iterations=100, robust_edges="loop_closures")
        solved = False
        for _ in range(cfg.loop_rounds):
            found = 0
            for i, j in loop_candidates(poses, cfg.loops):
                if (int(i), int(j)) in self._tried:
                    continue
                closure = self._verify(int(i), int(j), poses)
                if closure is not None:
                    self._accept(closure, poses)
                    found += 1
            self._counts["loop_closures_final"] += found
            poses = optimize(self._graph.graph(), opt).poses.copy()
            solved = True
        if not solved and (self._loops or self._injected):
            poses = optimize(self._graph.graph(), opt).poses.copy()
        if cfg.robust != "none" and (solved or self._loops or self._injected):
            poses = self._prune(poses, opt)
        self._final_poses = poses
        self._finished = True
        return self.estimate()

    def _prune(self, poses: np.ndarray, opt: OptimizeConfig) -> np.ndarray:
        """The consistency check: a loop closure (or injected edge) whose residual at the robust
        solution exceeds ``loop_chi2_max`` (whitened, 3 dof) disagrees with the rest of the graph
        -- the robust kernel only bounded its pull -- so it is dropped and the graph solved once
        more without it."""
        g = self._graph.graph()
        kind = np.asarray(self._edge_kind)
        err = se2.log(se2.between(g.measurements, se2.between(poses[g.edge_from], poses[g.edge_to])))
        chi2 = np.einsum("ni,nij,nj->n", err, g.information, err)
        bad = (kind != "odometry") & (chi2 > self.config.loop_chi2_max)
        if not bad.any():
            return poses
        rejected = {(int(i), int(j)) for i, j in zip(g.edge_from[bad], g.edge_to[bad])}
        self._loops = [lc for lc in self._loops if (lc.i, lc.j) not in rejected]
        self._injected = [e for e in self._injected if e not in rejected]
        self._counts["loop_closures_rejected"] += int(bad.sum())
        keep = ~bad
        pruned = replace(g, poses=poses, edge_from=g.edge_from[keep], edge_to=g.edge_to[keep],
                         measurements=g.measurements[keep], information=g.information[keep])
        self._pruned_graph = pruned
        return optimize(pruned, opt).poses.copy()

    # ---- results -----------------------------------------------------------------------------

    def graph(self):
        """The pose graph so far (keyframes, scan-match edges, loop closures, injected edges) as a
        :class:`~slamkit.data.pose_graph.PoseGraph` with the current estimate as its poses."""
        if self._pruned_graph is not None:
            return replace(self._pruned_graph, poses=self.keyframe_poses().copy())
        g = self._graph.graph()
        return replace(g, poses=self.keyframe_poses().copy()) if self._finished else g

    def keyframe_poses(self) -> np.ndarray:
        return self._final_poses if self._finished else self._graph.poses()

    def estimate(self) -> LidarSlamEstimate:
        poses = self.keyframe_poses()
        anchor = np.asarray(self._scan_anchor, dtype=np.int64)
        rel = np.asarray(self._scan_rel, dtype=float).reshape(-1, 3)
        world = se2.compose(poses[anchor], rel) if len(anchor) else np.zeros((0, 3))
        kf = self._kf
        return LidarSlamEstimate(np.asarray(self._scan_stamps), world, np.asarray(kf.scans, dtype=np.int64),
                                 np.asarray(kf.stamps), poses.copy(), np.asarray(kf.frontend).reshape(-1, 3),
                                 tuple(self._loops), tuple(self._injected), self.counters)

    def keyframe_scans(self) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
        """(body-frame points, lidar ranges (NaN: no return), beam angles) of every keyframe."""
        return tuple(self._kf.points), tuple(self._kf.ranges), tuple(self._kf.angles)

    def sensor_poses(self, world_xytheta_body: np.ndarray) -> np.ndarray:
        """Lidar poses of body poses (N, 3)."""
        return se2.compose(np.asarray(world_xytheta_body, float).reshape(-1, 3), self._body_T_lidar)

    @property
    def max_range_m(self) -> float:
        return self._max_range

    @property
    def counters(self) -> LidarSlamCounters:
        """What the system counted so far (a frozen copy of its running tally)."""
        return LidarSlamCounters(**self._counts)

    def map(self, config: LogOddsConfig | None = None, world_xytheta_body: np.ndarray | None = None,
            margin_m: float = 1.0, like: OccupancyGrid | None = None) -> LogOddsMap:
        """Log-odds map of the keyframe scans at ``world_xytheta_body`` (K, 3) (default: the
        current keyframe estimate), covering every return plus ``margin_m``, or on the cells of
        ``like`` (e.g. a ground-truth grid to score against)."""
        cfg = config or self.config.map
        poses = self.keyframe_poses() if world_xytheta_body is None else np.asarray(world_xytheta_body, float)
        return occupancy_map(self.sensor_poses(poses), self._kf.angles, self._kf.ranges, self.max_range_m,
                             cfg, margin_m, like)


def occupancy_map(world_xytheta_sensors: np.ndarray, angles_rad, ranges_m, max_range_m: float,
                  config: LogOddsConfig, margin_m: float = 1.0, like: OccupancyGrid | None = None) -> LogOddsMap:
    """Log-odds map of scans (per-scan angles and ranges, NaN: no return) at sensor poses (K, 3),
    covering every return plus ``margin_m`` (or on the cells of ``like``)."""
    if like is not None:
        m = LogOddsMap.like(like, config)
    else:
        ends = [se2.transform_points(p, np.column_stack([r * np.cos(a), r * np.sin(a)])[np.isfinite(r)])
                for p, a, r in zip(world_xytheta_sensors, angles_rad, ranges_m)]
        xy = np.concatenate(ends + [world_xytheta_sensors[:, :2]])
        m = LogOddsMap.covering(xy.min(axis=0) - margin_m, xy.max(axis=0) + margin_m, config)
    for p, a, r in zip(world_xytheta_sensors, angles_rad, ranges_m):
        m.update(p, a, r, max_range_m)
    return m


def _keep_newest(cache: dict, key, value, capacity: int) -> None:
    """Put ``value`` in ``cache`` as its newest entry (a dict keeps insertion order; the caller
    popped ``key`` on a hit) and drop the oldest beyond ``capacity``: the system's two caches,
    global-match pyramids and loop-verification targets."""
    cache[key] = value
    while len(cache) > capacity:
        cache.pop(next(iter(cache)))
