"""PGM/PNG decoding (Pillow, slamkit.data.formats.image) and the ROS map_server pixel rule, with a
PNG encoder written here from the specification (every scanline filter) as the oracle."""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from slamkit.errors import ConfigError, DataError
from slamkit.data.formats.image import MAX_IMAGE_PIXELS, read_image
from slamkit.maps.image_map import occupancy_from_image
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.sim.ros_map import load_ros_map, save_ros_map


def _paeth(a, b, c):
    p = a + b - c
    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
    return a if (pa <= pb and pa <= pc) else (b if pb <= pc else c)


def encode_png(img: np.ndarray, color_type: int, filters, palette=None) -> bytes:
    """Minimal PNG encoder: img (H, W, C) uint8; filters[y] in 0..4 per row."""
    h, w = img.shape[:2]
    bpp = img.shape[2]
    rows = img.reshape(h, w * bpp).astype(int)
    out = bytearray()
    for y in range(h):
        f = filters[y % len(filters)]
        out.append(f)
        for x in range(w * bpp):
            a = rows[y, x - bpp] if x >= bpp else 0
            b = rows[y - 1, x] if y > 0 else 0
            c = rows[y - 1, x - bpp] if (y > 0 and x >= bpp) else 0
            pred = [0, a, b, (a + b) // 2, _paeth(a, b, c)][f]
            out.append((rows[y, x] - pred) & 0xFF)

    def chunk(t, body):
        return struct.pack(">I", len(body)) + t + body + struct.pack(">I", zlib.crc32(t + body))

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, color_type, 0, 0, 0))
    if palette is not None:
        png += chunk(b"PLTE", palette.astype(np.uint8).tobytes())
    return png + chunk(b"IDAT", zlib.compress(bytes(out))) + chunk(b"IEND", b"")


@settings(max_examples=30, deadline=None)
@given(img=arrays(np.uint8, st.tuples(st.integers(1, 7), st.integers(1, 7), st.sampled_from([1, 2, 3, 4]))),
       filters=st.lists(st.integers(0, 4), min_size=1, max_size=5))
def test_png_decoder_inverts_every_filter(tmp_path_factory, img, filters):
    color = {1: 0, 2: 4, 3: 2, 4: 6}[img.shape[2]]
    path = tmp_path_factory.mktemp("png") / "m.png"
    path.write_bytes(encode_png(img, color, filters))
    expected = img[..., :3].astype(float).mean(axis=-1) if img.shape[2] >= 3 else img[..., 0].astype(float)
    np.testing.assert_allclose(read_image(path), expected)


def test_palette_png_and_bad_png(tmp_path):
    pal = np.array([[0, 0, 0], [254, 254, 254], [205, 205, 205]])
    idx = np.array([[0, 1, 2]], dtype=np.uint8)[..., None]
    (tmp_path / "p.png").write_bytes(encode_png(idx, 3, [0], palette=pal))
    np.testing.assert_allclose(read_image(tmp_path / "p.png"), [[0, 254, 205]])
    data = bytearray((tmp_path / "p.png").read_bytes())
    data[-20] ^= 0xFF  # corrupt the IDAT chunk
    (tmp_path / "bad.png").write_bytes(bytes(data))
    with pytest.raises(DataError, match="bad.png"):
        read_image(tmp_path / "bad.png")


def test_pgm_binary_ascii_16bit_comments_and_truncation(tmp_path):
    (tmp_path / "a.pgm").write_bytes(b"P5\n# made by hand\n3 2\n255\n" + bytes([0, 100, 255, 254, 205, 0]))
    np.testing.assert_allclose(read_image(tmp_path / "a.pgm"), [[0, 100, 255], [254, 205, 0]])
    (tmp_path / "b.pgm").write_text("P2\n3 1 # width height\n15\n0 15\n 5\n")
    np.testing.assert_allclose(read_image(tmp_path / "b.pgm"), [[0, 255, 85]])
    (tmp_path / "c.pgm").write_bytes(b"P5 2 1 65535\n" + struct.pack(">HH", 0, 65535))
    np.testing.assert_allclose(read_image(tmp_path / "c.pgm"), [[0, 255]])
    (tmp_path / "d.pgm").write_bytes(b"P5\n3 2\n255\n" + bytes([0, 1]))
    with pytest.raises(DataError) as info:
        read_image(tmp_path / "d.pgm")
    assert str(info.value).startswith(f"{tmp_path / 'd.pgm'}: PPM image data is truncated or corrupt: ")
    (tmp_path / "e.txt").write_text("hello")
    with pytest.raises(DataError, match="unsupported image format"):
        read_image(tmp_path / "e.txt")


