"""What the Gaussian localization filters (EKF, UKF) share: a known landmark map indexed by id,
the noise they assume, a chi-square gate, and a mean/covariance state reset from the prior."""

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
        self.x = prior.world_xytheta_body.copy()
        self.P = prior.covariance.copy()
        self._rejected = 0
        self._rejected_ranges = 0

    def _known_ranges(self, event) -> list[tuple[int, float]]:
        """(map index, range) of the event's ranges to mapped landmarks whose residual against
        the current pose passes the range gate; the others are counted as rejected."""
        ids, ranges = range_rows(event)
        out = []
        for lid, r in zip(ids.tolist(), ranges.tolist()):
            k = self._index.get(int(lid))
            if k is None or self.noise.range_rejected(r - range_only.observe(self.x[:2], self.landmarks[k])):
                self._rejected_ranges += 1
                continue
            out.append((k, r))
        return out
