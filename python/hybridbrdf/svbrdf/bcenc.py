"""Block-compression (BC1, BC4, BC5, BC7) encoders for texel maps, from PyPI's wheels
(docs/TEXTURES.md says which was measured best per format, and why).

Public names:

- :data:`ENCODERS`: ``{format: {encoder name: encode(rgba) -> bytes}}``, the candidates that are
  installed (one that is not raises ImportError naming its package when asked for by name);
  ``rgba`` uint8 (H, W, 4), H and W any size (edge blocks padded by the encoder). Formats are
  ``"bc1"``, ``"bc4"`` (the red channel), ``"bc5"`` (red and green), ``"bc7"``.
- :data:`DEFAULT_ENCODER`: the encoder :func:`encode_blocks` uses per format.
- :func:`encode_blocks` ``(texels, fmt, encoder=None) -> bytes``: the level's blocks, rows of blocks
  from the top, as KTX2 and the GPU lay them out.
- :func:`decode_blocks` ``(data, fmt, width, height) -> uint8 (H, W, C)``: libhybridbrdf's decoders
  (``hybridbrdf._core.bc_decode_level``), C = 3, 1, 2, 4 for BC1, BC4, BC5, BC7.
- :func:`encode_decode` ``(texels, fmt, encoder=None) -> uint8``: ``texels`` uint8 (H, W, C)
  or (H, W) through the format and back, the shape it came in: what a map stored as ``fmt`` reads.

``hybridbrdf`` is libhybridbrdf's own BC4/BC5 encoder (``_core.bc_encode_level``; docs/TEXTURES.md,
"Encoders"): it searches palettes whose levels extend past the block's range, so a steep ramp's
values fall on them, and keeps stored 0 and 255 exact (a weight of 0 or 1 stays so). Encoders
from PyPI are imported when first used: ``etcpak`` (BC1/BC4/BC5; BC7 through its bundled
bc7enc), ``quicktex`` (BC1/BC4/BC5) and ``bc7enc`` (the ``bc7enc-py`` wheel: rgbcx BC1/BC5 and
bc7enc_rdo's BC7). BC7 is encoded with linear (not perceptual) channel weights: the maps hold data
(weights, roughness, latents), and every channel's error counts the same.
"""

from __future__ import annotations

import ctypes
import importlib
import importlib.util

import numpy as np

from hybridbrdf import _core

BLOCK_FORMATS = ("bc1", "bc4", "bc5", "bc7")
CHANNELS = {"bc1": 3, "bc4": 1, "bc5": 2, "bc7": 4}
BLOCK_BYTES = {"bc1": 8, "bc4": 8, "bc5": 16, "bc7": 16}
BC7_UBER_LEVEL = 2  # bc7enc's search effort, 0..4: 2 gains 0.3-1.0 dB over 0 for 1.4-2.5x its time
RGBCX_LEVEL = 10    # rgbcx's BC1 effort, 0..18: 10 is 0.2-1.3 dB under 18 at 1/7 of its time
# (both measured by bench/bc_encoders.py's maps; docs/TEXTURES.md)


def _module(name: str):
    try:
        return importlib.import_module(name)
    except ImportError as err:  # pragma: no cover - the package is a dependency
        raise ImportError(f"the block-compression encoder needs the Python package {name!r}: "
                          f"pip install {name.replace('bc7enc', 'bc7enc-py')} ({err})") from None


def _rgba_bytes(rgba: np.ndarray) -> tuple:
    rgba = np.ascontiguousarray(rgba, dtype=np.uint8)
    return rgba.tobytes(), rgba.shape[1], rgba.shape[0]


def _etcpak(fmt: str):
    def encode(rgba):
        etcpak = _module("etcpak")
        data, w, h = _rgba_bytes(_pad4(rgba))
        if fmt == "bc7":
            params = etcpak.BC7CompressBlockParams()
            params.init_linear_weights()
            params.m_uber_level = BC7_UBER_LEVEL
            return etcpak.compress_bc7(data, w, h, params)
        return getattr(etcpak, "compress_" + fmt)(data, w, h)
    return encode


def _quicktex(fmt: str):
    def encode(rgba):
        qt = _module("quicktex")
        data, w, h = _rgba_bytes(rgba)
        texture = qt.RawTexture.frombytes(data, w, h)
        if fmt == "bc1":
            encoder = _module("quicktex.s3tc.bc1").BC1Encoder(RGBCX_LEVEL)
        elif fmt == "bc4":
            encoder = _module("quicktex.s3tc.bc4").BC4Encoder(0)
        else:
            encoder = _module("quicktex.s3tc.bc5").BC5Encoder(0, 1)
        return encoder.encode(texture).tobytes()
    return encode


