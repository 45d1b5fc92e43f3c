"""The .slamseq sequence file: exact round trip of every event kind, byte-identical files for
equal input, lazy reading, and DataError naming file and record on bad input."""

from __future__ import annotations

import hashlib
import json
import zipfile

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit.data.formats.sequence import load_sequence, open_sequence, save_sequence
from slamkit.data.sequence import Gps, Imu, Odometry, RangeBearing, Scan, Sequence, WheelEncoders
from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError


def _mixed_sequence() -> Sequence:
    events = (
        Odometry(0.1, 0.1, 1.0, -0.2),
        RangeBearing(0.1, np.array([3, 7]), np.array([2.5, 4.0]), np.array([0.1, -1.2])),
        RangeBearing(0.2, np.zeros(0, np.int64), np.zeros(0), np.zeros(0)),  # saw nothing
        Imu(0.2, np.array([0.0, 0.01, 0.3]), np.array([0.1, 0.0, 9.81])),
        WheelEncoders(0.2, 120, -4),
        Gps(0.5, np.array([1.0, 2.0, 0.0]), 2.5),
        Scan(0.5, np.linspace(-1, 1, 5), np.array([1.0, np.nan, 2.0, 3.0, np.nan]), 8.0),
        Odometry(0.5, 0.4, 0.0, 0.0),
    )
    gt = Trajectory.from_se2(np.array([0.0, 0.1, 0.5]), np.array([[0, 0, 0], [0.1, 0, 0.1], [0.4, 0.1, 0.2]]))
    return Sequence("mixed", events, ground_truth=gt,
                    world_p_landmarks={3: np.array([1.0, 2.0]), 7: np.array([-4.0, 0.5])},
                    initial_world_xytheta_body=np.array([0.0, 0.0, 0.0]),
                    metadata={"odometry_sigma": np.array([0.05, 0.01]), "known": True, "nested": {"k": (1, 2)}})


def _assert_same(a, b):
    assert a.name == b.name and len(a) == len(b)
    for ea, eb in zip(a, b):
        assert type(ea) is type(eb)
        for field in ea.__dataclass_fields__:
            va, vb = getattr(ea, field), getattr(eb, field)
            np.testing.assert_array_equal(np.asarray(va), np.asarray(vb), err_msg=field)


def test_round_trip_every_event_kind(tmp_path):
    seq = _mixed_sequence()
    path = save_sequence(tmp_path / "mixed.slamseq", seq)
    back = load_sequence(path)
    _assert_same(seq, back)
    assert [type(e).__name__ for e in back][:3] == ["Odometry", "RangeBearing", "RangeBearing"]
    np.testing.assert_array_equal(back.ground_truth.world_t_body, seq.ground_truth.world_t_body)
    assert back.ground_truth.planar
    assert set(back.world_p_landmarks) == {3, 7}
    np.testing.assert_array_equal(back.world_p_landmarks[7], [-4.0, 0.5])
    assert back.metadata == {"odometry_sigma": [0.05, 0.01], "known": True, "nested": {"k": [1, 2]}}
    np.testing.assert_array_equal(back.initial_world_xytheta_body, [0, 0, 0])
    # readable as plain npz too
    with np.load(path) as npz:
        np.testing.assert_array_equal(npz["range_bearing/offsets"], [0, 2, 2])


def test_equal_input_gives_identical_bytes_and_compression_round_trips(tmp_path):
    seq = _mixed_sequence()
    a = save_sequence(tmp_path / "a.slamseq", seq).read_bytes()
    b = save_sequence(tmp_path / "b.slamseq", seq).read_bytes()
    assert hashlib.sha256(a).hexdigest() == hashlib.sha256(b).hexdigest()
    c = save_sequence(tmp_path / "c.slamseq", seq, compress=True)
    _assert_same(seq, load_sequence(c))


