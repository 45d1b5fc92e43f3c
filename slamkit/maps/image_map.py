"""Occupancy grids from images, as ROS ``map_server`` reads them.

Pixel to occupancy (ROS ``map_server`` / ``nav2_map_server`` "trinary" mode, documented at
wiki.ros.org/map_server): with the pixel's brightness v in 0..255 (the mean of the colour
channels), p = (255 - v) / 255, or v / 255 when ``negate`` is set; p > ``occupied_thresh`` is
occupied, p < ``free_thresh`` is free, anything between is unknown. The image's top row is the
largest y: row r of an H-row image becomes ``occupied[H - 1 - r]`` so that cell (0, 0) sits at
``origin`` (the lower-left corner), as in ROS.

Images are decoded here without an imaging library: binary and ASCII PGM (P5, P2; 8 and 16
bit) and PNG (8-bit greyscale, grey+alpha, RGB, RGBA and palette; non-interlaced), PNG through
``zlib`` and the five scanline filters of the PNG specification (W3C PNG 2nd ed., sec. 9).
The YAML side lives in :mod:`slamkit.sim.ros_map` (algorithm packages do not import yaml).
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slamkit.errors import DataError
from slamkit.maps.occupancy_grid import OccupancyGrid

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def read_pgm(path: str | Path) -> np.ndarray:
    """(H, W) grey levels scaled to 0..255 (float) from a P5 or P2 PGM file."""
    path = Path(path)
    data = path.read_bytes()
    magic = data[:2]
    if magic not in (b"P5", b"P2"):
        raise DataError(f"not a PGM file (magic {magic!r}, expected P5 or P2)", path)
    # header: magic, width, height, maxval, separated by whitespace, '#' comments to line end
    tokens: list[bytes] = []
    i = 2
    while len(tokens) < 3:
        while i < len(data) and data[i:i + 1].isspace():
            i += 1
        if i < len(data) and data[i:i + 1] == b"#":
            while i < len(data) and data[i:i + 1] not in (b"\n", b"\r"):
                i += 1
            continue
        j = i
        while j < len(data) and not data[j:j + 1].isspace() and data[j:j + 1] != b"#":
            j += 1
        if j == i:
            raise DataError("PGM header ends early", path)
        tokens.append(data[i:j])
        i = j
    try:
        width, height, maxval = (int(t) for t in tokens)
    except ValueError:
        raise DataError(f"PGM header has non-integer fields {tokens}", path) from None
    if width <= 0 or height <= 0 or not 0 < maxval < 65536:
        raise DataError(f"PGM header: bad size {width}x{height} or maxval {maxval}", path)
    n = width * height
    if magic == b"P5":
        i += 1  # exactly one whitespace byte after maxval
        dtype = np.dtype(">u2") if maxval > 255 else np.dtype("u1")
        raw = data[i:i + n * dtype.itemsize]
        if len(raw) < n * dtype.itemsize:
            raise DataError(f"PGM pixel data truncated: {len(raw)} of {n * dtype.itemsize} bytes", path)
        pixels = np.frombuffer(raw, dtype=dtype).astype(float)
    else:
        try:
            pixels = np.array(data[i:].split(), dtype=float)
        except ValueError:
            raise DataError("P2 PGM pixel data has non-integer tokens", path) from None
        if len(pixels) < n:
            raise DataError(f"PGM pixel data truncated: {len(pixels)} of {n} values", path)
        pixels = pixels[:n]
    if np.any(pixels > maxval):
        raise DataError(f"PGM pixel value above maxval {maxval}", path)
    return pixels.reshape(height, width) * (255.0 / maxval)


def _unfilter(raw: bytes, width: int, height: int, bpp: int, path: Path) -> np.ndarray:
    """Undo PNG scanline filters (None, Sub, Up, Average, Paeth), row by row (rows depend on
    the row above; within a row Sub/Average/Paeth depend on the previous pixel)."""
    stride = width * bpp
    if len(raw) != height * (stride + 1):
        raise DataError(f"PNG image data has {len(raw)} bytes, expected {height * (stride + 1)}", path)
    rows = np.frombuffer(raw, dtype=np.uint8).reshape(height, stride + 1)
    out = np.zeros((height, stride), dtype=np.uint8)
    prev = np.zeros(stride, dtype=np.int32)
    for y in range(height):
        ftype = rows[y, 0]
        line = rows[y, 1:].astype(np.int32)
        if ftype == 0:
            cur = line
        elif ftype == 2:
            cur = (line + prev) & 0xFF
        elif ftype == 1:
            # Sub: a running sum of each channel along the row, modulo 256
            cur = (np.cumsum(line.reshape(width, bpp), axis=0) & 0xFF).reshape(-1)
        elif ftype in (3, 4):
            # Average and Paeth depend on the pixel just decoded: inherently sequential
            # (maps are small; encoders rarely choose these filters for flat map images)
            cur = np.zeros(stride, dtype=np.int32)
            for x in range(stride):  # sequential by definition of the filter
                a = cur[x - bpp] if x >= bpp else 0
                b = prev[x]
                if ftype == 3:
                    pred = (a + b) >> 1
                else:
                    c = prev[x - bpp] if x >= bpp else 0
                    p = a + b - c
                    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                    pred = a if (pa <= pb and pa <= pc) else (b if pb <= pc else c)
                cur[x] = (line[x] + pred) & 0xFF
        else:
            raise DataError(f"PNG row {y} has unknown filter type {ftype}", path)
        out[y] = cur
        prev = cur
    return out


def read_png(path: str | Path) -> np.ndarray:
    """(H, W) brightness 0..255 (float, mean of colour channels; alpha ignored) of an 8-bit,
    non-interlaced PNG (grey, grey+alpha, RGB, RGBA or palette)."""
    path = Path(path)
    data = path.read_bytes()
    if not data.startswith(_PNG_SIGNATURE):
        raise DataError("not a PNG file (bad signature)", path)
    pos = len(_PNG_SIGNATURE)
    header = None
    palette = None
    idat = []
    while pos + 8 <= len(data):
        length, ctype = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        crc = data[pos + 8 + length:pos + 12 + length]
        if len(body) < length or len(crc) < 4:
            raise DataError(f"PNG chunk {ctype!r} truncated", path)
        if zlib.crc32(ctype + body) != struct.unpack(">I", crc)[0]:
            raise DataError(f"PNG chunk {ctype!r} fails its CRC", path)
        if ctype == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif ctype == b"PLTE":
            palette = np.frombuffer(body, dtype=np.uint8).reshape(-1, 3)
        elif ctype == b"IDAT":
            idat.append(body)
        elif ctype == b"IEND":
            break
        pos += 12 + length
    if header is None or not idat:
        raise DataError("PNG file has no IHDR or no IDAT chunk", path)
    width, height, depth, color, _, _, interlace = header
    channels = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}.get(color)
    if depth != 8 or channels is None or interlace != 0:
        raise DataError(f"unsupported PNG (bit depth {depth}, colour type {color}, interlace "
                        f"{interlace}); slamkit reads 8-bit non-interlaced PNGs", path)
    try:
        raw = zlib.decompress(b"".join(idat))
    except zlib.error as exc:
        raise DataError(f"PNG image data does not decompress: {exc}", path) from None
    img = _unfilter(raw, width, height, channels, path).reshape(height, width, channels).astype(float)
    if color == 3:
        if palette is None:
            raise DataError("palette PNG without a PLTE chunk", path)
        idx = img[..., 0].astype(np.int64)
        if idx.max(initial=0) >= len(palette):
            raise DataError("palette index out of range", path)
        return palette[idx].astype(float).mean(axis=-1)
    colour = img[..., :3] if channels >= 3 else img[..., :1]
    return colour.mean(axis=-1)


def read_image(path: str | Path) -> np.ndarray:
    """Grey levels 0..255 of a PGM or PNG file, chosen by content (not extension)."""
    path = Path(path)
    try:
        head = path.open("rb").read(8)
    except FileNotFoundError:
        raise DataError("no such image file", path) from None
    if head.startswith(_PNG_SIGNATURE):
        return read_png(path)
    if head[:2] in (b"P5", b"P2"):
        return read_pgm(path)
    raise DataError("unsupported image format (slamkit reads PGM P2/P5 and PNG)", path)


@dataclass(frozen=True)
class ImageMap:
    """The grid (unknown cells counted as occupied or free as asked) and the unknown mask."""

    grid: OccupancyGrid
    unknown: np.ndarray


def occupancy_from_image(grey: np.ndarray, resolution_m: float, origin_xy_m=(0.0, 0.0),
                         negate: bool = False, occupied_thresh: float = 0.65,
                         free_thresh: float = 0.196, unknown_is_occupied: bool = True,
                         name: str = "map") -> ImageMap:
    """ROS map_server trinary interpretation of a grey image (rows top to bottom)."""
    g = np.asarray(grey, dtype=float)
    if g.ndim != 2:
        raise DataError(f"map image must be 2D grey levels, got shape {g.shape}")
    if not 0.0 <= free_thresh <= occupied_thresh <= 1.0:
        raise DataError(f"need 0 <= free_thresh <= occupied_thresh <= 1, got {free_thresh}, {occupied_thresh}")
    p = g / 255.0 if negate else (255.0 - g) / 255.0
    p = p[::-1]  # first image row is the top of the map
    occupied = p > occupied_thresh
    free = p < free_thresh
    unknown = ~occupied & ~free
    cells = occupied | unknown if unknown_is_occupied else occupied
    unknown.setflags(write=False)
    return ImageMap(OccupancyGrid(cells, resolution_m, np.asarray(origin_xy_m, float)[:2], name=name), unknown)


def grid_to_pgm_bytes(grid: OccupancyGrid, unknown: np.ndarray | None = None) -> bytes:
    """P5 PGM as map_server's map_saver writes it: occupied 0, free 254, unknown 205."""
    pixels = np.where(grid.occupied, 0, 254).astype(np.uint8)
    if unknown is not None:
        pixels[np.asarray(unknown, bool) & ~grid.occupied] = 205  # a known obstacle stays one
    pixels = pixels[::-1]
    return b"P5\n%d %d\n255\n" % (grid.width, grid.height) + pixels.tobytes()