def _bc7enc(fmt: str):
    def encode(rgba):
        bc7enc = _module("bc7enc")
        rgba = np.ascontiguousarray(rgba, dtype=np.uint8)
        h, w = rgba.shape[:2]
        size = ((w + 3) // 4) * ((h + 3) // 4)
        source = ctypes.create_string_buffer(rgba.tobytes(), rgba.nbytes)
        if fmt == "bc4":  # BC3's alpha block is a BC4 block: encode the red channel as alpha
            rgba3 = rgba.copy()
            rgba3[..., 3] = rgba[..., 0]
            source = ctypes.create_string_buffer(rgba3.tobytes(), rgba3.nbytes)
        out = ctypes.create_string_buffer(size * (8 if fmt == "bc1" else 16))
        if fmt == "bc1":
            bc7enc.bc7.compress_image_bc1(source, w, h, out, RGBCX_LEVEL, False, False)
        elif fmt == "bc4":
            bc7enc.bc7.compress_image_bc3(source, w, h, out, RGBCX_LEVEL)
            return b"".join(out.raw[16 * i:16 * i + 8] for i in range(size))
        elif fmt == "bc5":
            bc7enc.bc7.compress_image_bc5(source, w, h, out, 0, 1)
        else:
            params = bc7enc.bc7enc_compress_block_params_init()
            params.m_perceptual = False
            params.m_weights = (ctypes.c_uint * 4)(1, 1, 1, 1)
            params.m_uber_level = BC7_UBER_LEVEL
            bc7enc.bc7.compress_image(source, w, h, out, ctypes.byref(params))
        return out.raw
    return encode


def _own(fmt: str):
    def encode(rgba):
        return _core.bc_encode_level(fmt, np.ascontiguousarray(rgba, dtype=np.uint8))
    return encode


def _pad4(rgba: np.ndarray) -> np.ndarray:
    """etcpak reads whole blocks: a level whose sides are not multiples of 4 is extended by its
    edge texels (what the GPU never samples, and what keeps the edge block's endpoints tight)."""
    h, w = rgba.shape[:2]
    ph, pw = (-h) % 4, (-w) % 4
    return np.pad(rgba, ((0, ph), (0, pw), (0, 0)), mode="edge") if ph or pw else rgba


def _installed(name: str) -> bool:
    return name == "hybridbrdf" or importlib.util.find_spec(name) is not None


_CANDIDATES = {
    "bc1": {"etcpak": _etcpak("bc1"), "quicktex": _quicktex("bc1"), "bc7enc": _bc7enc("bc1")},
    "bc4": {"etcpak": _etcpak("bc4"), "quicktex": _quicktex("bc4"), "bc7enc": _bc7enc("bc4"), "hybridbrdf": _own("bc4")},
    "bc5": {"etcpak": _etcpak("bc5"), "quicktex": _quicktex("bc5"), "bc7enc": _bc7enc("bc5"), "hybridbrdf": _own("bc5")},
    "bc7": {"etcpak": _etcpak("bc7"), "bc7enc": _bc7enc("bc7")},
}
#: The installed candidates (etcpak and quicktex are dependencies; bc7enc-py is the test extra's).
ENCODERS = {fmt: {name: enc for name, enc in c.items() if _installed(name)} for fmt, c in _CANDIDATES.items()}
#: Chosen by bench/bc_encoders.py (docs/TEXTURES.md): rgbcx's BC1 (quicktex; etcpak's is 5-10 dB
#: worse), libhybridbrdf's BC4/BC5 (the PyPI encoders' min/max endpoints miss steep ramps: a
#: weights map's mask edges), bc7enc's BC7 through etcpak (the same blocks as bc7enc-py's, in half the time).
DEFAULT_ENCODER = {"bc1": "quicktex", "bc4": "hybridbrdf", "bc5": "hybridbrdf", "bc7": "etcpak"}


def _as_rgba(texels: np.ndarray, fmt: str) -> np.ndarray:
    """(H, W, C) uint8 with C <= the format's channels, as (H, W, 4): missing colour channels 0,
    a missing alpha 255."""
    if texels.dtype != np.uint8 or texels.ndim != 3 or not 1 <= texels.shape[2] <= CHANNELS[fmt]:
        raise ValueError(f"{fmt}: texels must be uint8 (H, W, C) with 1 <= C <= {CHANNELS[fmt]}, "
                         f"got {texels.dtype} {texels.shape}")
    h, w, c = texels.shape
    rgba = np.zeros((h, w, 4), np.uint8)
    rgba[..., 3] = 255
    rgba[..., :c] = texels
    return rgba


def encode_blocks(texels: np.ndarray, fmt: str, encoder: str = None) -> bytes:
    """The blocks of one level: ``texels`` uint8 (H, W, C), C at most the format's channels."""
    if fmt not in ENCODERS:
        raise ValueError(f"unknown block format {fmt!r} (known: {', '.join(BLOCK_FORMATS)})")
    name = encoder or DEFAULT_ENCODER[fmt]
    if name not in _CANDIDATES[fmt]:
        raise ValueError(f"{fmt}: unknown encoder {name!r} (known: {', '.join(_CANDIDATES[fmt])})")
    h, w = texels.shape[:2]
    data = _CANDIDATES[fmt][name](_as_rgba(texels, fmt))
    expected = ((w + 3) // 4) * ((h + 3) // 4) * BLOCK_BYTES[fmt]
    if len(data) != expected:  # an encoder's contract, checked: never a short level in a file
        raise RuntimeError(f"{fmt} encoder {name} returned {len(data)} bytes for {w} x {h}, expected {expected}")
    return data


def decode_blocks(data: bytes, fmt: str, width: int, height: int) -> np.ndarray:
    """uint8 (height, width, C) from a level's blocks, by libhybridbrdf's decoders."""
    return _core.bc_decode_level(fmt, data, int(width), int(height))


def encode_decode(texels: np.ndarray, fmt: str, encoder: str = None) -> np.ndarray:
    """``texels`` (uint8 (H, W, C) or (H, W)) as they read back from ``fmt``: same shape, uint8."""
    texels = np.asarray(texels)
    flat = texels.ndim == 2
    t3 = texels[..., None] if flat else texels
    out = decode_blocks(encode_blocks(t3, fmt, encoder), fmt, t3.shape[1], t3.shape[0])[..., :t3.shape[2]]
    return out[..., 0] if flat else out
