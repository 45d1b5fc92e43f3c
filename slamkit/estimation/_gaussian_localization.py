"""What the Gaussian localization filters (EKF, UKF) share: a known landmark map indexed by id,
the noise they assume, a chi-square gate, and a mean/covariance state reset from the prior."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from slamkit.data.estimate import Prior
from slamkit.errors import ConfigError
from slamkit.estimation._common import FilterBase, NoiseParams, chi2_gate, landmark_array


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
        self.x = prior.world_xytheta_body.copy()
        self.P = prior.covariance.copy()
        self._rejected = 0
