"""Multi-rate planar fusion as running systems (course Example 11.1): IMU (gyro, forward
accelerometer), wheel encoders and lidar scans matched against the known map of the world.

* :class:`FusionLocalizer` (registry name ``fusion_ekf``): the 5-state EKF of
  :mod:`slamkit.estimation.fusion_ekf`, predicted at the IMU rate, updated by every encoder
  reading and by a pose fix from every scan.
* :class:`FusionSmoother` (``fusion_isam2``): every scan is a keyframe of an iSAM2 pose graph
  (``slamkit.backend.Isam2PoseGraph``); the wheel distances and gyro heading changes since the
  previous keyframe are preintegrated (``slamkit.models.planar_preintegration``) into a
  BetweenFactor, the scan's pose fix is a PriorFactor; one iSAM2 update per keyframe, and the
  trajectory is the keyframes' smoothed poses with their marginal covariances.

Pose fixes (:class:`MapMatcher`): the scan's end points, in the body frame through
``body_xytheta_lidar``, are aligned by point-to-line ICP (``slamkit.frontend.icp``) with points
on the map's wall faces (the mid-points of every occupied cell face next to a free cell: where a
beam stops), starting from the predicted pose. A match with fitness below ``min_fitness`` or
farther than ``max_correction_m`` / ``max_correction_rad`` from the prediction gives no fix
(counted in ``extras["rejected_fixes"]``). Without a map (``Sequence.occupancy_grid`` None) scans
are ignored. The systems know nothing of ground truth: they are built from a Sequence's map and
metadata only.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from slamkit.data.estimate import Estimate, Prior
from slamkit.data.sequence import Event, Imu, Scan, Sequence, WheelEncoders, check_event
from slamkit.data.trajectory import Trajectory
from slamkit.errors import ConfigError, EstimationError
from slamkit.estimation.fusion_ekf import FusionEKF, FusionEkfConfig, PoseFix, WheelCalibration
from slamkit.frontend.icp import IcpConfig, IcpTarget, icp, scan_to_points
from slamkit.geometry import se2
from slamkit.geometry.angles import wrap_angle
from slamkit.maps.occupancy_grid import OccupancyGrid, wall_face_points
from slamkit.models.planar_preintegration import PlanarPreintegration


@dataclass(frozen=True)
class MapMatchConfig:
    #: a 0.2 m correspondence gate: the prediction is within a few cm, and people walking by are
    #: then left unmatched instead of pulling the fix (office seed 2, two crossing people: largest
    #: EKF error 25 cm with a 0.5 m gate, 1.3 cm with 0.2 m)
    icp: IcpConfig = field(default_factory=lambda: IcpConfig(max_correspondence_m=0.2))
    #: a match below this fitness (fraction of points within icp.fitness_distance_m) is no fix
    min_fitness: float = 0.5
    #: a fix farther than these from the predicted pose is rejected
    max_correction_m: float = 0.5
    max_correction_rad: float = 0.2
    #: where the lidar sits on the robot (x, y, theta)
    body_xytheta_lidar: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: at most this many scan points go into ICP (evenly subsampled)
    max_points: int = 360


class MapMatcher:
    """Pose fixes from scans matched against a known occupancy grid (see the module doc)."""

    def __init__(self, grid: OccupancyGrid, config: MapMatchConfig = MapMatchConfig()) -> None:
        self.config = config
        self.target = IcpTarget(wall_face_points(grid), config.icp.normal_neighbours)
        self.accepted = 0
        self.rejected = 0

    def fix(self, scan: Scan, world_xytheta_guess: np.ndarray) -> PoseFix | None:
        c = self.config
        pts = scan_to_points(scan.ranges_m, scan.angles_rad, scan.max_range_m)
        if len(pts) < c.icp.min_correspondences:
            self.rejected += 1
            return None
        if len(pts) > c.max_points:
            pts = pts[np.linspace(0, len(pts) - 1, c.max_points).astype(np.int64)]
        lidar = np.asarray(c.body_xytheta_lidar, dtype=float)
        body_pts = se2.transform_points(lidar, pts)
        guess = np.asarray(world_xytheta_guess, dtype=float).reshape(3)
        res = icp(body_pts, self.target, guess, c.icp)
        step = se2.between(guess, res.target_T_source)
        if (res.fitness < c.min_fitness or np.hypot(step[0], step[1]) > c.max_correction_m
                or abs(wrap_angle(step[2])) > c.max_correction_rad):
            self.rejected += 1
            return None
        self.accepted += 1
        # ICP's covariance is in the right tangent of the pose; the fix is stated in world terms
        cov = se2.covariance_body_to_world(res.target_T_source, res.covariance)
        return PoseFix(float(scan.stamp_s), res.target_T_source, 0.5 * (cov + cov.T))


def sensors_of(sequence: Sequence, config) -> tuple[WheelCalibration | None, MapMatcher | None]:
    """What a fusion system is built from: the wheel calibration the sequence's metadata states
    and a matcher on its map (None when ``config.use_lidar`` is off or there is no map)."""
    grid = sequence.occupancy_grid
    matcher = MapMatcher(grid, config.matcher) if config.use_lidar and grid is not None else None
    return WheelCalibration.from_metadata(sequence.metadata), matcher


# --------------------------------------------------------------------------------------------
# the filter


@dataclass(frozen=True)
class FusionLocalizerConfig:
    ekf: FusionEkfConfig = FusionEkfConfig()
    matcher: MapMatchConfig = MapMatchConfig()
    #: False: IMU and encoders only (the scans are ignored)
    use_lidar: bool = True


class FusionLocalizer:
    """EKF + map matcher (registry name ``fusion_ekf``; see the module doc)."""

    name = "fusion_ekf"

    def __init__(self, calibration: WheelCalibration | None, matcher: MapMatcher | None,
                 config: FusionLocalizerConfig = FusionLocalizerConfig()) -> None:
        self.config = config
        self.ekf = FusionEKF(calibration, config.ekf)
        self.matcher = matcher

    @classmethod
    def from_sequence(cls, sequence: Sequence, config: FusionLocalizerConfig = FusionLocalizerConfig()
                      ) -> "FusionLocalizer":
        return cls(*sensors_of(sequence, config), config)

    def reset(self, prior: Prior) -> None:
        self.ekf.reset(prior)
        self._scan_s = 0.0

    def step(self, event: Event) -> None:
        if isinstance(event, Scan) and self.matcher is not None:
            t0 = time.perf_counter()
            fix = self.matcher.fix(event, self.ekf.predicted_pose())
            self._scan_s += time.perf_counter() - t0
            if fix is not None:
                self.ekf.step(fix)
            return
        self.ekf.step(event)

    def latest_estimate(self) -> Estimate:
        """The newest pose only (for observers; see ``runner.belief_snapshot``)."""
        return self.ekf.latest_estimate()

    def estimate(self) -> Estimate:
        est = self.ekf.estimate()
        m = self.matcher
        return dataclasses.replace(est, extras={
            **est.extras, "accepted_fixes": m.accepted if m else 0, "rejected_fixes": m.rejected if m else 0,
            "scan_matching_s": self._scan_s})


# --------------------------------------------------------------------------------------------
# the smoother


@dataclass(frozen=True)
class FusionSmootherConfig:
    matcher: MapMatchConfig = MapMatchConfig()
    #: white-noise densities of the wheel speed (m/s/sqrt(Hz)) and of the gyro rate
    #: (rad/s/sqrt(Hz)) in the preintegrated odometry: var(d) = sigma_v^2 dt per increment; the
    #: defaults are the EKF's pose_random_walk, so filter and smoother assume the same noise
    odometry_v_density: float = 0.1
    odometry_omega_density: float = 0.06
    #: R_lidar of the pose-fix priors (as the EKF's default), or the fix's own covariance
    lidar_covariance: tuple[float, float, float] = (0.01, 0.01, 0.001)
    lidar_noise: str = "fixed"
    use_lidar: bool = True
    #: empty iSAM2 updates after the last keyframe (more relinearisation)
    final_updates: int = 5

    def __post_init__(self) -> None:
        if self.lidar_noise not in ("fixed", "measured"):
            raise ConfigError(f"FusionSmootherConfig.lidar_noise must be 'fixed' or 'measured', got {self.lidar_noise!r}")


class FusionSmoother:
    """iSAM2 over lidar keyframes with preintegrated wheel/gyro odometry (``fusion_isam2``)."""

    name = "fusion_isam2"

    def __init__(self, calibration: WheelCalibration | None, matcher: MapMatcher | None,
                 config: FusionSmootherConfig = FusionSmootherConfig()) -> None:
        self.config = config
        self.calibration = calibration
        self.matcher = matcher
        self._ready = False

    @classmethod
    def from_sequence(cls, sequence: Sequence, config: FusionSmootherConfig = FusionSmootherConfig()
                      ) -> "FusionSmoother":
        return cls(*sensors_of(sequence, config), config)

    def reset(self, prior: Prior) -> None:
        from slamkit.backend.isam2 import Isam2PoseGraph

        sigma = float(np.sqrt(max(np.max(np.diag(prior.covariance)), 1e-12)))
        self.graph = Isam2PoseGraph(robust_kind="none", prior_sigma=sigma, name=self.name)
        self.graph.add_pose(0, prior.world_xytheta_body)
        self._stamps: list[float] = [0.0]
        self._first = True
        self._pre = PlanarPreintegration()
        self._gyro = 0.0
        self._t_enc: float | None = None
        self._updates = 0
        self._cached: tuple[int, Estimate] | None = None
        self._fix_stamps: list[float] = []
        self._ready = True

    def step(self, event: Event) -> None:
        if not self._ready:
            raise EstimationError(f"{self.name}: step() called before reset(prior)")
        check_event(event, self.name)
        stamp = float(event.stamp_s)
        if self._first:
            self._stamps[0] = stamp
            self._first = False
        if isinstance(event, Imu):
            self._gyro = float(event.gyro_radps[2])
        elif isinstance(event, WheelEncoders):
            self._encoders(event, stamp)
        elif isinstance(event, Scan) and self.matcher is not None:
            self._keyframe(event, stamp)

    def _encoders(self, event: WheelEncoders, stamp: float) -> None:
        previous, self._t_enc = self._t_enc, stamp
        if previous is None or stamp <= previous:
            return
        dt = stamp - previous
        v, _ = WheelCalibration.required(self.calibration, self.name).rates(event, dt)
        c = self.config
        self._pre.integrate(v * dt, self._gyro * dt, c.odometry_v_density ** 2 * dt,
                            c.odometry_omega_density ** 2 * dt, dt)

    def _keyframe(self, scan: Scan, stamp: float) -> None:
        if stamp <= self._stamps[-1]:
            return
        g = self.graph
        i = g.num_poses - 1
        guess = se2.compose(g.poses()[i], self._pre.delta)
        fix = self.matcher.fix(scan, guess)
        g.add_pose(i + 1, fix.world_xytheta_body if fix is not None else guess)
        info = np.linalg.inv(self._pre.covariance + 1e-12 * np.eye(3))
        g.add_edge(i, i + 1, self._pre.delta, info, robust_edge=False)
        if fix is not None:
            self._fix_stamps.append(stamp)
            cov = fix.covariance if self.config.lidar_noise == "measured" else np.diag(self.config.lidar_covariance)
            g.add_prior(i + 1, fix.world_xytheta_body, cov)
        g.update()
        self._updates += 1
        self._stamps.append(stamp)
        self._pre.reset()

    def latest_estimate(self) -> Estimate:
        """The newest keyframe's current estimate and marginal covariance (for observers)."""
        if not self._ready:
            raise EstimationError(f"{self.name}: latest_estimate() called before reset(prior)")
        pose = self.graph.poses()[-1]
        cov = self.graph.covariance(self.graph.num_poses - 1) if self.graph.num_poses > 1 else np.eye(3) * 1e-12
        return Estimate(trajectory=Trajectory.from_se2(np.array([self._stamps[-1]]), pose[None]),
                        pose_covariances=cov[None])

    def estimate(self) -> Estimate:
        """The smoothed keyframes (after ``final_updates`` more iSAM2 steps) with their marginal
        covariances; kept until the next keyframe, so observers may ask often."""
        if not self._ready:
            raise EstimationError(f"{self.name}: estimate() called before reset(prior)")
        if self._cached is not None and self._cached[0] == self.graph.num_poses:
            return self._cached[1]
        self.graph.update(extra_steps=self.config.final_updates)
        m = self.matcher
        est = Estimate(trajectory=Trajectory.from_se2(np.array(self._stamps), self.graph.poses()),
                        pose_covariances=self.graph.covariances(),
                        extras={"keyframes": self.graph.num_poses, "isam2_updates": self._updates,
                                "accepted_fixes": m.accepted if m else 0,
                                "rejected_fixes": m.rejected if m else 0,
                                "lidar_update_stamps_s": np.array(self._fix_stamps)})
        self._cached = (self.graph.num_poses, est)
        return est


__all__ = ["FusionLocalizer", "FusionLocalizerConfig", "FusionSmoother", "FusionSmootherConfig",
           "MapMatchConfig", "MapMatcher"]
