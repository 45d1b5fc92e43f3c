"""What the Gaussian localization filters (EKF, UKF) share: a known landmark map indexed by id,
the noise they assume, a chi-square gate, and a mean/covariance state reset from the prior.

When the sequence declares its ranges' scale unknown (``NoiseParams.range_scale_sigma`` > 0,
range-only data whose radios read a few percent long, as Plaza's do), the state is augmented
with the scale s after the pose, x = (x, y, theta, s) with the prior N(1, range_scale_sigma^2),
as in the particle filter and EKF-SLAM; a range then predicts r = s |m - p| and passes the same
gate |r - s |m - p|| <= range_gate_m. Odometry leaves s unchanged (no process noise)."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from slamkit.data.estimate import Prior
from slamkit.errors import ConfigError
from slamkit.estimation._common import FilterBase, NoiseParams, chi2_gate, landmark_array, range_rows
from slamkit.models import range_only


class GaussianLocalization(FilterBase):
    """Base of EKF and UKF localization; ``config`` needs a ``gate_probability`` field."""

    def __init__(self, world_p_landmarks: Mapping[int, np.ndarray], noise: NoiseParams,
                 config: Any) -> None:
        super().__init__()
        self.landmark_ids, self.landmarks = landmark_array(world_p_landmarks)
        if len(self.landmark_ids) == 0:
            raise ConfigError(f"{self.name} localization needs a non-empty landmark map")
        self._index = {int(i): k for k, i in enumerate(self.landmark_ids)}
        self.noise, self.config = noise, config
        self._gate = chi2_gate(config.gate_probability, 2)

    def _reset(self, prior: Prior) -> None:
        sigma_s = self.noise.range_scale_sigma
        #: where s sits in the state (None: ranges calibrated, the state is the pose alone)
        self._scale_index = 3 if sigma_s > 0 else None
        n = 3 if self._scale_index is None else 4
        self.x, self.P = np.zeros(n), np.zeros((n, n))
        self.x[:3], self.P[:3, :3] = prior.world_xytheta_body, prior.covariance
        if self._scale_index is not None:
            self.x[3], self.P[3, 3] = 1.0, sigma_s**2
        #: the state's angle components (the heading)
        self._angles = np.arange(n) == 2
        self._rejected = 0
        self._rejected_ranges = 0

    def _scale(self) -> float:
        """The current range scale estimate (1 when the ranges are calibrated)."""
        return 1.0 if self._scale_index is None else float(self.x[self._scale_index])

    def _pad(self, H_pose: np.ndarray) -> np.ndarray:
        """Jacobians (..., 3) with respect to the pose -> (..., n) over the state (zero in s)."""
        H = np.zeros((*H_pose.shape[:-1], len(self.x)))
        H[..., :3] = H_pose
        return H

    def _embed_motion(self, F_pose: np.ndarray, Q_pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The pose's transition Jacobian and noise (3, 3) -> the state's (s unchanged)."""
        n = len(self.x)
        F, Q = np.eye(n), np.zeros((n, n))
        F[:3, :3], Q[:3, :3] = F_pose, Q_pose
        return F, Q

    def _known_ranges(self, event) -> list[tuple[int, float]]:
        """(map index, range) of the event's ranges to mapped landmarks whose residual against
        the current pose (and scale) passes the range gate; the others are counted as rejected."""
        ids, ranges = range_rows(event)
        scale = self._scale()
        out = []
        for lid, r in zip(ids.tolist(), ranges.tolist()):
            k = self._index.get(int(lid))
            if k is None or self.noise.range_rejected(
                    r - scale * range_only.observe(self.x[:2], self.landmarks[k])):
                self._rejected_ranges += 1
                continue
            out.append((k, r))
        return out

    def _pose_and_covariance(self) -> tuple[np.ndarray, np.ndarray]:
        return self.x[:3].copy(), self.P[:3, :3].copy()

    def _extras(self) -> dict:
        return {"rejected_measurements": self._rejected, "rejected_ranges": self._rejected_ranges,
                **({} if self._scale_index is None else {"range_scale": self._scale()})}