def test_map_server_rule_and_orientation():
    # top row: occupied (0), free (254), unknown (205); bottom row: all free
    grey = np.array([[0, 254, 205], [254, 254, 254]], dtype=float)
    m = occupancy_from_image(grey, 0.05, (-1.0, 2.0))
    # the image's top row is the grid's last row (largest y)
    assert m.grid.occupied.tolist() == [[False, False, False], [True, False, True]]
    assert m.unknown.tolist() == [[False, False, False], [False, False, True]]
    assert m.grid.is_free_world(np.array([[-0.975, 2.075], [-0.925, 2.075]])).tolist() == [False, True]
    free_unknown = occupancy_from_image(grey, 0.05, unknown_is_occupied=False)
    assert free_unknown.grid.occupied.sum() == 1
    # negate: bright pixels are occupied
    assert occupancy_from_image(grey, 0.05, negate=True).grid.occupied[0].all()


def test_ros_yaml_round_trip_and_errors(tmp_path):
    rng = np.random.default_rng(0)
    grid = OccupancyGrid(rng.random((12, 17)) < 0.3, 0.1, np.array([-3.0, 1.5]))
    unknown = rng.random((12, 17)) < 0.1
    path = save_ros_map(tmp_path / "room.yaml", grid, unknown)
    back = load_ros_map(path, unknown_is_occupied=False)
    np.testing.assert_array_equal(back.grid.occupied, grid.occupied)
    np.testing.assert_array_equal(back.unknown, unknown & ~grid.occupied)
    assert back.grid.resolution_m == 0.1 and back.grid.origin_xy_m.tolist() == [-3.0, 1.5]
    (tmp_path / "noimg.yaml").write_text("resolution: 0.1\norigin: [0, 0, 0]\n")
    # the map YAML is a config: validated into a typed model, errors name file, line and field
    with pytest.raises(ConfigError, match="noimg.yaml:1: image: required but missing"):
        load_ros_map(tmp_path / "noimg.yaml")
    (tmp_path / "typo.yaml").write_text("image: room.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegat: 1\n")
    with pytest.raises(ConfigError, match=r"typo.yaml:4: negat: unknown key \(did you mean 'negate'\?\)"):
        load_ros_map(tmp_path / "typo.yaml")
    (tmp_path / "nan.yaml").write_text("image: room.pgm\nresolution: .nan\norigin: [0, 0, 0]\n")
    with pytest.raises(ConfigError, match=r"nan.yaml:2: resolution: Input should be a finite number"):
        load_ros_map(tmp_path / "nan.yaml")
    (tmp_path / "rot.yaml").write_text("image: room.pgm\nresolution: 0.1\norigin: [0, 0, 0.5]\n")
    with pytest.raises(DataError, match="rotated"):
        load_ros_map(tmp_path / "rot.yaml")


def test_oversized_png_header_is_refused_before_decoding(tmp_path):
    # issue 10: a tiny PNG declaring 30000 x 30000 pixels (900 M) took 18 GB before a MemoryError
    png = bytearray(encode_png(np.zeros((1, 1, 1), np.uint8), 0, [0]))
    png[16:24] = struct.pack(">II", 30000, 30000)
    png[29:33] = struct.pack(">I", zlib.crc32(bytes(png[12:29])))  # keep the IHDR CRC valid
    (tmp_path / "huge.png").write_bytes(bytes(png))
    with pytest.raises(DataError) as info:
        read_image(tmp_path / "huge.png")
    assert str(info.value) == (f"{tmp_path / 'huge.png'}: image declares 30000 x 30000 = 900000000 pixels, "
                               f"more than the limit of {MAX_IMAGE_PIXELS}")
    assert MAX_IMAGE_PIXELS == 100_000_000


def test_16_bit_pgm_and_png(tmp_path):
    (tmp_path / "a.pgm").write_bytes(b"P5\n3 1\n1000\n" + struct.pack(">HHH", 0, 1000, 200))
    # Pillow scales maxval 1000 to 0..65535 (200 -> 13107): 13107 * 255 / 65535 = 51.0
    np.testing.assert_allclose(read_image(tmp_path / "a.pgm"), [[0.0, 255.0, 51.0]])
    (tmp_path / "b.pgm").write_text("P2\n2 1\n65535\n65535 0\n")
    np.testing.assert_allclose(read_image(tmp_path / "b.pgm"), [[255.0, 0.0]])
