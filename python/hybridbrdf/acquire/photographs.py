"""A photograph's file decoded to linear radiance (docs/ACQUISITION.md, "Photographs from a camera"):
float32 OpenEXR or TIFF as they are, 8- and 16-bit PNG and TIFF through the capture's stated
encoding, with the pixels at the encoding's largest code marked saturated.

A capture index may state, for all its photographs::

    "photographs": {"encoding": "srgb", "scale": 2.5, "black_level": 0.002}

- ``encoding``: how an integer code c of n bits maps to a linear value v: ``linear`` (v = c / (2^n - 1))
  or ``srgb`` (IEC 61966-2-1's piecewise curve of c / (2^n - 1)); default ``linear``. Float images
  are linear whatever it says (``srgb`` on one is refused: nothing would decode it).
- ``black_level``: the linear value of no light, subtracted; default 0.
- ``scale``: radiance per unit of linear value (exposure time, gain, the camera's radiometric
  calibration); default 1. Radiance = scale (v - black_level).

A pixel with any colour channel at the largest code (255, 65535) is saturated: the sensor clipped
it and its radiance is unknown; a fit leaves it out as it leaves out a pixel that is not finite."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Tuple

import numpy as np
import png
import tifffile

from hybridbrdf.acquire.rig import PHOTO_EXTENSIONS
from hybridbrdf.render.tracer import read_image

#: Encodings a capture index may state.
ENCODINGS = ("linear", "srgb")
#: File name endings of the photographs read (the rig format's).
EXTENSIONS = PHOTO_EXTENSIONS


@dataclass(frozen=True)
class PhotoEncoding:
    """How a capture's integer photographs decode to radiance (module docstring)."""
    encoding: str = "linear"
    scale: float = 1.0
    black_level: float = 0.0


def encoding_of_index(index: dict, where: str, error) -> PhotoEncoding:
    """The ``photographs`` entry of a capture index (``where`` names it in ``error``'s one line)."""
    entry = index.get("photographs") if isinstance(index, dict) else None
    if entry is None:
        return PhotoEncoding()
    if not isinstance(entry, dict):
        raise error(where, f"photographs: expected an object, got {type(entry).__name__}")
    unknown = sorted(set(entry) - {"encoding", "scale", "black_level"})
    if unknown:
        raise error(where, f"photographs: unknown key {unknown[0]!r} (encoding, scale, black_level)")
    enc = entry.get("encoding", "linear")
    if enc not in ENCODINGS:
        raise error(where, f"photographs: encoding: unknown encoding {enc!r} (one of {', '.join(ENCODINGS)})")
    scale, black = entry.get("scale", 1.0), entry.get("black_level", 0.0)
    for key, v, ok in (("scale", scale, lambda x: x > 0), ("black_level", black, lambda x: 0 <= x < 1)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not ok(v):
            raise error(where, f"photographs: {key}: expected {'a number > 0' if key == 'scale' else 'a number in [0, 1)'}"
                               f", got {v!r}")
    return PhotoEncoding(enc, float(scale), float(black))


def srgb_to_linear(v: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1's decoding of values in [0, 1]."""
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def _png_codes(path: str, data: bytes, size: Tuple[int, int], error) -> np.ndarray:
    """(H, W, 3) integer codes of an 8- or 16-bit RGB(A) PNG; the header checked before decoding."""
    try:
        width, height, rows, info = png.Reader(bytes=data).read()
        if info.get("palette"):
            raise error(path, "a palette (indexed) PNG; a photograph needs RGB values (save it as RGB)")
        if info["greyscale"] or info["planes"] not in (3, 4):
            raise error(path, f"a PNG of {info['planes']} channel(s) (grey{' and alpha' if info['alpha'] else ''}); "
                              f"a photograph needs RGB (alpha is ignored)")
        if info["bitdepth"] not in (8, 16):
            raise error(path, f"a {info['bitdepth']}-bit PNG; photographs are 8- or 16-bit")
        _check_size(path, width, height, size, error)
        dtype = np.uint8 if info["bitdepth"] == 8 else np.uint16
        codes = np.vstack([np.asarray(r, dtype) for r in rows]).reshape(height, width, info["planes"])
    except png.Error as exc:
        raise error(path, f"cannot read the PNG: {str(exc).splitlines()[0]}") from None
    return codes[..., :3]


def _tiff_image(path: str, size: Tuple[int, int], error) -> np.ndarray:
    """(H, W, 3) of an 8/16-bit integer or 32-bit float RGB(A) TIFF (its first image)."""
    try:
        with tifffile.TiffFile(path) as tif:
            page = tif.pages[0]
            dtype, shape = np.dtype(page.dtype) if page.dtype is not None else None, page.shape
            if dtype is None or dtype.kind not in "uf" or (dtype.kind == "u" and dtype.itemsize > 2):
                raise error(path, f"a TIFF of {dtype} samples; photographs are 8- or 16-bit integers or 32-bit floats")
            if len(shape) != 3 or shape[2] not in (3, 4):
                raise error(path, f"a TIFF of shape {tuple(shape)}; a photograph needs RGB (height x width x 3, "
                                  f"alpha ignored)")
            _check_size(path, shape[1], shape[0], size, error)
            image = page.asarray()
    except (tifffile.TiffFileError, ValueError, OSError, IndexError, KeyError) as exc:
        raise error(path, f"cannot read the TIFF: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}") from None
    return image[..., :3]


def _check_size(path, width, height, size, error) -> None:
    w, h = size
    if (width, height) != (w, h):
        raise error(path, f"photograph is {width}x{height}; the rig says {w}x{h}")


def decode_photo(path: str, size: Tuple[int, int], encoding: PhotoEncoding, error) -> Tuple[np.ndarray, np.ndarray]:
    """(radiance (H, W, 3) float32, saturated (H, W) bool) of the photograph ``path`` of the rig's
    ``size`` (W, H); a file that cannot be used is ``error(path, problem)``."""
    ext = os.path.splitext(path)[1].lower()
    if ext not in EXTENSIONS:
        raise error(path, f"a photograph must be {', '.join(EXTENSIONS)}")
    if ext == ".exr":
        try:
            image = read_image(path)
        except (RuntimeError, ValueError, OSError) as exc:
            raise error(path, f"cannot read the photograph: {exc}") from None
        _check_size(path, image.shape[1], image.shape[0], size, error)
    elif ext == ".png":
        with open(path, "rb") as f:
            image = _png_codes(path, f.read(), size, error)
    else:
        image = _tiff_image(path, size, error)
    if image.dtype.kind == "f":
        if encoding.encoding != "linear":
            raise error(path, f"a float photograph is linear; the capture states encoding {encoding.encoding!r}, "
                              f"which is for 8- and 16-bit images")
        saturated = np.zeros(image.shape[:2], bool)
        value = image.astype(np.float64)
    else:
        top = np.iinfo(image.dtype).max
        saturated = (image == top).any(axis=2)
        value = image.astype(np.float64) / top
        if encoding.encoding == "srgb":
            value = srgb_to_linear(value)
    radiance = encoding.scale * (value - encoding.black_level)
    return radiance.astype(np.float32), saturated
