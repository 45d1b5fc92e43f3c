"""Private stop-gap until slamkit.geometry.angles lands: angle wrapping only."""

from __future__ import annotations

import numpy as np


def wrap_angle(angle_rad):
    """Wrap to [-pi, pi)."""
    return (np.asarray(angle_rad, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi
