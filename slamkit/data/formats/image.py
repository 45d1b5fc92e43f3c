"""Map images (PNG, binary and ASCII PGM P5/P2, 8 or 16 bit) decoded with Pillow under a pixel limit.

This is a file format, so it lives in ``slamkit.data`` (ARCHITECTURE.md: algorithm packages such
as ``slamkit.maps`` never import a file format); the pixel -> occupancy rule stays in
:mod:`slamkit.maps.image_map` and the ROS YAML in :mod:`slamkit.sim.ros_map`, which calls
:func:`read_image`. Pillow is imported only here (``tests/test_layers.py``).

The header is read first (``Image.open`` is lazy) and an image declaring more than
:data:`MAX_IMAGE_PIXELS` pixels is a ``DataError`` before any pixel is decoded: an 875 KB PNG can
declare 30000 x 30000 pixels, which the hand-written decoder this replaces expanded to 18 GB.

Grey level of a pixel (0..255, float): the mean of its colour channels, alpha ignored (ROS
``map_server``); palette images through their palette; 16-bit images scaled by 255 / 65535
(Pillow scales a PGM with maxval M to 0..65535 for M > 255, and to 0..255 for M <= 255).
"""

from __future__ import annotations

import struct
import warnings
from pathlib import Path

import numpy as np

from slamkit.errors import DataError

#: largest width * height accepted (100 M pixels: a 10 km x 10 km map at 1 m, 800 MB as float64)
MAX_IMAGE_PIXELS = 100_000_000
#: the formats read (Pillow's PPM plugin reads PGM P2 and P5)
_FORMATS = ("PNG", "PPM")


def read_image(path: str | Path, max_pixels: int = MAX_IMAGE_PIXELS) -> np.ndarray:
    """(H, W) grey levels 0..255 (float) of a PNG or PGM file, chosen by content."""
    from PIL import Image, UnidentifiedImageError

    path = Path(path)
    try:
        with warnings.catch_warnings():
            # our own limit is checked below, before decoding; Pillow's own bomb check is off
            # for the same reason (it would raise at 2x its 89 M default, with its own text)
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            previous = Image.MAX_IMAGE_PIXELS
            Image.MAX_IMAGE_PIXELS = None
            try:
                image = Image.open(path, formats=_FORMATS)
            finally:
                Image.MAX_IMAGE_PIXELS = previous
    except FileNotFoundError:
        raise DataError("no such image file", path) from None
    except IsADirectoryError:
        raise DataError("is a directory, not an image file", path) from None
    except UnidentifiedImageError:
        raise DataError("unsupported image format (slamkit reads PGM P2/P5 and PNG)", path) from None
    except (OSError, ValueError, SyntaxError, struct.error) as exc:
        raise DataError(f"image header is malformed: {exc}", path) from None
    with image:
        width, height = image.size
        if width <= 0 or height <= 0:
            raise DataError(f"image declares {width} x {height} pixels", path)
        if width * height > max_pixels:
            raise DataError(f"image declares {width} x {height} = {width * height} pixels, more than "
                            f"the limit of {max_pixels}", path)
        try:
            image.load()
            grey = _grey(image)
        except (OSError, ValueError, SyntaxError, EOFError, struct.error, IndexError) as exc:
            raise DataError(f"{image.format} image data is truncated or corrupt: {exc}", path) from None
    return grey


#: file suffixes :func:`list_images` picks up
IMAGE_SUFFIXES = (".png", ".pgm")


def list_images(folder: str | Path) -> list[Path]:
    """The image files of a folder (PNG or PGM), in name order (KITTI's 000000.png ...)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise DataError("no such image folder", folder)
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file())
    if not files:
        raise DataError(f"no {' or '.join(IMAGE_SUFFIXES)} files in the image folder", folder)
    return files


def _grey(image) -> np.ndarray:
    mode = image.mode
    if mode in ("P", "PA"):
        image = image.convert("RGBA")
        mode = "RGBA"
    if mode == "1":
        return np.asarray(image, dtype=float) * 255.0
    a = np.asarray(image)
    if mode in ("I", "I;16", "I;16B", "I;16L"):
        return a.astype(float) * (255.0 / 65535.0)
    if mode in ("L", "LA", "RGB", "RGBA"):
        a = a.astype(float)
        if a.ndim == 2:
            return a
        return a[..., :3].mean(axis=-1) if a.shape[-1] >= 3 else a[..., 0]
    raise ValueError(f"pixel mode {mode!r} is not supported")
