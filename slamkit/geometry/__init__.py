"""Lie groups for robotics on plain numpy arrays, batch first.

* ``so2``: angles (...,); ``se2``: (..., 3) = (x, y, theta), tangent (v_x, v_y, omega)
* ``so3``: (..., 3, 3) matrices, tangent phi (..., 3); quaternions wxyz; ZYX Euler
* ``se3``: (..., 4, 4) matrices, tangent (rho, phi) -- translation first (GTSAM: rotation first)
* ``angles.wrap_angle`` into [-pi, pi)
"""

from slamkit.geometry import angles, se2, se3, so2, so3
from slamkit.geometry.angles import angle_diff, wrap_angle

__all__ = ["angles", "so2", "se2", "so3", "se3", "wrap_angle", "angle_diff"]
