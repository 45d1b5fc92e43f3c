"""Lie groups for robotics on plain numpy arrays, batch first.

* ``so2``: angles (...,); ``se2``: (..., 3) = (x, y, theta), tangent (v_x, v_y, omega)
* ``so3``: (..., 3, 3) matrices, tangent phi (..., 3); quaternions wxyz; ZYX Euler
* ``se3``: (..., 4, 4) matrices, tangent (rho, phi) -- translation first (GTSAM: rotation first)
* ``angles.wrap_angle`` into [-pi, pi); ``segments.point_segment_distance``

Naming (issue 18: one pose, one spelling): a pose is named after its frames, ``a_T_b`` maps
frame b into frame a, and the representation follows the frames' letter: ``world_T_body`` for
SE(3) matrices (..., 4, 4), ``world_xytheta_body`` for planar poses (..., 3) = (x, y, theta),
``world_t_body`` / ``world_p_landmark`` for translations and points. ``pose_xytheta`` (no
frames) is gone from the code base; the ``.slamseq`` member ``initial_pose_xytheta.npy`` keeps
its name because a file format does not change with a Python attribute.
"""

from slamkit.geometry import angles, se2, se3, segments, so2, so3
from slamkit.geometry.angles import angle_diff, wrap_angle

__all__ = ["angles", "so2", "se2", "so3", "se3", "segments", "wrap_angle", "angle_diff"]
