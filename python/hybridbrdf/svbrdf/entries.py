"""The map entries of a textured material's index (docs/SVBRDF.md, "The folder"): each names a
file of stored values, the quantity, layer and components it holds, and each channel's decode;
a mip chain's levels are more files ("mips", PNG and EXR) or inside the one file (KTX2). Reading
checks every entry and file against the index before and while decoding; writing encodes
decoded values with the spec's decode.

Map files: 3-channel 8-bit PNG or float32 EXR (``hybridbrdf.svbrdf.maps``), or KTX2
(``hybridbrdf.svbrdf.ktx2``: BC4/BC5/BC7 blocks, 8-bit or half-float RGBA) holding the whole
chain. A KTX2 map stores the first ``channels`` of the map's three (a channel it lacks reads 0,
as a GPU sampler returns it); an sRGB format is decoded by the GPU's sampler before filtering, so
every channel it holds must have the ``srgb`` transfer.
"""

from __future__ import annotations

import os
from typing import Dict, List, Optional

import numpy as np

from hybridbrdf import spec
from hybridbrdf.errors import InputFileError
from hybridbrdf.inputs import check_input_file
from hybridbrdf.svbrdf.decode import QUANTITIES, channel_problem, decode, encode, float_channel, png_channel
from hybridbrdf.svbrdf.ktx2 import read_ktx2, vk_format, write_ktx2
from hybridbrdf.svbrdf.maps import map_bits, read_map, write_map
from hybridbrdf.svbrdf.mips import level_size

SV = spec.SVBRDF
CHANNELS = SV["map_channels"]
MAP_KEYS = {"file", "quantity", "layer", "first", "mips", "decode"}
LAYER_QUANTITIES = ("kd", "eta", "alpha", "latent")
FORMATS = ("png", "exr", "ktx2")
#: The block format a map of `used` channels is written in as KTX2 (kd: the sRGB BC7, decoded by
#: the sampler; one and two channels: BC4 and BC5, which keep each channel's 8-bit precision and
#: store no other channel: a weights map's unused channels must read exactly 0, which a BC7 block
#: of two used channels does not promise; measured: BC7 on the three-layer weights of
#: bench/svbrdf_compression.py has the lower p99 error, 2 steps against BC5's 9, but a nonzero B).
KTX2_FORMATS = {1: "BC4_UNORM_BLOCK", 2: "BC5_UNORM_BLOCK", 3: "BC7_UNORM_BLOCK"}
#: The sRGB block formats a kd map (the one map of the srgb transfer) may be written in, by name
#: (``SVBRDF.save(kd_format=)``, ``hbrdf paint --kd-format``). BC1, half a byte a texel, is the
#: default: within the compression bound of the whole material against its measurements, and the
#: sampler's decode of BC1 is cheap where BC7's is not (lavapipe decodes BC7 in software at every
#: tap: 3.9x the shader's time; docs/SVBRDF.md, "KTX2 maps"). BC7 keeps a third of BC1's error.
KTX2_KD_FORMATS = {"bc1": "BC1_RGB_SRGB_BLOCK", "bc7": "BC7_SRGB_BLOCK"}
KTX2_KD_DEFAULT = "bc1"


class SVBRDFError(InputFileError):
    """A textured-material folder, index or map that cannot be used (one line naming the file)."""


def components(quantity: str, latent: int) -> int:
    c = QUANTITIES[quantity]["components"]
    return latent if c == "latent" else c


def plain_name(index_path: str, name, what: str) -> str:
    """A file name inside the folder: no separators, not '.' or '..', not hidden."""
    if not isinstance(name, str) or not name or os.path.basename(name) != name or name in (".", "..") \
            or name.startswith(".") or "\\" in name or "\0" in name:
        raise SVBRDFError(index_path, f"{what} must be a plain file name inside the folder, got {name!r}")
    return name


