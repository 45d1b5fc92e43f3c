"""Angle wrapping.

Every angle slamkit returns lies in the half-open interval [-pi, pi), so that two equal
rotations always have the same representative (pi and -pi would otherwise both appear).
"""

from __future__ import annotations

import numpy as np

TWO_PI = 2.0 * np.pi


def wrap_angle(angle_rad):
    """Wrap angles (any shape) into [-pi, pi).

    Scalars in give a float out; arrays in give an array of the same shape out.
    """
    a = np.asarray(angle_rad, dtype=float)
    wrapped = np.mod(a + np.pi, TWO_PI) - np.pi
    # np.mod can return exactly 2*pi for tiny negative inputs through rounding; fold it back
    # so the upper bound stays open.
    wrapped = np.where(wrapped >= np.pi, wrapped - TWO_PI, wrapped)
    wrapped = np.where(wrapped < -np.pi, -np.pi, wrapped)
    return float(wrapped) if wrapped.ndim == 0 else wrapped


def angle_diff(a_rad, b_rad):
    """Signed smallest difference ``a - b`` wrapped into [-pi, pi)."""
    return wrap_angle(np.asarray(a_rad, dtype=float) - np.asarray(b_rad, dtype=float))
