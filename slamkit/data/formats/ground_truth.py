"""Small readers for the ground-truth files that accompany pose-graph benchmarks.

Every reader returns a :class:`slamkit.data.trajectory.Trajectory` whose ``stamps_s`` are the
VERTEX IDS (as floats), so an estimate is associated with ground truth by id, not by time.

* ``id_x_y_theta``: one ``id x y theta`` per line (Vertigo's ``ring`` / ``ringCity`` poses.txt).
* ``x_y_theta``: one ``x y theta`` per line, line k (zero-based, blank lines skipped) is vertex k
  (Vertigo's ``manhattanOlson3500_nodes_groundTruth.dat``, gtsam's ``ISAM2_GT_city10000.txt``).
* ``isam_noise_free``: an iSAM file whose measurements are noise-free (``sphere2500_groundtruth.txt``,
  ``cityTrees10000_groundtruth.txt``): the poses are the edges composed in file order from vertex
  0 at the origin (any path gives the same pose up to the file's printed precision).

Bad input: a line with the wrong number of fields or a token that is not a number ->
``DataError`` naming file and one-based line; duplicate ids -> ``DataError``; an empty file ->
``DataError``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from slamkit.data.formats._records import wrap_angle_rad
from slamkit._text import number_rows
from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError

GROUND_TRUTH_FORMATS = ("id_x_y_theta", "x_y_theta", "isam_noise_free")


def _table(path: str | Path, width: int) -> tuple[np.ndarray, np.ndarray]:
    """(line numbers, values (K, width)) of a whitespace-separated numeric file."""
    return number_rows(path, width, "empty ground-truth file")


def read_id_x_y_theta(path: str | Path) -> Trajectory:
    lines, values = _table(path, 4)
    ids = values[:, 0]
    if np.any(ids != np.round(ids)):
        k = int(np.flatnonzero(ids != np.round(ids))[0])
        raise DataError(f"id {ids[k]!r} is not an integer", path, int(lines[k]))
    order = np.argsort(ids, kind="stable")
    dup = np.flatnonzero(np.diff(ids[order]) == 0)
    if len(dup):
        k = int(order[dup[0] + 1])
        raise DataError(f"vertex {int(ids[k])} appears twice", path, int(lines[k]))
    poses = values[order, 1:]
    return Trajectory.from_se2(ids[order], np.column_stack([poses[:, :2], wrap_angle_rad(poses[:, 2])]))


def read_x_y_theta(path: str | Path) -> Trajectory:
    _, values = _table(path, 3)
    return Trajectory.from_se2(np.arange(len(values), dtype=float),
                               np.column_stack([values[:, :2], wrap_angle_rad(values[:, 2])]))


def read_isam_noise_free(path: str | Path) -> Trajectory:
    from slamkit.data.formats.isam import read_isam

    graph = read_isam(path)
    stamps = graph.vertex_ids.astype(float)
    if graph.dim == 2:
        return Trajectory.from_se2(stamps, graph.poses)
    return Trajectory(stamps, graph.poses[:, :3], graph.poses[:, 3:])


def read_ground_truth(path: str | Path, format: str) -> Trajectory:
    readers = {"id_x_y_theta": read_id_x_y_theta, "x_y_theta": read_x_y_theta,
               "isam_noise_free": read_isam_noise_free}
    if format not in readers:
        raise DataError(f"unknown ground-truth format {format!r}; use one of {GROUND_TRUTH_FORMATS}", path)
    return readers[format](path)