# ---- writing -------------------------------------------------------------------------------
def map_name(quantity: str, layer: Optional[int], first: int, format: str, level: int = 0) -> str:
    stem = quantity if layer is None else f"layer{layer}_{quantity}" + (str(first // 3) if quantity == "latent" else "")
    return f"{stem}{f'.mip{level}' if level else ''}.{format}"


def write_quantity(folder, quantity, layer, chain, format, n_layers=None, kd_format=KTX2_KD_DEFAULT) -> List[Dict]:
    """Encode a quantity's decoded values, (H, W, c) per mip level (level 0 first), into map files
    of 3 channels each (level 0's decode for every level: a coarser level's values are means of
    the finer ones, within their range); their index entries. ``format``: 'png' and 'exr' write a
    file per level, 'ktx2' one file of the whole chain (:data:`KTX2_FORMATS`; three sRGB channels,
    kd's, in :data:`KTX2_KD_FORMATS` ``[kd_format]``)."""
    if kd_format not in KTX2_KD_FORMATS:
        raise ValueError(f"kd_format must be one of {', '.join(KTX2_KD_FORMATS)}, got {kd_format!r}")
    eight_bit = format in ("png", "ktx2")
    entries = []
    for first in range(0, chain[0].shape[2], CHANNELS):
        c = min(CHANNELS, chain[0].shape[2] - first)
        decodes = []
        held = [ch < c and not (quantity == "weights" and ch >= n_layers - 1) for ch in range(CHANNELS)]
        for ch in range(CHANNELS):
            if not held[ch]:
                decodes.append(None if quantity != "weights" else (png_channel("weights") if eight_bit else float_channel()))
                continue
            x = chain[0][..., first + ch].astype(np.float64)
            decodes.append(png_channel(quantity, x.min(), x.max()) if eight_bit else float_channel())
        levels = []
        for values in chain:
            stored = np.zeros(values.shape[:2] + (CHANNELS,), dtype=np.uint8 if eight_bit else np.float32)
            for ch in range(c):
                if held[ch]:
                    stored[..., ch] = encode(values[..., first + ch].astype(np.float64), decodes[ch], bits=8 if eight_bit else 0)
            levels.append(stored)
        entry = {"file": map_name(quantity, layer, first, format), "quantity": quantity,
                 **({} if layer is None else {"layer": layer}), "first": first}
        if format == "ktx2":
            n = sum(held)
            srgb = all(d["transfer"] == "srgb" for d, h in zip(decodes, held) if h)
            write_ktx2(os.path.join(folder, entry["file"]), [lv[..., :n] for lv in levels],
                       vk_format(KTX2_KD_FORMATS[kd_format] if srgb and n == 3 else KTX2_FORMATS[n]))
        else:
            names = [map_name(quantity, layer, first, format, level) for level in range(len(chain))]
            for name, stored in zip(names, levels):
                write_map(os.path.join(folder, name), stored)
            if len(names) > 1:
                entry["mips"] = names[1:]
        entries.append({**entry, "decode": decodes})
    return entries


# ---- reading -------------------------------------------------------------------------------
def read_entry(folder, index_path, entry, n_layers, latent, size, levels):
    """(quantity, layer, first, [path per level], [decoded values (H, W, components in this map)
    per level]) of one map entry."""
    if not isinstance(entry, dict) or not {"file", "quantity", "first", "decode"} <= set(entry) <= MAP_KEYS:
        raise SVBRDFError(index_path, "each map must be {\"file\", \"quantity\", [\"layer\"], \"first\", [\"mips\"], \"decode\"}")
    quantity = entry["quantity"]
    if quantity not in QUANTITIES:
        raise SVBRDFError(index_path, f"unknown map quantity {quantity!r} (expected one of {', '.join(QUANTITIES)})")
    per_layer = QUANTITIES[quantity]["per_layer"]
    layer = entry.get("layer")
    if per_layer != ("layer" in entry):
        raise SVBRDFError(index_path, f"a {quantity} map {'needs' if per_layer else 'has no'} \"layer\"")
    if per_layer and not (isinstance(layer, int) and not isinstance(layer, bool) and 0 <= layer < n_layers):
        raise SVBRDFError(index_path, f"{quantity} map: layer must be 0 to {n_layers - 1}, got {layer!r}")
    c = 3 if quantity == "weights" else components(quantity, latent)
    first = entry["first"]
    if not (isinstance(first, int) and not isinstance(first, bool) and 0 <= first < c and first % CHANNELS == 0):
        raise SVBRDFError(index_path, f"{quantity} map: first must be a multiple of {CHANNELS} below {c}, got {first!r}")
    path = os.path.join(folder, plain_name(index_path, entry["file"], "a map's file"))
    name = os.path.basename(path)
    ext = os.path.splitext(path)[1].lower()
    if ext not in (".png", ".exr", ".ktx2"):
        raise SVBRDFError(path, f"texel maps are .png (8-bit), .exr (float32) or .ktx2, not '{ext or 'no extension'}'")
    ktx2 = ext == ".ktx2"
    mips = entry.get("mips", [])
    if ktx2 and "mips" in entry:
        raise SVBRDFError(index_path, f"{name}: a KTX2 map holds its own mip levels; \"mips\" lists PNG and EXR levels")
    if not ktx2 and ((levels > 1) != ("mips" in entry) or not (isinstance(mips, list) and len(mips) == levels - 1)):
        raise SVBRDFError(index_path, f"{name}: a material of {levels} levels lists {levels - 1} mip files per map "
                                      "(\"mips\")" if levels > 1 else f"{name}: \"mips\" needs \"levels\" above 1 in the index")
    texture = _read_ktx2_map(path, size, levels) if ktx2 else None
    floating = texture.levels[0].dtype != np.uint8 if ktx2 else not map_bits(path)
    decodes = entry["decode"]
    used = min(CHANNELS, c - first)
    if not (isinstance(decodes, list) and len(decodes) == CHANNELS):
        raise SVBRDFError(index_path, f"{entry['file']}: decode must list {CHANNELS} channels")
    for ch, d in enumerate(decodes):
        if ch >= used:
            if d is not None and quantity != "weights":
                raise SVBRDFError(index_path, f"{entry['file']}: channel {'RGB'[ch]} holds no {quantity} component; its decode must be null")
            continue
        problem = channel_problem(quantity, d, floating=floating)
        if problem:
            raise SVBRDFError(index_path, f"{entry['file']} channel {'RGB'[ch]}: {problem}")
    if ktx2:
        return quantity, layer, first, [path] * levels, _ktx2_levels(texture, path, index_path, quantity, decodes, used, n_layers)
    paths = [path] + [os.path.join(folder, plain_name(index_path, m, "a mip file")) for m in mips]
    out = []
    for level, file in enumerate(paths):
        if map_bits(file) != map_bits(path):
            raise SVBRDFError(index_path, f"{os.path.basename(file)}: a mip level is stored as level 0 is "
                                          f"({os.path.splitext(path)[1]})")
        check_input_file(file, "texel map", None, SVBRDFError)
        stored, _ = read_map(file)
        if (stored.shape[1], stored.shape[0]) != level_size(size, level):
            w, h = level_size(size, level)
            raise SVBRDFError(file, f"map is {stored.shape[1]}x{stored.shape[0]}; the index says {w}x{h}")
        out.append(_decoded(file, stored, quantity, decodes, used))
    return quantity, layer, first, paths, out


def _read_ktx2_map(path, size, levels):
    """A KTX2 map's texture, its size and level count checked against the index."""
    check_input_file(path, "texel map", None, SVBRDFError)
    texture = read_ktx2(path)  # bounded: every size checked against the file before any allocation
    if (texture.width, texture.height) != tuple(size):
        raise SVBRDFError(path, f"map is {texture.width}x{texture.height}; the index says {size[0]}x{size[1]}")
    if len(texture.levels) != levels:
        raise SVBRDFError(path, f"holds {len(texture.levels)} mip level(s); the index says {levels}")
    return texture


def _ktx2_levels(texture, path, index_path, quantity, decodes, used, n_layers) -> List[np.ndarray]:
    """Decoded values per level of a KTX2 map: its format holds the channels the map uses (a
    weights map those of its layers), and an sRGB format only channels of the srgb transfer."""
    needed = n_layers - 1 if quantity == "weights" else used
    if texture.channels < needed:
        raise SVBRDFError(path, f"{texture.name} holds {texture.channels} channel(s); this {quantity} map needs {needed}")
    if texture.srgb:
        for ch in range(min(used, texture.channels)):
            if decodes[ch] is not None and decodes[ch]["transfer"] != "srgb":
                raise SVBRDFError(index_path, f"{os.path.basename(path)} channel {'RGB'[ch]}: {texture.name} is sRGB-encoded "
                                              f"(a sampler decodes it), so its transfer must be srgb, not {decodes[ch]['transfer']}")
    out = []
    for level in texture.levels:
        k = min(texture.channels, CHANNELS)
        stored = np.zeros(level.shape[:2] + (CHANNELS,))
        stored[..., :k] = level[..., :k] / 255.0 if level.dtype == np.uint8 else level[..., :k]
        out.append(_decoded(path, stored, quantity, decodes, used))
    return out


def _decoded(path, stored: np.ndarray, quantity, decodes, used) -> np.ndarray:
    """Stored values (H, W, 3) decoded (H, W, components; weights padded to 3), each checked
    against the quantity's range (the texel and channel named)."""
    values = np.stack([decode(stored[..., ch], decodes[ch]) for ch in range(used)], axis=2)
    q = QUANTITIES[quantity]
    bad = ~((values >= q["min"]) & (values <= q["max"]))
    if bad.any():
        y, x, ch = np.argwhere(bad)[0]
        raise SVBRDFError(path, f"texel ({x}, {y}) channel {'RGB'[ch]} decodes to {values[y, x, ch]:g}, outside "
                                f"{quantity}'s range [{q['min']:g}, {q['max']:g}]")
    if quantity == "weights":
        values = np.concatenate([values, np.zeros(values.shape[:2] + (3 - used,))], axis=2) if used < 3 else values
    return values.astype(np.float32)
