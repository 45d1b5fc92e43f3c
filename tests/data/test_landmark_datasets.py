"""Landmark datasets as Sequences: counts from MANIFEST.md, odometry that composes exactly, ground
truth that agrees with the registry, and DataErrors that name the file and line."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit.data.formats.landmark_datasets import (
    chain,
    load_landmark_sequence,
    odometry_segments,
    read_mrclam_sequence,
    read_pyfg_landmark_sequence,
)
from slamkit.data.sequence import Odometry, RangeBearing
from slamkit.geometry import se2
from slamkit.errors import DataError
from slamkit.models import diff_drive


def _integrate(start: np.ndarray, events) -> np.ndarray:
    x = np.asarray(start, dtype=float)
    for e in events:
        x = diff_drive.motion(x, np.array([e.v_mps, e.omega_radps]), e.dt_s)
    return x


def test_rotate_translate_rotate_worked_examples() -> None:
    # (1, 0, pi/2) over 3 s: no first turn, drive 1 m in 1 s, turn pi/2 in 1 s
    ev = odometry_segments(np.array([[1.0, 0.0, np.pi / 2]]), np.array([0.0]), np.array([3.0]))
    np.testing.assert_allclose([(e.stamp_s, e.dt_s, e.v_mps, e.omega_radps) for e in ev],
                               [(1.0, 1.0, 0.0, 0.0), (2.0, 1.0, 1.0, 0.0), (3.0, 1.0, 0.0, np.pi / 2)])
    # a step backwards drives backwards rather than turning round twice
    ev = odometry_segments(np.array([[-1.0, 0.0, 0.0]]), np.array([0.0]), np.array([3.0]))
    np.testing.assert_allclose([(e.v_mps, e.omega_radps) for e in ev], [(0, 0), (-1.0, 0), (0, 0)], atol=1e-12)
    # (1, 1, 0): turn 45 degrees, drive sqrt(2), turn back
    ev = odometry_segments(np.array([[1.0, 1.0, 0.0]]), np.array([0.0]), np.array([0.3]))
    np.testing.assert_allclose([(e.v_mps, e.omega_radps) for e in ev],
                               [(0.0, np.pi / 4 / 0.1), (np.sqrt(2) / 0.1, 0.0), (0.0, -np.pi / 4 / 0.1)],
                               atol=1e-12)
    with pytest.raises(DataError, match="must increase"):
        odometry_segments(np.zeros((1, 3)), np.array([1.0]), np.array([1.0]))


@settings(max_examples=60, deadline=None)
@given(st.floats(-5, 5), st.floats(-5, 5), st.floats(-3.1, 3.1), st.floats(-3.1, 3.1),
       st.floats(0.05, 5.0))
def test_odometry_events_compose_to_the_relative_pose(dx, dy, dth, th0, dt) -> None:
    start = np.array([0.3, -1.2, th0])
    rel = np.array([[dx, dy, dth]])
    end = _integrate(start, odometry_segments(rel, np.array([0.0]), np.array([dt])))
    expected = se2.compose(start[None], rel)[0]
    np.testing.assert_allclose(end[:2], expected[:2], atol=1e-9)
    assert np.angle(np.exp(1j * (end[2] - expected[2]))) == pytest.approx(0.0, abs=1e-9)


def test_citytrees10000(shared_datasets) -> None:
    from slamkit.data import registry

    seq = load_landmark_sequence("citytrees10000")
    odo, rb = seq.of_type(Odometry), seq.of_type(RangeBearing)
    # MANIFEST: 10,000 poses, 9,999 odometry edges (3 events each), 4,443 sightings, 100 landmarks
    assert len(seq.ground_truth) == 10000 and len(odo) == 3 * 9999
    assert sum(len(e.landmark_ids) for e in rb) == 4443
    assert len(seq.world_p_landmarks) == 100
    # ground truth = the registry's noise-free composition (stamps = pose ids = seconds)
    reg = registry.ground_truth("citytrees10000")
    np.testing.assert_allclose(seq.ground_truth.xytheta()[:, :2], reg.xytheta()[:, :2], atol=1e-6)
    # integrating the (noisy) odometry events reproduces the noisy chain of the file exactly
    end = _integrate(seq.initial_world_xytheta_body, odo[:300])
    from slamkit.data.formats.isam import read_isam

    noisy = read_isam(registry.path_of("citytrees10000", "cityTrees10000.txt"))
    np.testing.assert_allclose(end, chain(np.zeros(3), noisy.measurements[:100])[-1], atol=1e-9)
    # iSAM sqrt information 50 / 100 and 10: sigma 0.02 m, 0.01 rad and 0.1 m (converted for filters)
    assert seq.metadata["odometry_relative_sigma"] == pytest.approx([0.02, 0.02, 0.01])
    assert seq.metadata["range_bearing_sigma"][0] == pytest.approx(0.1)
    # measured ranges scatter about the true ones with that 0.1 m sigma
    gt = seq.ground_truth
    index = {float(t): k for k, t in enumerate(gt.stamps_s)}
    res = []
    for e in rb:
        pose = gt.xytheta()[index[e.stamp_s]]
        lm = np.array([seq.world_p_landmarks[int(i)] for i in e.landmark_ids])
        res.extend(np.asarray(e.range_m) - np.hypot(*(lm - pose[:2]).T))
    assert np.std(res) == pytest.approx(0.1, rel=0.15)
    assert abs(np.mean(res)) < 0.01
    short = load_landmark_sequence("citytrees10000", max_poses=50)
    assert len(short.ground_truth) == 50 and len(short.of_type(Odometry)) == 147


def test_victoria_park_has_no_ground_truth() -> None:
    try:
        seq = load_landmark_sequence("victoria-park")
    except DataError as exc:
        pytest.skip(f"gtsam wheel data missing: {exc}")
    # MANIFEST: 6,969 poses, 6,968 odometry, 3,640 landmark measurements of 151 landmarks
    assert len(seq.of_type(Odometry)) == 3 * 6968
    rb = seq.of_type(RangeBearing)
    assert sum(len(e.landmark_ids) for e in rb) == 3640
    assert len(np.unique(np.concatenate([e.landmark_ids for e in rb]))) == 151
    assert seq.ground_truth is None and not seq.world_p_landmarks
    # covariance entries 1e-4 / 4e-6 and 0.4: sigmas 0.01 m, 0.002 rad, 0.632 m
    assert seq.metadata["odometry_relative_sigma"] == pytest.approx([0.01, 0.002, 0.002])
    assert seq.metadata["range_bearing_sigma"][0] == pytest.approx(np.sqrt(0.4))


def test_mrclam5a_robot_a(shared_datasets) -> None:
    seq = load_landmark_sequence("mrclam5a")
    gt = seq.ground_truth
    assert len(gt) == 275 and len(seq.world_p_landmarks) == 15
    assert len(seq.of_type(Odometry)) == 3 * 274
    assert sum(len(e.landmark_ids) for e in seq.of_type(RangeBearing)) == 371
    assert set(int(i) for e in seq.of_type(RangeBearing) for i in e.landmark_ids) <= set(range(6, 21))
    # the first VERTEX_SE2 of A (Vicon) is the start; stamps count from its Unix time
    np.testing.assert_allclose(seq.initial_world_xytheta_body, [1.271436699, 3.049075753, -1.1553912])
    assert gt.stamps_s[0] == 0.0 and seq.metadata["time_offset_s"] == pytest.approx(1248362857.7)
    # all five robots: 1,080 poses in total
    total = sum(len(load_landmark_sequence("mrclam5a", robot=r).ground_truth) for r in "ABCDE")
    assert total == 1080


def test_mrclam1_raw(shared_datasets) -> None:
    seq = load_landmark_sequence("mrclam1", max_duration_s=120.0)
    odo, rb = seq.of_type(Odometry), seq.of_type(RangeBearing)
    assert seq.ground_truth is None and len(seq.world_p_landmarks) == 15
    # landmarks are subjects 6-20; robot sightings (subjects 1-5) are dropped
    ids = np.concatenate([e.landmark_ids for e in rb])
    assert ids.min() >= 6 and ids.max() <= 20
    assert odo[0].stamp_s == pytest.approx(0.011, abs=1e-6) and odo[0].v_mps == pytest.approx(0.074)
    assert seq.events[-1].stamp_s <= 120.0
    full = load_landmark_sequence("mrclam1")
    # MANIFEST: 97,890 odometry rows (the first starts the clock), 5,723 measurements of which
    # 4,771 see one of the 15 landmarks after the first odometry reading
    assert len(full.of_type(Odometry)) == 97889
    assert sum(len(e.landmark_ids) for e in full.of_type(RangeBearing)) == 4771


def test_bad_input_names_file_and_line(tmp_path) -> None:
    bad = tmp_path / "bad.pyfg"
    bad.write_text("VERTEX_SE2 0.0 A0 0 0 0\nVERTEX_SE2 1.0 A1 zero 0 0\n")
    with pytest.raises(DataError, match=r"bad.pyfg:2: malformed VERTEX_SE2"):
        read_pyfg_landmark_sequence(bad)
    gap = tmp_path / "gap.pyfg"
    gap.write_text("VERTEX_SE2 0.0 A0 0 0 0\nVERTEX_SE2 1.0 A1 1 0 0\n")
    with pytest.raises(DataError, match="no odometry edge after pose 0"):
        read_pyfg_landmark_sequence(gap)
    odo = tmp_path / "odo.dat"
    odo.write_text("# header\n1.0 0.1 0.0\n1.1 0.1 x\n")
    for name, text in [("m.dat", "1.0 14 2.0 0.1\n"), ("l.dat", "6 1 2 0 0\n"), ("b.dat", "6 14\n")]:
        (tmp_path / name).write_text(text)
    with pytest.raises(DataError, match="odo.dat:3: field 3 is 'x', expected a number"):
        read_mrclam_sequence(odo, tmp_path / "m.dat", tmp_path / "l.dat", tmp_path / "b.dat")
