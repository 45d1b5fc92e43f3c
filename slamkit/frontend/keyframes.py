"""Keyframe selection: keep a scan when the robot has moved far enough since the last keyframe.

The distance/angle rule of most 2D lidar SLAM front-ends (GMapping's ``linearUpdate`` /
``angularUpdate``; Cartographer's motion filter, Hess et al., ICRA 2016, sec. IV): a new
keyframe once the relative motion since the previous one exceeds ``min_translation_m`` or
``min_rotation_rad`` (or ``max_interval_s`` when set, so a robot turning slowly in place still
gets keyframes). Keyframes bound the pose-graph size and make consecutive scans overlap well.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import ConfigError
from slamkit.geometry import se2


@dataclass(frozen=True)
class KeyframeConfig:
    min_translation_m: float = 0.5
    min_rotation_rad: float = float(np.deg2rad(20.0))
    max_interval_s: float | None = None

    def __post_init__(self) -> None:
        if not (self.min_translation_m > 0 and self.min_rotation_rad > 0):
            raise ConfigError("KeyframeConfig thresholds must be > 0")

    def exceeded_by(self, k_xytheta_x: np.ndarray, interval_s: float) -> bool:
        """The rule itself: is a pose ``k_xytheta_x`` (relative to the last keyframe, reached
        ``interval_s`` after it) far enough for a new keyframe?"""
        return bool(np.hypot(k_xytheta_x[0], k_xytheta_x[1]) >= self.min_translation_m
                    or abs(k_xytheta_x[2]) >= self.min_rotation_rad
                    or (self.max_interval_s is not None and interval_s >= self.max_interval_s))


class KeyframeSelector:
    """Streaming selector: ``offer(stamp_s, world_xytheta_body) -> bool`` (True: new keyframe).
    The first pose offered is always a keyframe."""

    def __init__(self, config: KeyframeConfig = KeyframeConfig()):
        self.config = config
        self._last_pose: np.ndarray | None = None
        self._last_stamp = -np.inf

    def offer(self, stamp_s: float, world_xytheta_body: np.ndarray) -> bool:
        pose = np.asarray(world_xytheta_body, dtype=float).reshape(3)
        if self._last_pose is None or self._is_far(stamp_s, pose):
            self._last_pose, self._last_stamp = pose.copy(), float(stamp_s)
            return True
        return False

    def _is_far(self, stamp_s: float, pose: np.ndarray) -> bool:
        return self.config.exceeded_by(se2.between(self._last_pose, pose), stamp_s - self._last_stamp)


def select_keyframes(stamps_s: np.ndarray, world_xytheta_body: np.ndarray,
                     config: KeyframeConfig = KeyframeConfig()) -> np.ndarray:
    """Indices of the keyframes among poses (N, 3) (the streaming rule applied in order)."""
    sel = KeyframeSelector(config)
    poses = np.asarray(world_xytheta_body, dtype=float).reshape(-1, 3)
    return np.array([i for i, (t, p) in enumerate(zip(stamps_s, poses)) if sel.offer(t, p)],
                    dtype=np.int64)
