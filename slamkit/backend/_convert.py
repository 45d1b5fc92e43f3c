"""Conversions between slamkit's numpy pose layouts and GTSAM objects (internal to the back-end).

Layouts are the ones ``slamkit.data.pose_graph`` fixes: 2D (x, y, theta); 3D (x, y, z, qw, qx,
qy, qz); 3D information in g2o order (translation first) while GTSAM's Pose3 tangent is rotation
first, so 6x6 blocks are permuted with ``G2O_TO_GTSAM``.
"""

from __future__ import annotations

import gtsam
import numpy as np
from gtsam.symbol_shorthand import X

from slamkit.errors import BackendError

#: index permutation taking a g2o-ordered (x y z rx ry rz) 6-vector to GTSAM's (rx ry rz x y z);
#: it is its own inverse.
G2O_TO_GTSAM = np.array([3, 4, 5, 0, 1, 2])


def permute_information(information: np.ndarray) -> np.ndarray:
    """(M, 6, 6) g2o-order information -> GTSAM Pose3 tangent order (and back: an involution)."""
    info = np.asarray(information, dtype=float)
    return info[..., G2O_TO_GTSAM, :][..., :, G2O_TO_GTSAM]


def pose_key(vertex_id: int) -> int:
    """GTSAM key of a pose vertex: ``X(id)`` so keys read like the file's ids."""
    return X(int(vertex_id))


def to_pose(dim: int, row: np.ndarray):
    """One pose in slamkit layout -> gtsam.Pose2 / gtsam.Pose3."""
    if dim == 2:
        return gtsam.Pose2(float(row[0]), float(row[1]), float(row[2]))
    # Rot3.Quaternion(w, x, y, z) is exactly what gtsam.readG2o uses, so a slamkit-built problem
    # and a raw gtsam one start from bit-identical rotations.
    rot = gtsam.Rot3.Quaternion(float(row[3]), float(row[4]), float(row[5]), float(row[6]))
    return gtsam.Pose3(rot, np.array(row[:3], dtype=float))


def values_from_poses(dim: int, vertex_ids: np.ndarray, poses: np.ndarray) -> gtsam.Values:
    values = gtsam.Values()
    # X(id) is ('x' << 56) | id for every id at once; the keyword picks Values.insert's Pose2 /
    # Pose3 overload directly (positionally, pybind11 first tries the vector and matrix
    # overloads on every call: 3.2 us instead of 1.7 us per pose)
    keys = (pose_key(0) + np.asarray(vertex_ids, dtype=np.int64)).tolist()
    insert = values.insert
    if dim == 2:
        Pose2 = gtsam.Pose2
        for key, (x, y, theta) in zip(keys, np.asarray(poses, dtype=float).tolist()):
            insert(key, pose2=Pose2(x, y, theta))
    else:
        for key, row in zip(keys, poses):
            insert(key, pose3=to_pose(3, row))
    return values


def rotation_to_quat_wxyz(R: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotation matrices -> (N, 4) unit quaternions (w, x, y, z) with w >= 0.

    Shepperd's method: pick the largest of (w, x, y, z) to divide by, which keeps it stable
    near 180-degree rotations."""
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    tr = np.trace(R, axis1=1, axis2=2)
    d = np.stack([tr, R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]], axis=1)
    pick = np.argmax(d, axis=1)
    q = np.empty((len(R), 4))
    # case 0: w largest
    s = np.sqrt(np.maximum(1.0 + tr, 1e-300)) * 2.0
    c0 = np.stack([0.25 * s, (R[:, 2, 1] - R[:, 1, 2]) / s, (R[:, 0, 2] - R[:, 2, 0]) / s,
                   (R[:, 1, 0] - R[:, 0, 1]) / s], axis=1)
    s = np.sqrt(np.maximum(1.0 + R[:, 0, 0] - R[:, 1, 1] - R[:, 2, 2], 1e-300)) * 2.0
    c1 = np.stack([(R[:, 2, 1] - R[:, 1, 2]) / s, 0.25 * s, (R[:, 0, 1] + R[:, 1, 0]) / s,
                   (R[:, 0, 2] + R[:, 2, 0]) / s], axis=1)
    s = np.sqrt(np.maximum(1.0 + R[:, 1, 1] - R[:, 0, 0] - R[:, 2, 2], 1e-300)) * 2.0
    c2 = np.stack([(R[:, 0, 2] - R[:, 2, 0]) / s, (R[:, 0, 1] + R[:, 1, 0]) / s, 0.25 * s,
                   (R[:, 1, 2] + R[:, 2, 1]) / s], axis=1)
    s = np.sqrt(np.maximum(1.0 + R[:, 2, 2] - R[:, 0, 0] - R[:, 1, 1], 1e-300)) * 2.0
    c3 = np.stack([(R[:, 1, 0] - R[:, 0, 1]) / s, (R[:, 0, 2] + R[:, 2, 0]) / s,
                   (R[:, 1, 2] + R[:, 2, 1]) / s, 0.25 * s], axis=1)
    q = np.choose(pick[:, None], [c0, c1, c2, c3])
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 0] < 0] *= -1.0
    return q


def quat_wxyz_to_rotation(q: np.ndarray) -> np.ndarray:
    """(N, 4) quaternions (w, x, y, z) -> (N, 3, 3); normalises first."""
    q = np.asarray(q, dtype=float).reshape(-1, 4)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1),
    ], axis=1)


def poses_from_values(dim: int, vertex_ids: np.ndarray, values: gtsam.Values) -> np.ndarray:
    """Values holding ``X(id)`` for every vertex -> (N, 3) or (N, 7) rows in ``vertex_ids`` order.

    Uses GTSAM's bulk extractors (C++), which return rows in sorted-key order; X(id) sorts like
    id, so one argsort maps them back."""
    ids = np.asarray(vertex_ids, dtype=np.int64)
    if dim == 2:
        raw = gtsam.utilities.extractPose2(values)
    else:
        raw = gtsam.utilities.extractPose3(values)
    if len(raw) != len(ids):
        raise BackendError(f"expected {len(ids)} poses in the solution, found {len(raw)}")
    order = np.argsort(ids, kind="stable")
    out = np.empty((len(ids), 3 if dim == 2 else 7))
    if dim == 2:
        out[order] = raw
    else:
        R = raw[:, :9].reshape(-1, 3, 3)
        out[order, :3] = raw[:, 9:12]
        out[order, 3:] = rotation_to_quat_wxyz(R)
    return out


def check_vertex_ids(vertex_ids: np.ndarray) -> None:
    ids = np.asarray(vertex_ids)
    if len(ids) == 0:
        raise BackendError("pose graph has no vertices")
    if ids.min() < 0 or ids.max() >= 2**56:
        raise BackendError("vertex ids must lie in [0, 2^56) to be used as GTSAM X(id) keys")
    if len(np.unique(ids)) != len(ids):
        raise BackendError("vertex ids are not unique")
