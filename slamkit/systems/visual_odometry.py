"""Monocular visual odometry as a running system: frames in, camera poses and a local map out.

Feature-based VO in the classic shape (Scaramuzza & Fraundorfer, "Visual odometry, part I",
IEEE RAM 18(4), 2011, Algorithm 1 / the course's Example 3.1; the tracking and local-map split
of PTAM and ORB-SLAM, Mur-Artal et al., IEEE T-RO 31(5), 2015):

1. Features: ORB keypoints and descriptors on every frame (``slamkit.vision.orb``), matched to
   the previous frame's by Hamming distance with the ratio test and cross-check (the putative
   matches), guided: a keypoint is compared only with those within ``match_window_px`` of it
   (the frame-to-frame image motion is small), brute force over all when that finds too few. The second front-end (``frontend: klt``) tracks Shi-Tomasi corners with
   pyramidal Lucas-Kanade (``slamkit.vision.klt``) and tops them up with new corners away from
   the tracked ones; a track is a putative match.
2. Outlier rejection: the essential matrix by Nister's 5-point RANSAC
   (``slamkit.vision.two_view``) on the putative matches; its inliers are the frame's inliers.
3. Initialisation (frame 1): (R, t) of the essential matrix with the cheirality check,
   |t| = 1; the inliers in front of both cameras are triangulated into the map. **Monocular
   scale is unobservable**: the whole trajectory is in the unit of that first baseline, so it is
   scored after a Sim(3) alignment.
4. Tracking (frames >= 2): the inlier matches whose previous keypoint carries a map point give
   3D-2D correspondences; PnP RANSAC (``slamkit.vision.pnp``) gives the pose, which keeps the
   scale of the map. The new matches are triangulated between the previous and the current pose
   (in front of both, reprojection error below ``pnp_threshold_px``, parallax above
   ``min_parallax_deg``). Too few correspondences: the essential matrix's rotation and direction
   with the previous step length (constant-speed fallback).
5. Sliding-window bundle adjustment (``window`` frames, ``slamkit.backend.bundle_adjustment``):
   after every frame the poses of the last ``window`` frames and every point they see are
   refined with the Huber-robust reprojection error; the window's two oldest poses are held
   fixed (they fix the gauge, scale included). ``window = 0`` turns it off, so its effect can
   be measured.

Poses are ``world_T_camera`` with the world = the first camera (z forward, x right, y down).
The system knows nothing of ground truth or files: ``slamkit.experiments.visual_odometry``
feeds it frames and scores it. Observers subscribe with ``on_frame(FrameResult)``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Literal, Protocol

import numpy as np

from slamkit.backend.bundle_adjustment import BundleAdjustmentConfig, bundle_adjust
from slamkit.errors import ConfigError, DataError
from slamkit.geometry import se3
from slamkit.models.camera import PinholeCamera
from slamkit.vision.image import good_features_to_track
from slamkit.vision.klt import KltConfig, track_klt
from slamkit.vision.orb import Features, OrbConfig, detect_orb, match_descriptors, match_descriptors_windowed
from slamkit.vision.pnp import pnp_ransac, reprojection_errors
from slamkit.vision.two_view import ransac_essential, recover_pose, triangulate

__all__ = ["VisualOdometryConfig", "FrameResult", "VisualOdometry", "VisualOdometryObserver", "VoEstimate"]


@dataclass(frozen=True)
class VisualOdometryConfig:
    #: ``orb`` (descriptor matching frame to frame) or ``klt`` (Shi-Tomasi corners tracked by
    #: pyramidal Lucas-Kanade, topped up when they thin out)
    frontend: Literal["orb", "klt"] = "orb"
    orb: OrbConfig = OrbConfig(num_features=3000, grid_cols=8, grid_rows=2, fast_threshold=10)
    match_ratio: float = 0.8
    #: guided matching: a keypoint is compared only with the next frame's keypoints within about
    #: this many pixels (``match_descriptors_windowed``); brute force over all of them when that
    #: finds fewer than ``min_pnp_points`` matches (tracking lost) or when 0
    match_window_px: float = 80.0
    klt: KltConfig = KltConfig(window=15, iterations=20)
    klt_max_corners: int = 1000
    klt_min_distance_px: float = 10.0
    ransac_threshold_px: float = 1.0
    ransac_confidence: float = 0.999
    pnp_threshold_px: float = 2.0
    min_pnp_points: int = 30
    min_parallax_deg: float = 0.1
    #: frames in the bundle-adjustment window (0: no bundle adjustment)
    window: int = 10
    ba: BundleAdjustmentConfig = BundleAdjustmentConfig()
    seed: int = 0

    def __post_init__(self) -> None:
        if not 0 < self.match_ratio <= 1:
            raise ConfigError(f"VisualOdometryConfig.match_ratio must be in (0, 1], got {self.match_ratio}")
        if not (self.ransac_threshold_px > 0 and self.pnp_threshold_px > 0):
            raise ConfigError("VisualOdometryConfig thresholds must be positive")
        if self.window != 0 and self.window < 3:
            raise ConfigError(f"VisualOdometryConfig.window must be 0 (off) or >= 3, got {self.window}")
        if self.frontend not in ("orb", "klt"):
            raise ConfigError(f"VisualOdometryConfig.frontend must be 'orb' or 'klt', got {self.frontend!r}")
        if self.klt_max_corners < 8 or not self.klt_min_distance_px >= 0:
            raise ConfigError("VisualOdometryConfig needs klt_max_corners >= 8 and klt_min_distance_px >= 0")
        if not self.match_window_px >= 0:
            raise ConfigError(f"VisualOdometryConfig.match_window_px must be >= 0, got {self.match_window_px}")
        if self.min_pnp_points < 6:
            raise ConfigError("VisualOdometryConfig.min_pnp_points must be >= 6")


@dataclass(frozen=True)
class FrameResult:
    """What one frame did (the course's per-frame numbers) and what a viewer needs."""

    index: int
    stamp_s: float
    world_T_camera: np.ndarray
    keypoints_uv: np.ndarray         #: (N, 2) this frame's keypoints
    matches: np.ndarray              #: (M, 2) putative matches (previous index, current index)
    inliers: np.ndarray              #: (M,) bool: essential-matrix inliers
    tracked_points: int              #: PnP inliers (3D-2D)
    new_points: int
    method: str                      #: "first", "essential", "pnp" or "essential_fallback"
    frontend_ms: float
    ba_ms: float

    @property
    def num_keypoints(self) -> int:
        return len(self.keypoints_uv)

    @property
    def num_matches(self) -> int:
        return len(self.matches)

    @property
    def num_inliers(self) -> int:
        return int(self.inliers.sum())


class VisualOdometryObserver(Protocol):
    def on_frame(self, result: FrameResult) -> None: ...


@dataclass(frozen=True)
class VoEstimate:
    stamps_s: np.ndarray           #: (F,)
    world_T_camera: np.ndarray     #: (F, 4, 4)
    world_p: np.ndarray            #: (P, 3) map points
    point_observations: np.ndarray  #: (P,) number of frames that saw each point


@dataclass
class _Frame:
    stamp_s: float
    features: Features
    x: np.ndarray                  # normalised coordinates of the keypoints
    point_id: np.ndarray           # map point of each keypoint, -1 for none
    image: np.ndarray | None = None  # the newest frame's image (KLT front-end)


#: the smallest frame side: ORB describes a keypoint only 31 px (its edge threshold) from every
#: border, so a smaller image has no pixel to describe (a 1 x 1 frame was an OpenCV assertion)
MIN_FRAME_PX = 2 * 31 + 1


class VisualOdometry:
    """Streaming monocular VO: ``step(stamp_s, image) -> FrameResult``, ``estimate()``.

    Every frame must be a 2-D grey image of the camera's size (``camera.height`` x
    ``camera.width``, at least :data:`MIN_FRAME_PX` on each side); another is a DataError
    naming the frame index -- a frame of another size would be projected with the wrong
    intrinsics and give a wrong trajectory without a word."""

    def __init__(self, camera: PinholeCamera, config: VisualOdometryConfig = VisualOdometryConfig()):
        if not isinstance(config, VisualOdometryConfig):
            raise ConfigError(f"VisualOdometry is configured by VisualOdometryConfig, not {type(config).__name__}")
        self.camera = camera
        self.config = config
        self.observers: list[VisualOdometryObserver] = []
        self._rng = np.random.default_rng(config.seed)
        self._frames: list[_Frame] = []
        self._poses: list[np.ndarray] = []   # world_T_camera
        self._points: list[np.ndarray] = []
        # observations: frame, point, pixel
        self._obs_frame: list[int] = []
        self._obs_point: list[int] = []
        self._obs_uv: list[np.ndarray] = []
        self._last_step_m = 1.0

    # -- helpers ----------------------------------------------------------------------------

    def _normalised(self, uv: np.ndarray) -> np.ndarray:
        return self.camera.unproject(uv)[:, :2] if len(uv) else np.empty((0, 2))

    def _add_observation(self, frame: int, point: int, uv: np.ndarray) -> None:
        self._obs_frame.append(frame)
        self._obs_point.append(point)
        self._obs_uv.append(np.asarray(uv, dtype=float))

    def _new_points(self, k: int, prev: _Frame, cur: _Frame, pairs: np.ndarray) -> int:
        """Triangulate the pairs (previous index, current index) between frames k-1 and k."""
        if len(pairs) == 0:
            return 0
        T_prev, T_cur = se3.inverse(self._poses[k - 1]), se3.inverse(self._poses[k])
        x1, x2 = prev.x[pairs[:, 0]], cur.x[pairs[:, 1]]
        X = triangulate(T_prev[:3], T_cur[:3], x1, x2)
        thr = self.config.pnp_threshold_px / self.camera.fx
        ok = np.isfinite(X).all(axis=1)
        ok &= reprojection_errors(T_prev, np.nan_to_num(X), x1) < thr
        ok &= reprojection_errors(T_cur, np.nan_to_num(X), x2) < thr
        c1, c2 = self._poses[k - 1][:3, 3], self._poses[k][:3, 3]
        r1, r2 = X - c1, X - c2
        cos = np.einsum("ij,ij->i", r1, r2) / np.maximum(np.linalg.norm(r1, axis=1) * np.linalg.norm(r2, axis=1), 1e-12)
        ok &= np.degrees(np.arccos(np.clip(cos, -1, 1))) > self.config.min_parallax_deg
        for (i, j), p in zip(pairs[ok], X[ok]):
            pid = len(self._points)
            self._points.append(p)
            prev.point_id[i] = pid
            cur.point_id[j] = pid
            self._add_observation(k - 1, pid, prev.features.uv[i])
            self._add_observation(k, pid, cur.features.uv[j])
        return int(ok.sum())

    # -- the streaming interface ------------------------------------------------------------

    def _check_frame(self, k: int, stamp_s: float, image) -> None:
        shape = np.shape(image)
        cam_hw = (self.camera.height, self.camera.width)
        if len(shape) != 2:
            raise DataError(f"frame {k} (t={stamp_s} s): expected a 2-D grey image, got an array of shape {shape}")
        if min(shape) < MIN_FRAME_PX:
            raise DataError(f"frame {k} (t={stamp_s} s): {shape[1]} x {shape[0]} pixels is too small for visual "
                            f"odometry (at least {MIN_FRAME_PX} x {MIN_FRAME_PX})")
        if shape != cam_hw:
            raise DataError(f"frame {k} (t={stamp_s} s): {shape[1]} x {shape[0]} pixels, but the camera (and frame 0) "
                            f"is {cam_hw[1]} x {cam_hw[0]}; every frame must have the camera's size")

    def step(self, stamp_s: float, image) -> FrameResult:
        t0 = time.perf_counter()
        cfg = self.config
        k = len(self._frames)
        self._check_frame(k, stamp_s, image)
        prev = self._frames[k - 1] if k else None
        if cfg.frontend == "orb":
            feats = detect_orb(image, cfg.orb)
            matches = np.empty((0, 2), int) if prev is None else self._match(prev.features, feats)
        else:
            feats, matches = self._klt_frontend(prev, image)
        cur = _Frame(float(stamp_s), feats, self._normalised(feats.uv), -np.ones(len(feats), dtype=int),
                     np.asarray(image, dtype=float) if cfg.frontend == "klt" else None)
        self._frames.append(cur)
        if prev is not None:
            prev.image = None  # only the newest image is kept (the KLT front-end tracks from it)
        if k == 0:
            self._poses.append(np.eye(4))
            return self._finish(k, cur, matches, np.empty(0, bool), 0, 0, "first", t0, 0.0)
        if len(matches) < 8:
            self._poses.append(self._constant_speed(k))
            return self._finish(k, cur, matches, np.zeros(len(matches), bool), 0, 0, "essential_fallback", t0, 0.0)
        x1, x2 = prev.x[matches[:, 0]], cur.x[matches[:, 1]]
        ess = ransac_essential(x1, x2, cfg.ransac_threshold_px / self.camera.fx, cfg.ransac_confidence,
                               rng=self._rng)
        inl = ess.inliers
        rel = recover_pose(ess.model, x1, x2, inl)
        good = matches[inl]
        tracked = 0
        if k == 1:
            cam1_T_cam0 = se3.from_rotation_translation(rel.R, rel.t)
            self._poses.append(se3.inverse(cam1_T_cam0))
            self._last_step_m = 1.0
            method = "essential"
            new_pairs = matches[rel.in_front]
        else:
            pid = prev.point_id[good[:, 0]]
            has = pid >= 0
            method = "essential_fallback"
            if has.sum() >= cfg.min_pnp_points:
                world_p = np.asarray(self._points)[pid[has]]
                try:
                    pnp = pnp_ransac(world_p, cur.x[good[has, 1]], cfg.pnp_threshold_px / self.camera.fx,
                                     rng=self._rng)
                except ConfigError:  # no pose with enough inliers: the fallback below
                    pnp = None
                if pnp is not None and pnp.inliers.sum() >= cfg.min_pnp_points:
                    self._poses.append(se3.inverse(pnp.camera_T_world))
                    method = "pnp"
                    for (i, j), p in zip(good[has][pnp.inliers], pid[has][pnp.inliers]):
                        cur.point_id[j] = p
                        self._add_observation(k, int(p), feats.uv[j])
                    tracked = int(pnp.inliers.sum())
            if method != "pnp":
                step = se3.from_rotation_translation(rel.R, rel.t * self._last_step_m)  # cam_k_T_cam_k-1
                self._poses.append(self._poses[k - 1] @ se3.inverse(step))
            self._last_step_m = float(np.linalg.norm(self._poses[k][:3, 3] - self._poses[k - 1][:3, 3])) or 1.0
            new_pairs = good[~has]
        new = self._new_points(k, prev, cur, new_pairs)
        frontend_ms = (time.perf_counter() - t0) * 1e3
        t1 = time.perf_counter()
        if cfg.window and k >= 2:
            self._bundle_adjust(k)
        return self._finish(k, cur, matches, inl, tracked, new, method, t0, (time.perf_counter() - t1) * 1e3,
                            frontend_ms)

    def _match(self, prev: Features, cur: Features) -> np.ndarray:
        """Guided (windowed) matching, brute force when it finds too few (tracking lost)."""
        cfg = self.config
        if cfg.match_window_px > 0:
            matches = match_descriptors_windowed(prev.uv, prev.descriptors, cur.uv, cur.descriptors,
                                                 cfg.match_window_px, ratio=cfg.match_ratio)
            if len(matches) >= cfg.min_pnp_points:
                return matches
        return match_descriptors(prev.descriptors, cur.descriptors, ratio=cfg.match_ratio)

    def _klt_frontend(self, prev: _Frame | None, image) -> tuple[Features, np.ndarray]:
        """Track the previous keypoints with pyramidal LK (``slamkit.vision.klt``), then top the
        set up with Shi-Tomasi corners away from the tracked ones: (features, matches)."""
        cfg = self.config
        tracked = np.empty((0, 2))
        matches = np.empty((0, 2), int)
        if prev is not None and len(prev.features):
            p1, ok = track_klt(prev.image, image, prev.features.uv, cfg.klt)
            tracked = p1[ok]
            matches = np.stack([np.flatnonzero(ok), np.arange(len(tracked))], axis=1)
        room = cfg.klt_max_corners - len(tracked)
        new = np.empty((0, 2))
        if room > 0:
            mask = np.ones(np.shape(image), dtype=bool)
            r = int(cfg.klt_min_distance_px)
            for u, v in np.rint(tracked).astype(int):
                mask[max(0, v - r):v + r + 1, max(0, u - r):u + r + 1] = False
            new = good_features_to_track(image, room, 0.01, cfg.klt_min_distance_px, mask=mask)
        uv = np.vstack([tracked, new])
        n = len(uv)
        return Features(uv, np.zeros((n, 32), np.uint8), np.zeros(n, int), np.zeros(n)), matches

    def _constant_speed(self, k: int) -> np.ndarray:
        if k < 2:
            return self._poses[k - 1].copy()
        delta = se3.inverse(self._poses[k - 2]) @ self._poses[k - 1]
        return self._poses[k - 1] @ delta

    def _bundle_adjust(self, k: int) -> None:
        first = max(0, k - self.config.window + 1)
        frames = np.asarray(self._obs_frame)
        in_window = frames >= first
        if not in_window.any():
            return
        points = np.asarray(self._obs_point)
        seen = np.unique(points[in_window])
        # every observation of those points inside the window
        use = in_window & np.isin(points, seen)
        local_point = {int(p): i for i, p in enumerate(seen)}
        result = bundle_adjust(
            np.asarray(self._poses[first:k + 1]), np.asarray(self._points)[seen], frames[use] - first,
            np.array([local_point[int(p)] for p in points[use]]), np.asarray(self._obs_uv)[use],
            (self.camera.fx, self.camera.fy, self.camera.cx, self.camera.cy), fixed=(0, 1), config=self.config.ba)
        for i in range(k + 1 - first):
            self._poses[first + i] = result.world_T_camera[i]
        for i, p in enumerate(seen):
            if result.used_points[i]:
                self._points[int(p)] = result.world_p[i]

    def _finish(self, k, cur, matches, inliers, tracked, new, method, t0, ba_ms, frontend_ms=None) -> FrameResult:
        frontend_ms = (time.perf_counter() - t0) * 1e3 - ba_ms if frontend_ms is None else frontend_ms
        result = FrameResult(k, cur.stamp_s, self._poses[k].copy(), cur.features.uv, matches, inliers, tracked, new,
                             method, frontend_ms, ba_ms)
        for observer in self.observers:
            observer.on_frame(result)
        return result

    def estimate(self) -> VoEstimate:
        points = np.asarray(self._points).reshape(-1, 3)
        counts = np.bincount(np.asarray(self._obs_point, dtype=int), minlength=len(points))
        return VoEstimate(np.array([f.stamp_s for f in self._frames]), np.asarray(self._poses).reshape(-1, 4, 4),
                          points, counts)