def test_reader_is_lazy_and_offers_columns(tmp_path):
    n = 50_000
    events = tuple(Odometry(0.01 * (i + 1), 0.01, 1.0, 0.001 * i) for i in range(n))
    path = save_sequence(tmp_path / "long.slamseq", Sequence("long", events))
    reader = open_sequence(path)
    assert len(reader) == n and reader._cache == {}  # nothing but the header read yet
    cols = reader.columns("odometry")
    assert cols["omega_radps"][49_999] == pytest.approx(49.999)
    it = iter(reader)
    first = next(it)
    assert first == Odometry(0.01, 0.01, 1.0, 0.0)
    assert sum(1 for _ in it) == n - 1
    assert reader.columns("scan") == {} and reader.of_type(Scan) == []
    reader.close()


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(["o", "r", "w"]), st.floats(0, 100), st.integers(0, 5)),
                max_size=30))
def test_round_trip_property(tmp_path_factory, spec):
    rng = np.random.default_rng(len(spec))
    events = []
    for kind, t, k in spec:
        if kind == "o":
            events.append(Odometry(t, 0.1, float(rng.normal()), float(rng.normal())))
        elif kind == "r":
            events.append(RangeBearing(t, rng.integers(-1, 9, k), rng.uniform(0, 9, k), rng.uniform(-3, 3, k)))
        else:
            events.append(WheelEncoders(t, int(rng.integers(-999, 999)), int(rng.integers(-999, 999))))
    seq = Sequence("prop", tuple(events))  # order as given, stamps may tie or go backwards
    path = save_sequence(tmp_path_factory.mktemp("p") / "s.slamseq", seq)
    _assert_same(seq, load_sequence(path))


