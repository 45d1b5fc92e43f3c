"""Landmark-SLAM datasets as :class:`~slamkit.data.sequence.Sequence` objects: odometry and
range-bearing events, plus ground truth where the dataset has it.

* ``cityTrees10000`` (iSAM text; Kaess et al.): ``EDGE2`` odometry and ``LANDMARK`` Cartesian
  offsets in the observing pose's frame, square-root information (read by
  :mod:`slamkit.data.formats.isam`). Ground truth composes the noise-free twin file.
* Victoria Park (``victoria_park.txt`` in the gtsam wheel): the same record layout with
  ``ODOMETRY`` and **covariance** entries (MANIFEST.md); no ground truth.
* ``mrclam5a.pyfg`` (PyFactorGraph text, CORA): ``VERTEX_SE2 t name x y th`` (Vicon-derived,
  used as ground truth), ``VERTEX_XY``, ``EDGE_SE2 t a b dx dy dth`` + 6 covariance entries,
  ``EDGE_SE2_XY t pose landmark dx dy`` + 3 covariance entries; one robot (``A``..``E``) per
  sequence; ``EDGE_RANGE`` (inter-robot ranges) is not a landmark observation and is skipped.
* UTIAS MRCLAM Dataset 1, robot 1 (Leung et al., IJRR 2011), raw files: ``Odometry.dat``
  ``time v w`` commands, ``Measurement.dat`` ``time barcode range bearing``, barcodes mapped to
  subjects by ``Barcodes.dat`` (subjects 6-20 are landmarks, 1-5 robots: robot sightings are
  dropped), ``Landmark_Groundtruth.dat`` the landmark map. The robot's Vicon file is not in the
  shared datasets, so the sequence has no trajectory ground truth and no initial pose.

Relative-pose odometry (iSAM, PyFG) becomes ``Odometry`` events through the rotate-translate-
rotate decomposition of Thrun, Burgard & Fox, *Probabilistic Robotics*, sec. 5.4 (odometry motion
model): (dx, dy, dtheta) = rotate by alpha = atan2(dy, dx), drive d = |(dx, dy)|, rotate by
dtheta - alpha, each held over a third of the interval. It composes exactly to the measured
relative pose; a backwards step (|alpha| > pi/2) drives backwards (v < 0) instead of turning round.
The noise the filters should assume is converted to the same parametrisation and stored in
``metadata`` (``odometry_sigma`` on (v, omega), ``range_bearing_sigma`` from the isotropic
Cartesian sigma s: sigma_range = s, sigma_bearing = s / median range) -- an approximation,
recorded as such in ``metadata['noise_note']``; ``odometry_relative_sigma`` keeps the original
(x, y, theta) sigmas for smoothers.

Stamps: iSAM files have none, so pose ``i`` is at ``i * pose_dt_s`` seconds; MRCLAM files carry
Unix times, shifted so the sequence starts at 0 (``metadata['time_offset_s']``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np

from slamkit.geometry import se2
from slamkit.geometry.angles import wrap_angle
from slamkit._text import number_rows, parse_int, parse_number, read_lines
from slamkit.data.sequence import Event, Odometry, RangeBearing, Sequence
from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError

LANDMARK_DATASETS = ("citytrees10000", "victoria-park", "mrclam5a", "mrclam1")




def chain(start: np.ndarray, rel: np.ndarray) -> np.ndarray:
    """Poses (N + 1, 3) from ``start`` and N consecutive relative poses."""
    out = np.empty((len(rel) + 1, 3))
    out[0] = start
    for k in range(len(rel)):  # a recurrence: each pose depends on the previous one
        out[k + 1] = se2.compose(out[k:k + 1], rel[k:k + 1])[0]
    return out


def odometry_segments(rel: np.ndarray, t0: np.ndarray, t1: np.ndarray) -> list[Odometry]:
    """Relative poses (N, 3) between stamps t0 (N,) and t1 (N,) -> 3 N ``Odometry`` events
    (rotate, translate, rotate; see the module docstring), in time order."""
    rel = np.asarray(rel, dtype=float)
    d = np.hypot(rel[:, 0], rel[:, 1])
    alpha = np.where(d > 1e-12, np.arctan2(rel[:, 1], rel[:, 0]), 0.0)
    backwards = np.abs(alpha) > np.pi / 2
    alpha = np.where(backwards, wrap_angle(alpha - np.pi), alpha)
    d = np.where(backwards, -d, d)
    beta = wrap_angle(rel[:, 2] - alpha)
    dt = (np.asarray(t1, float) - np.asarray(t0, float)) / 3.0
    if np.any(~(dt > 0)):
        k = int(np.flatnonzero(~(dt > 0))[0])
        raise DataError(f"pose stamps must increase; relative pose {k} spans {3 * dt[k]} s")
    events: list[Odometry] = []
    for k in range(len(rel)):
        a = float(t0[k])
        h = float(dt[k])
        events.append(Odometry(a + h, h, 0.0, float(alpha[k] / h)))
        events.append(Odometry(a + 2 * h, h, float(d[k] / h), 0.0))
        events.append(Odometry(float(t1[k]), h, 0.0, float(beta[k] / h)))
    return events


def sequence_from_relative(name: str, stamps_s: np.ndarray, rel: np.ndarray, obs_pose: np.ndarray,
                           obs_landmark: np.ndarray, body_p_landmark: np.ndarray,
                           ground_truth_xytheta: np.ndarray | None = None,
                           world_p_landmarks: Mapping[int, np.ndarray] | None = None,
                           odometry_sigma_xytheta: np.ndarray | None = None,
                           landmark_sigma_m: float | None = None,
                           initial_world_xytheta_body: np.ndarray | None = None,
                           metadata: Mapping | None = None) -> Sequence:
    """Poses 0..N-1 at ``stamps_s`` linked by ``rel`` (N-1, 3); landmark observations from pose
    index ``obs_pose`` (K,) of ``obs_landmark`` at ``body_p_landmark`` (K, 2)."""
    stamps = np.asarray(stamps_s, dtype=float)
    events: list[Event] = odometry_segments(rel, stamps[:-1], stamps[1:])
    body = np.asarray(body_p_landmark, dtype=float).reshape(-1, 2)
    ranges = np.hypot(body[:, 0], body[:, 1])
    bearings = np.arctan2(body[:, 1], body[:, 0])
    order = np.argsort(obs_pose, kind="stable")
    obs_pose = np.asarray(obs_pose)[order]
    split = np.flatnonzero(np.diff(obs_pose)) + 1
    for idx in np.split(np.arange(len(obs_pose)), split):
        if len(idx) == 0:
            continue
        rows = order[idx]
        events.append(RangeBearing(float(stamps[obs_pose[idx[0]]]), np.asarray(obs_landmark)[rows].astype(np.int64),
                                   ranges[rows], bearings[rows]))
    meta = dict(metadata or {})
    _require_finite_events(events, meta.get("source"))
    dt_seg = float(np.median(np.diff(stamps))) / 3.0 if len(stamps) > 1 else 1.0
    if odometry_sigma_xytheta is not None:
        sx, sy, st = (float(v) for v in odometry_sigma_xytheta)
        meta["odometry_relative_sigma"] = [sx, sy, st]
        # translation noise over one drive segment, heading noise shared by the two turns
        meta["odometry_sigma"] = [max(sx, sy) / dt_seg, st / (np.sqrt(2.0) * dt_seg)]
    if landmark_sigma_m is not None and len(ranges):
        meta["landmark_cartesian_sigma_m"] = float(landmark_sigma_m)
        meta["range_bearing_sigma"] = [float(landmark_sigma_m), float(landmark_sigma_m / np.median(ranges))]
    meta.setdefault("noise_note", "odometry_sigma and range_bearing_sigma are converted from the "
                                  "dataset's (x, y, theta) and Cartesian noise; approximate")
    meta.setdefault("units", "SI (m, s, rad)")
    meta.setdefault("initial_pose_sigma", [1e-3, 1e-3, 1e-3])
    gt = None
    if ground_truth_xytheta is not None:
        gt = Trajectory.from_se2(stamps, ground_truth_xytheta)
        if initial_world_xytheta_body is None:
            initial_world_xytheta_body = np.asarray(ground_truth_xytheta[0], dtype=float)
    return Sequence.from_events(name, events, ground_truth=gt, world_p_landmarks=world_p_landmarks,
                                initial_world_xytheta_body=initial_world_xytheta_body, metadata=meta)


def _require_finite_events(events: list[Event], path) -> None:
    """Finite numbers that overflow on the way (1e308 m in 1/3 s) make a DataError, not events a
    filter would choke on."""
    for e in events:
        values = ([e.stamp_s, e.dt_s, e.v_mps, e.omega_radps] if isinstance(e, Odometry)
                  else [e.stamp_s, *np.asarray(e.range_m).tolist(), *np.asarray(e.bearing_rad).tolist()])
        if not np.isfinite(values).all():
            raise DataError(f"{type(e).__name__} at stamp {e.stamp_s!r} s is not finite (values overflow)",
                            path)


# --------------------------------------------------------------------------------------------
# iSAM-style files (cityTrees10000, Victoria Park)


def _isam_parts(path: Path, max_poses: int | None):
    from slamkit.data.formats.isam import read_isam_with_landmarks

    graph, lms = read_isam_with_landmarks(path)
    if graph.dim != 2 or lms is None:
        raise DataError("expected a 2D iSAM file with LANDMARK records", path)
    # every edge of these files is odometry (in file order); ``is_odometry`` would call 4 -> 6 a
    # loop closure where the ids skip a landmark's number
    odo = np.ones(len(graph.edge_from), dtype=bool)
    e_from, e_to = graph.edge_from[odo], graph.edge_to[odo]
    # the odometry edges must form one chain; pose ids need not be consecutive (Victoria Park
    # numbers poses and landmarks from one counter)
    if len(e_from) == 0 or np.any(e_to[:-1] != e_from[1:]):
        k = 0 if len(e_from) == 0 else int(np.flatnonzero(e_to[:-1] != e_from[1:])[0]) + 1
        raise DataError(f"odometry edge {k} does not continue the chain of poses", path)
    pose_ids = np.concatenate([e_from[:1], e_to])
    n = len(pose_ids) if max_poses is None else min(int(max_poses), len(pose_ids))
    pose_ids = pose_ids[:n]
    rel = graph.measurements[odo][: n - 1]
    info = graph.information[odo][: n - 1]
    order = np.argsort(pose_ids)
    pos = np.clip(np.searchsorted(pose_ids, lms.pose_id, sorter=order), 0, n - 1)
    index = order[pos]
    keep = pose_ids[index] == lms.pose_id
    return rel, info, n, lms, keep, index


def read_isam_landmark_sequence(path: str | Path, name: str | None = None, max_poses: int | None = None,
                                pose_dt_s: float = 1.0, ground_truth_path: str | Path | None = None,
                                covariance_entries: bool = False) -> Sequence:
    """An iSAM 2D file with LANDMARK records as a Sequence (poses every ``pose_dt_s``).

    ``covariance_entries``: the file stores covariances where iSAM stores square-root
    information (Victoria Park in the gtsam wheel). ``ground_truth_path``: the noise-free twin
    whose composed odometry and landmark offsets are the ground truth (cityTrees10000)."""
    path = Path(path)
    rel, info, n, lms, keep, index = _isam_parts(path, max_poses)
    if covariance_entries:
        # the parser built R^T R from the entries; the entries are (upper-triangular) covariances:
        # their diagonals are the variances (off-diagonals are zero in these files)
        sig_odo = np.median(_cov_sigmas(path, "ODOMETRY", 3), axis=0)
        sig_lm = float(np.median(_cov_sigmas(path, "LANDMARK", 2)))
    else:
        sig_odo = np.median(1.0 / np.sqrt(np.diagonal(info, axis1=1, axis2=2)), axis=0)
        sig_lm = float(np.median(1.0 / np.sqrt(np.diagonal(lms.information[keep], axis1=1, axis2=2))))
    stamps = np.arange(n) * float(pose_dt_s)
    gt_poses = world_lm = None
    if ground_truth_path is not None:
        gt_rel, _, gn, gt_lms, gkeep, gindex = _isam_parts(Path(ground_truth_path), max_poses)
        if gn != n or not np.array_equal(gt_lms.pose_id, lms.pose_id):
            raise DataError("ground-truth twin does not have the same structure", ground_truth_path)
        gt_poses = chain(np.zeros(3), gt_rel)
        pose_idx = gindex[gkeep]
        world = se2.compose(gt_poses[pose_idx], np.column_stack([gt_lms.body_p_landmark[gkeep], np.zeros(gkeep.sum())]))
        world_lm = {}
        for lid, p in zip(gt_lms.landmark_id[gkeep], world[:, :2]):
            world_lm.setdefault(int(lid), p)  # noise-free: every sighting gives the same point
    start = np.zeros(3)
    return sequence_from_relative(
        name or path.stem, stamps, rel, index[keep], lms.landmark_id[keep], lms.body_p_landmark[keep],
        gt_poses, world_lm, sig_odo, sig_lm, initial_world_xytheta_body=start,
        metadata={"source": str(path), "format": "isam", "num_poses": n,
                  "known_correspondences": True})


def _cov_sigmas(path: Path, tag: str, dim: int) -> np.ndarray:
    """(K, dim) standard deviations: sqrt of the covariance diagonals of ``tag`` records."""
    rows = []
    n_upper = dim * (dim + 1) // 2
    for lineno, line in enumerate(read_lines(path), 1):
        parts = line.split()
        if parts[:1] == [tag]:
            if len(parts) != 3 + dim + n_upper:
                raise DataError(f"malformed {tag} record", path, lineno)
            upper = [parse_number(x, f"{tag} covariance entry", path, lineno) for x in parts[3 + dim:]]
            diag = [upper[0], upper[dim]] if dim == 2 else [upper[0], upper[3], upper[5]]
            if not (np.isfinite(upper).all() and min(diag) >= 0):
                raise DataError(f"{tag} covariance has a negative or non-finite variance", path, lineno)
            rows.append(upper)
    if not rows:
        raise DataError(f"no {tag} records", path)
    diag_idx = [0, dim] if dim == 2 else [0, 3, 5]
    return np.sqrt(np.array(rows)[:, diag_idx])


# --------------------------------------------------------------------------------------------
# PyFG (mrclam5a)


def read_pyfg_landmark_sequence(path: str | Path, robot: str = "A", name: str | None = None) -> Sequence:
    """One robot of a PyFG file: its odometry chain and pose-landmark observations; the VERTEX
    values (Vicon-derived for MRCLAM) are the ground truth."""
    path = Path(path)
    poses: dict[int, tuple[float, np.ndarray]] = {}
    landmarks: dict[int, np.ndarray] = {}
    odo: list[tuple[int, int, np.ndarray, np.ndarray]] = []
    obs: list[tuple[int, int, np.ndarray, float]] = []
    fields = {"VERTEX_SE2": 6, "VERTEX_XY": 4, "EDGE_SE2": 13, "EDGE_SE2_XY": 9}
    for lineno, line in enumerate(read_lines(path), 1):
        parts = line.split()
        if not parts:
            continue
        tag = parts[0]
        if tag in fields and len(parts) != fields[tag]:
            raise DataError(f"malformed {tag} record: {len(parts) - 1} fields after the tag, expected "
                            f"{fields[tag] - 1}", path, lineno)

        def num(k: int) -> float:
            value = parse_number(parts[k], f"malformed {tag} record: field {k}", path, lineno)
            if not np.isfinite(value):
                raise DataError(f"{tag} field {k} is {parts[k]!r}, expected a finite number", path, lineno)
            return value

        def key(k: int, prefix: str) -> int:
            return parse_int(parts[k][len(prefix):], f"{tag} field {k} ({parts[k]!r}) index", path, lineno)

        if tag == "VERTEX_SE2" and parts[2].startswith(robot):
            poses[key(2, robot)] = (num(1), np.array([num(k) for k in (3, 4, 5)]))
        elif tag == "VERTEX_XY":
            landmarks[key(1, "L" if parts[1].startswith("L") else "")] = np.array([num(2), num(3)])
        elif tag == "EDGE_SE2" and parts[2].startswith(robot) and parts[3].startswith(robot):
            cov = np.array([num(k) for k in range(7, 13)])
            if np.any(cov[[0, 3, 5]] < 0):
                raise DataError("EDGE_SE2 has a negative variance", path, lineno)
            odo.append((key(2, robot), key(3, robot), np.array([num(k) for k in (4, 5, 6)]), cov))
        elif tag == "EDGE_SE2_XY" and parts[2].startswith(robot) and parts[3].startswith("L"):
            obs.append((key(2, robot), key(3, "L"), np.array([num(4), num(5)]), num(6)))
    if not poses:
        raise DataError(f"no VERTEX_SE2 of robot {robot!r}", path)
    ids = np.array(sorted(poses))
    if not np.array_equal(ids, np.arange(len(ids))):
        raise DataError(f"robot {robot!r} pose indices are not 0..N-1", path)
    stamps_abs = np.array([poses[i][0] for i in ids])
    gt = np.array([poses[i][1] for i in ids])
    rel = np.zeros((len(ids) - 1, 3))
    have = np.zeros(len(ids) - 1, dtype=bool)
    sig = []
    for a, b, z, cov in odo:
        if b != a + 1:
            raise DataError(f"odometry edge {robot}{a} -> {robot}{b} skips poses", path)
        rel[a], have[a] = z, True
        sig.append(np.sqrt(cov[[0, 3, 5]]))
    if not have.all():
        raise DataError(f"robot {robot!r} has no odometry edge after pose {int(np.flatnonzero(~have)[0])}", path)
    t0 = float(stamps_abs[0])
    obs_pose = np.array([o[0] for o in obs], dtype=np.int64)
    return sequence_from_relative(
        name or f"{path.stem}_{robot}", stamps_abs - t0, rel, obs_pose,
        np.array([o[1] for o in obs], dtype=np.int64), np.array([o[2] for o in obs]).reshape(-1, 2),
        gt, landmarks, np.median(np.array(sig), axis=0),
        float(np.sqrt(np.median([o[3] for o in obs]))) if obs else None,
        metadata={"source": str(path), "format": "pyfg", "robot": robot, "time_offset_s": t0,
                  "known_correspondences": True})


# --------------------------------------------------------------------------------------------
# raw MRCLAM


def _table(path: Path, columns: int) -> np.ndarray:
    """Rows of ``columns`` finite numbers (``#`` comments and blank lines skipped)."""
    return number_rows(path, columns, "no data rows")[1]


def read_mrclam_sequence(odometry_path: str | Path, measurement_path: str | Path,
                         landmark_groundtruth_path: str | Path, barcodes_path: str | Path,
                         name: str = "mrclam1", max_duration_s: float | None = None,
                         odometry_sigma: tuple[float, float] = (0.05, 0.1),
                         range_bearing_sigma: tuple[float, float] = (0.15, 0.05)) -> Sequence:
    """Raw MRCLAM robot files as a Sequence (see the module docstring).

    The dataset gives no noise figures; ``odometry_sigma`` (v m/s, omega rad/s) and
    ``range_bearing_sigma`` (m, rad) are the assumed values, stored in the metadata."""
    odo = _table(Path(odometry_path), 3)
    meas = _table(Path(measurement_path), 4)
    lm = _table(Path(landmark_groundtruth_path), 5)
    codes = _table(Path(barcodes_path), 2)
    t0 = float(odo[0, 0])
    barcode_to_subject = {int(b): int(s) for s, b in codes}
    landmark_subjects = {int(s) for s in lm[:, 0]}
    t = odo[:, 0] - t0
    meas_t = meas[:, 0] - t0
    if max_duration_s is not None:
        t_keep = t <= max_duration_s
        odo, t = odo[t_keep], t[t_keep]
        m_keep = meas_t <= max_duration_s
        meas, meas_t = meas[m_keep], meas_t[m_keep]
    if np.any(np.diff(t) < 0):
        k = int(np.flatnonzero(np.diff(t) < 0)[0])
        raise DataError(f"odometry time goes backwards at data row {k + 2}", odometry_path)
    events: list[Event] = [Odometry(float(t[k]), float(t[k] - t[k - 1]), float(odo[k, 1]), float(odo[k, 2]))
                           for k in range(1, len(t))]
    subjects = np.array([barcode_to_subject.get(int(b), -1) for b in meas[:, 1]], dtype=np.int64)
    is_landmark = np.isin(subjects, list(landmark_subjects))
    meas, meas_t, subjects = meas[is_landmark], meas_t[is_landmark], subjects[is_landmark]
    # measurements before the first odometry reading have no motion to attach to
    after = meas_t >= 0.0
    meas, meas_t, subjects = meas[after], meas_t[after], subjects[after]
    split = np.flatnonzero(np.diff(meas_t)) + 1
    for idx in np.split(np.arange(len(meas_t)), split):
        if len(idx):
            events.append(RangeBearing(float(meas_t[idx[0]]), subjects[idx], meas[idx, 2], meas[idx, 3]))
    world_lm = {int(s): np.array([x, y]) for s, x, y, _, _ in lm}
    return Sequence.from_events(name, events, ground_truth=None, world_p_landmarks=world_lm,
                                initial_world_xytheta_body=None, metadata={
                                    "source": str(odometry_path), "format": "mrclam", "time_offset_s": t0,
                                    "odometry_sigma": list(odometry_sigma),
                                    "range_bearing_sigma": list(range_bearing_sigma),
                                    "noise_note": "assumed noise: the dataset publishes none",
                                    "landmark_sigma_m": lm[:, 3:5].tolist(),
                                    "known_correspondences": True, "units": "SI (m, s, rad)"})


# --------------------------------------------------------------------------------------------
# registry front door


def load_landmark_sequence(name: str, **params) -> Sequence:
    """A registry landmark dataset as a Sequence: ``citytrees10000`` (params: max_poses,
    pose_dt_s), ``victoria-park`` (max_poses, pose_dt_s), ``mrclam5a`` (robot),
    ``mrclam1`` (max_duration_s, odometry_sigma, range_bearing_sigma)."""
    from slamkit.data import registry

    entry = registry.get(name)
    key = entry.name
    if key == "citytrees10000":
        return read_isam_landmark_sequence(registry.path_of(key, "cityTrees10000.txt"), name=key,
                                           ground_truth_path=registry.path_of(key, "cityTrees10000_groundtruth.txt"),
                                           **params)
    if key == "victoria-park":
        return read_isam_landmark_sequence(registry.path_of(key), name=key, covariance_entries=True, **params)
    if key == "mrclam5a":
        return read_pyfg_landmark_sequence(registry.path_of(key), name=None, **params)
    if key == "mrclam1":
        files = [registry.path_of(key, f) for f in ("Robot1_Odometry.dat", "Robot1_Measurement.dat",
                                                     "Landmark_Groundtruth.dat", "Barcodes.dat")]
        return read_mrclam_sequence(*files, name=key, **params)
    raise DataError(f"dataset {name!r} is not a landmark dataset slamkit reads as a sequence; "
                    f"use one of {LANDMARK_DATASETS}")
