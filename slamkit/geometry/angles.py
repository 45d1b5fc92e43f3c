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
    # one floor instead of np.mod (several times cheaper on large arrays: particle filters wrap
    # N x m bearings every step)
    wrapped = a - TWO_PI * np.floor((a + np.pi) * (1.0 / TWO_PI))
    if wrapped.ndim == 0:
        w = float(wrapped)
        # rounding can land exactly on +pi or a hair below -pi; fold back so [-pi, pi) holds
        return w - TWO_PI if w >= np.pi else (-np.pi if w < -np.pi else w)
    high = wrapped >= np.pi
    if high.any():
        wrapped[high] -= TWO_PI
    low = wrapped < -np.pi
    if low.any():
        wrapped[low] = -np.pi
    return wrapped


def angle_diff(a_rad, b_rad):
    """Signed smallest difference ``a - b`` wrapped into [-pi, pi)."""
    return wrap_angle(np.asarray(a_rad, dtype=float) - np.asarray(b_rad, dtype=float))
