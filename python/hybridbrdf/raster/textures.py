"""A textured material's maps as the files ``hbrdf_raster --texture`` uploads (cpp/tools/raster/
textures.hpp), per map in the generated lookup's parameter order (``codegen/textured.py``), each
with its mip chain, so that the texture unit delivers what the generated code decodes:

- an 8-bit PNG map: an ``.hbtx`` file of its stored bytes as RGBA8 rows, with the sRGB flag and the
  folder's addressing; the sampler returns bytes / 255, the PNG's stored values;
- a KTX2 map: the folder's own file, uploaded as stored (its chain, its format: the texture unit
  decodes the BC blocks, and the sRGB of an sRGB format); the sampler returns the stored bytes / 255
  as the loaders read them. The folder's addressing reaches the tool as ``--clamp``
  (:func:`texture_args`);
- an OpenEXR map: a float KTX2 (R32G32B32A32_SFLOAT) of its stored values and its chain, written
  here: the sampler returns the floats the EXR holds.

The generated code decodes ``offset + scale * T(v)`` after the filter, except where the texture
unit has decoded: a map whose channels are all sRGB (``srgb_texture``) is bound with
HBRDF_SRGB_TEXTURES, so the shader skips the EOTF and the upload must deliver decoded values: an
sRGB format (PNG, KTX2), or for EXR the EOTF applied to the floats before upload (decode, then
filter: the loaders' order for sRGB). The frame reads the normal map itself as ``2 v - 1``: a PNG or
KTX2 normal map must have that decode (``hbrdf paint`` writes it), an EXR one (stored x, y) is
uploaded as ``(decode(v) + 1) / 2``, which the filter commutes with (linear).
"""

from __future__ import annotations

import json
import os
import pathlib
import struct
from typing import Any, Dict, List

import numpy as np

from hybridbrdf.errors import InputFileError
from hybridbrdf.svbrdf.decode import decode, transfer
from hybridbrdf.svbrdf.ktx2 import FORMATS, write_ktx2
from hybridbrdf.svbrdf.maps import read_map

FLOAT_FORMAT = "R32G32B32A32_SFLOAT"  # an EXR map's upload: float32, as the EXR stores it
NORMAL_DECODE = {"transfer": "linear", "scale": 2.0, "offset": -1.0}  # the frame's own x, y = 2 v - 1


def _entry(folder: str, index: Dict[str, Any], file: str) -> Dict[str, Any]:
    for entry in index["maps"]:
        if entry["file"] == file:
            return entry
    raise InputFileError(os.path.join(folder, "svbrdf.json"), f"no map entry for {file}")


def _ktx2_is_srgb(path: str) -> bool:
    """Whether the KTX2 file's format is sRGB (vkFormat, the word after the 12-byte identifier;
    the loader that made the plan has read and checked the whole file)."""
    with open(path, "rb") as f:
        head = f.read(16)
    return FORMATS[struct.unpack_from("<I", head, 12)[0]].srgb


def _check_ktx2(path: str, m: Dict[str, Any], entry: Dict[str, Any]) -> None:
    """A KTX2 map is uploaded as stored: refused where the texture unit would not deliver what the
    shader decodes (an sRGB map in a linear format, a normal map not stored as (x + 1) / 2)."""
    if m["id"] == "normal":
        if any(d != NORMAL_DECODE for d in entry["decode"][:2]):
            raise InputFileError(path, "the raster frame reads a KTX2 normal map as 2 v - 1; its decode is another")
    elif m["srgb_texture"] and not _ktx2_is_srgb(path):
        raise InputFileError(path, "an sRGB map stored in a linear format; the raster frame binds sRGB maps in an "
                                   "sRGB format (hbrdf paint --format ktx2 writes one)")


def _float_levels(folder: str, m: Dict[str, Any], entry: Dict[str, Any]) -> List[np.ndarray]:
    """An EXR map's levels as the float values the shader must read (module docstring)."""
    levels = []
    for name in [entry["file"]] + list(entry.get("mips", [])):
        values, _ = read_map(os.path.join(folder, name))
        if m["id"] == "normal":
            values = np.stack([(decode(values[..., c], entry["decode"][c]) + 1.0) / 2.0 for c in range(2)]
                              + [np.ones(values.shape[:2])], -1)
        elif m["srgb_texture"]:
            values = transfer("srgb", values)
        levels.append(values.astype(np.float32))
    return levels


def _write_hbtx(path: pathlib.Path, folder: str, entry: Dict[str, Any], srgb: bool, clamp: int) -> None:
    levels = []
    for name in [entry["file"]] + list(entry.get("mips", [])):
        values, _ = read_map(os.path.join(folder, name))
        rgba = np.full(values.shape[:2] + (4,), 255, np.uint8)
        rgba[..., :3] = np.rint(values * 255.0).astype(np.uint8)
        levels.append(rgba)
    height, width = levels[0].shape[:2]
    with open(path, "wb") as f:
        f.write(b"HBTX" + struct.pack("<5I", width, height, len(levels), int(srgb), clamp))
        for level in levels:
            f.write(np.ascontiguousarray(level).tobytes())


def write_textures(folder, plan: Dict[str, Any], out: pathlib.Path) -> List[pathlib.Path]:
    """The files ``hbrdf_raster --texture`` takes for the maps of ``plan``
    (``codegen.textured.textured_plan(folder)``), then the normal map's (``plan["normal"]``, when
    there is one: linear, never sRGB), in binding order: an ``.hbtx`` file written into ``out`` per
    PNG map, the folder's own file per KTX2 map, a float ``.ktx2`` written into ``out`` per EXR map
    (module docstring). A KTX2 map's addressing is the tool's ``--clamp`` (:func:`texture_args`).
    One-line InputFileError for a map the frame cannot upload as the shader decodes it."""
    folder = os.fspath(folder)
    with open(os.path.join(folder, "svbrdf.json"), "rb") as f:  # checked by the loader that made the plan
        index = json.loads(f.read().decode("utf-8"))
    clamp = 1 if plan["addressing"] == "clamp" else 0
    paths = []
    maps = list(plan["maps"])
    if plan.get("normal") is not None:
        maps.append({"file": plan["normal"], "id": "normal", "srgb_texture": False})
    for k, m in enumerate(maps):
        entry = _entry(folder, index, m["file"])
        source = os.path.join(folder, m["file"])
        ext = os.path.splitext(m["file"])[1].lower()
        if ext == ".ktx2":
            _check_ktx2(source, m, entry)
            paths.append(pathlib.Path(source))
        elif ext == ".exr":
            path = out / f"map{k}_{m['id']}.ktx2"
            write_ktx2(path, _float_levels(folder, m, entry), FLOAT_FORMAT)
            paths.append(path)
        else:
            if m["id"] == "normal" and any(d != NORMAL_DECODE for d in entry["decode"][:2]):
                raise InputFileError(source, "the raster frame reads an 8-bit normal map as 2 v - 1; its decode is another")
            path = out / f"map{k}_{m['id']}.hbtx"
            _write_hbtx(path, folder, entry, m["srgb_texture"], clamp)
            paths.append(path)
    return paths


def texture_args(folder, plan: Dict[str, Any], out: pathlib.Path) -> List[str]:
    """``hbrdf_raster``'s arguments for the textured material of ``plan``: ``--texture`` per file of
    :func:`write_textures`, and ``--clamp`` for a folder of clamp addressing (the KTX2 files'
    addressing; an ``.hbtx`` file carries its own)."""
    args = [] if plan["addressing"] != "clamp" else ["--clamp"]
    for path in write_textures(folder, plan, out):
        args += ["--texture", str(path)]
    return args