def _rewrite(src, dst, change):
    """Copy a sequence file member by member, letting ``change(name, data)`` alter members."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for name in zin.namelist():
            data = change(name, zin.read(name))
            if data is not None:
                zout.writestr(name, data)
    return dst


def _npy(a):
    import io
    buf = io.BytesIO()
    np.save(buf, a)
    return buf.getvalue()


@pytest.mark.parametrize("case,match", [
    ("truncated", "mixed.slamseq"),
    ("text", "not a readable ZIP"),
    ("missing", "record odometry/v_mps.npy is missing"),
    ("header_json", "record header.json is not valid JSON"),
    ("version", "unsupported version 99"),
    ("rows", "record odometry/dt_s.npy: 1 rows, header says 2"),
    ("offsets", "record range_bearing/offsets.npy"),
    ("order", "not a permutation"),
    ("npy", "record odometry/v_mps.npy is not a valid .npy"),
])
def test_bad_files_raise_data_error_naming_file_and_record(tmp_path, case, match):
    good = save_sequence(tmp_path / "mixed.slamseq", _mixed_sequence())
    bad = tmp_path / "bad.slamseq"
    if case == "truncated":
        bad = tmp_path / "mixed.slamseq"
        data = good.read_bytes()
        bad.write_bytes(data[: len(data) // 2])
    elif case == "text":
        bad.write_text("VERTEX_SE2 0 0 0 0\n")
    elif case == "missing":
        _rewrite(good, bad, lambda n, d: None if n == "odometry/v_mps.npy" else d)
    elif case == "header_json":
        _rewrite(good, bad, lambda n, d: b"{not json" if n == "header.json" else d)
    elif case == "version":
        def change(n, d):
            if n != "header.json":
                return d
            h = json.loads(d)
            h["version"] = 99
            return json.dumps(h).encode()
        _rewrite(good, bad, change)
    elif case == "rows":
        _rewrite(good, bad, lambda n, d: _npy(np.array([0.1])) if n == "odometry/dt_s.npy" else d)
    elif case == "offsets":
        _rewrite(good, bad, lambda n, d: _npy(np.array([0, 3, 2])) if n == "range_bearing/offsets.npy" else d)
    elif case == "order":
        _rewrite(good, bad, lambda n, d: _npy(np.array([0, 0])) if n == "odometry/order.npy" else d)
    elif case == "npy":
        _rewrite(good, bad, lambda n, d: b"garbage" if n == "odometry/v_mps.npy" else d)
    with pytest.raises(DataError, match=match) as info:
        load_sequence(bad)
    assert info.value.path == str(bad)


def test_missing_file_and_non_json_metadata(tmp_path):
    with pytest.raises(DataError, match="no such sequence file"):
        load_sequence(tmp_path / "nope.slamseq")
    seq = Sequence("m", (), metadata={"fn": object()})
    with pytest.raises(DataError, match="metadata.fn"):
        save_sequence(tmp_path / "m.slamseq", seq)
    assert not (tmp_path / "m.slamseq").exists() and not (tmp_path / "m.slamseq.partial").exists()


def test_saving_an_opened_file_reproduces_its_bytes(tmp_path):
    first = save_sequence(tmp_path / "a.slamseq", _mixed_sequence())
    with open_sequence(first) as reader:
        second = save_sequence(tmp_path / "b.slamseq", reader)
    assert first.read_bytes() == second.read_bytes()


def _object_npy() -> bytes:
    import io
    buf = io.BytesIO()
    np.save(buf, np.array([{"a": 1}, None], dtype=object), allow_pickle=True)
    return buf.getvalue()


@pytest.mark.parametrize("member,data,message", [
    ("odometry/v_mps.npy", "object", "record odometry/v_mps.npy is not a valid .npy array: Object arrays "
                                     "cannot be loaded when allow_pickle=False"),
    ("odometry/order.npy", _npy(np.array([0.0, 7.0])), "record odometry/order.npy: dtype float64 is not an "
                                                       "integer type"),
    ("odometry/stamp_s.npy", _npy(np.array([0.1, np.nan])), "record odometry/stamp_s.npy: NaN or infinity "
                                                           "at index 1"),
    ("imu/gyro_radps.npy", _npy(np.zeros((1, 2))), "record imu/gyro_radps.npy: shape (1, 2), expected (n, 3)"),
    ("odometry/dt_s.npy", _npy(np.array(["a", "b"])), "record odometry/dt_s.npy: dtype <U1 is not a number type"),
    ("header.json", b'{"format": "slamkit-sequence", "name": "\xff"}',
     "record header.json is not valid JSON: 'utf-8' codec can't decode byte 0xff in position 40: invalid "
     "start byte"),
    ("header.json", b'{"format": "slamkit-sequence", "version": 1, "num_events": NaN}',
     "record header.json is not valid JSON: NaN is not a JSON number"),
    ("ground_truth/world_t_body.npy", _npy(np.zeros((2, 3))), "record ground_truth/world_t_body.npy: shape "
                                                               "(2, 3), expected (3, 3)"),
])
def test_bad_member_error_text(tmp_path, member, data, message):
    # issue 10: every malformed member is a DataError naming the file and the member
    good = save_sequence(tmp_path / "mixed.slamseq", _mixed_sequence())
    payload = _object_npy() if data == "object" else data
    bad = _rewrite(good, tmp_path / "bad.slamseq", lambda n, d: payload if n == member else d)
    with pytest.raises(DataError) as info:
        with open_sequence(bad) as reader:
            list(reader), reader.ground_truth
    assert str(info.value) == f"{bad}: {message}"


def test_zip_bomb_member_is_refused_before_inflating(tmp_path, monkeypatch):
    import slamkit.data.formats.sequence as fmt
    # 64 MiB of zeros deflates to ~64 KiB; with the limit at 1 MiB it is refused from the directory
    good = save_sequence(tmp_path / "mixed.slamseq", _mixed_sequence())
    bad = tmp_path / "bomb.slamseq"
    with zipfile.ZipFile(good) as zin, zipfile.ZipFile(bad, "w", zipfile.ZIP_DEFLATED) as zout:
        for name in zin.namelist():
            zout.writestr(name, b"\0" * (64 << 20) if name == "landmarks/ids.npy" else zin.read(name))
    assert bad.stat().st_size < (1 << 20)
    assert fmt.MAX_MEMBER_BYTES == 1 << 30
    monkeypatch.setattr(fmt, "MAX_MEMBER_BYTES", 1 << 20)
    with pytest.raises(DataError) as info:
        open_sequence(bad).world_p_landmarks
    assert str(info.value) == (f"{bad}: record landmarks/ids.npy declares 67108864 bytes uncompressed, "
                               "more than the limit of 1048576")
