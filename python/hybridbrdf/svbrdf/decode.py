"""How a texel map's stored values become material values (spec/model.json, ``svbrdf``): a channel
holding v (a PNG's byte / 255, an EXR's float) decodes to ``offset + scale * T(v)``, T the
channel's transfer. Encoding is the inverse, rounded to the nearest byte for 8-bit maps.

The transfers are the spec's: ``linear``, ``srgb`` (the sRGB EOTF, IEC 61966-2-1) and ``square``
(a roughness map stores r = sqrt(alpha), Burley 2012).
"""

from __future__ import annotations

from typing import Dict

import numpy as np

from hybridbrdf import spec

SV = spec.SVBRDF
TRANSFERS = tuple(SV["transfers"])
QUANTITIES = SV["quantities"]


def transfer(name: str, v: np.ndarray) -> np.ndarray:
    """T(v) of the spec's transfer ``name`` (float64)."""
    v = np.asarray(v, dtype=np.float64)
    if name == "linear":
        return v
    if name == "srgb":
        return np.where(v <= 0.04045, v / 12.92, ((np.maximum(v, 0.04045) + 0.055) / 1.055) ** 2.4)
    if name == "square":
        return v * v
    raise ValueError(f"unknown transfer '{name}' (expected one of {', '.join(TRANSFERS)})")


def inverse_transfer(name: str, t: np.ndarray) -> np.ndarray:
    """v with T(v) = t, for t in T's range over [0, 1] (float64)."""
    t = np.asarray(t, dtype=np.float64)
    if name == "linear":
        return t
    if name == "srgb":
        t = np.clip(t, 0.0, 1.0)
        return np.where(t <= 0.0031308, 12.92 * t, 1.055 * np.power(np.maximum(t, 0.0031308), 1 / 2.4) - 0.055)
    if name == "square":
        return np.sqrt(np.clip(t, 0.0, None))
    raise ValueError(f"unknown transfer '{name}' (expected one of {', '.join(TRANSFERS)})")


def decode(v: np.ndarray, channel: Dict) -> np.ndarray:
    """offset + scale T(v) of one channel's stored values (float64)."""
    return channel["offset"] + channel["scale"] * transfer(channel["transfer"], v)


def encode(x: np.ndarray, channel: Dict, bits: int = 0) -> np.ndarray:
    """Stored values of material values ``x`` for ``channel``: floats (``bits`` 0) or integers of
    ``bits`` bits (rounded to the nearest step, clipped to [0, 2^bits - 1])."""
    scale = channel["scale"]
    t = (np.asarray(x, dtype=np.float64) - channel["offset"]) / (scale if scale != 0 else 1.0)
    v = inverse_transfer(channel["transfer"], t)
    if not bits:
        return v
    top = (1 << bits) - 1
    return np.clip(np.rint(np.clip(v, 0.0, 1.0) * top), 0, top).astype(np.uint16 if bits > 8 else np.uint8)


def png_channel(quantity: str, lo: float = None, hi: float = None) -> Dict:
    """The 8-bit decode of one channel of ``quantity``: the spec's, or for the latent code (whose
    range is the painted values') a linear map of [lo, hi] onto [0, 1]."""
    d = dict(QUANTITIES[quantity]["png"])
    if d["scale"] is None:
        lo, hi = float(lo), float(hi)
        d.update(scale=(hi - lo) if hi > lo else 1.0, offset=lo)
    return d


def float_channel() -> Dict:
    """The decode of a float (EXR) channel: the value itself."""
    return {"transfer": "linear", "scale": 1.0, "offset": 0.0}


def channel_problem(quantity: str, channel: Dict, floating: bool) -> str:
    """Why a channel's decode is not allowed for ``quantity`` ('' when it is): an unknown transfer,
    non-finite scale or offset, or (8-bit maps) a decoded range outside the quantity's."""
    if not isinstance(channel, dict) or set(channel) != {"transfer", "scale", "offset"}:
        return "a channel's decode must be {\"transfer\", \"scale\", \"offset\"}"
    if channel["transfer"] not in TRANSFERS:
        return f"unknown transfer '{channel['transfer']}' (expected one of {', '.join(TRANSFERS)})"
    for key in ("scale", "offset"):
        value = channel[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
            return f"decode {key} must be a finite number, got {value!r}"
    if floating:
        return ""
    q = QUANTITIES[quantity]
    ends = decode(np.array([0.0, 1.0]), channel)
    lo, hi = float(ends.min()), float(ends.max())
    slack = 1e-6 * max(1.0, abs(q["min"]), abs(q["max"]))
    if lo < q["min"] - slack or hi > q["max"] + slack:
        return (f"decodes to [{lo:g}, {hi:g}], outside {quantity}'s range [{q['min']:g}, {q['max']:g}]")
    return ""
