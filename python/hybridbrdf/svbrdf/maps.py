"""Texel map files of a textured material: 3-channel 8-bit PNG or float32 OpenEXR
(spec/model.json, ``svbrdf``: ``map_channels``, ``max_side``).

A map is read as stored values in (H, W, 3) float64 (a PNG's bytes / 255, an EXR's floats), its
size bounded before any pixel is decoded; writing is atomic (:func:`hybridbrdf.files.atomic_write_bytes`).
"""

from __future__ import annotations

import io
import os
import warnings
from typing import Tuple

import numpy as np
from PIL import Image

from hybridbrdf import _core, spec
from hybridbrdf.errors import InputFileError
from hybridbrdf.inputs import check_input_file
from hybridbrdf.files import atomic_write_bytes

SV = spec.SVBRDF
MAX_SIDE = SV["max_side"]
CHANNELS = SV["map_channels"]
#: Largest map file accepted: an uncompressed float32 RGB image of MAX_SIDE^2 texels and headers.
MAX_MAP_BYTES = MAX_SIDE * MAX_SIDE * CHANNELS * 4 + (1 << 20)
FORMATS = {".png": 8, ".exr": 0}  # extension -> bits per stored value (0: float)


def map_bits(path) -> int:
    """8 for a PNG map, 0 (float) for an EXR one; InputFileError for another extension."""
    ext = os.path.splitext(os.fspath(path))[1].lower()
    if ext not in FORMATS:
        raise InputFileError(path, f"texel maps are .png (8-bit) or .exr (float32), not '{ext or 'no extension'}'")
    return FORMATS[ext]


def _check_size(path, width: int, height: int) -> None:
    if not (0 < width <= MAX_SIDE and 0 < height <= MAX_SIDE):
        raise InputFileError(path, f"map is {width}x{height}; each side must be 1 to {MAX_SIDE} texels")


def read_map(path) -> Tuple[np.ndarray, int]:
    """(stored values (H, W, 3) float64, bits): 8-bit RGB PNG values / 255, or EXR floats (every
    one finite). One-line InputFileError naming the file otherwise."""
    path = os.fspath(path)
    bits = map_bits(path)
    check_input_file(path, "texel map", MAX_MAP_BYTES)
    if bits:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error", Image.DecompressionBombWarning)
                with Image.open(path) as img:
                    if img.format != "PNG":
                        raise InputFileError(path, f"is not a PNG file (Pillow reads it as {img.format})")
                    _check_size(path, *img.size)  # from the header, before any pixel is decoded
                    if img.mode != "RGB":
                        raise InputFileError(path, f"texel maps are 8-bit RGB PNG; this one has "
                                                   f"{len(img.getbands())} channel(s) (mode '{img.mode}')")
                    values = np.asarray(img.convert("RGB"), dtype=np.float64) / 255.0
        except InputFileError:
            raise
        except (OSError, ValueError, SyntaxError, Image.DecompressionBombWarning) as exc:
            raise InputFileError(path, f"cannot read the PNG map: {exc}") from None
        return values, 8
    try:
        values = np.asarray(_core.render_read_image(path), dtype=np.float64)
    except Exception as exc:  # the C++ reader's FileError, one line naming the file
        raise InputFileError(path, str(exc).split(": ", 1)[-1] if str(exc).startswith(path) else str(exc)) from None
    _check_size(path, values.shape[1], values.shape[0])
    bad = ~np.isfinite(values)
    if bad.any():
        y, x, c = np.argwhere(bad)[0]
        raise InputFileError(path, f"texel ({x}, {y}) channel {'RGB'[c]} is {values[y, x, c]} (maps must be finite)")
    return values, 0


def write_map(path, values: np.ndarray) -> None:
    """Write stored values (H, W, 3): uint8 to a PNG, floats to an EXR (by ``path``'s extension)."""
    path = os.fspath(path)
    values = np.asarray(values)
    if values.ndim != 3 or values.shape[2] != CHANNELS:
        raise ValueError(f"a map has shape (H, W, {CHANNELS}), got {values.shape}")
    _check_size(path, values.shape[1], values.shape[0])
    if map_bits(path):
        if values.dtype != np.uint8:
            raise ValueError(f"an 8-bit map needs uint8 values, got {values.dtype}")
        buf = io.BytesIO()
        Image.fromarray(values, "RGB").save(buf, format="PNG", optimize=False)
        atomic_write_bytes(path, buf.getvalue())
        return
    values = np.asarray(values, dtype=np.float32)
    if not np.isfinite(values).all():
        raise ValueError(f"{path}: refusing to write non-finite map values")
    _core.render_write_exr(values, path)
