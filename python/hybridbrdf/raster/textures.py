"""A textured material's maps as the files ``hbrdf_raster --texture`` uploads (cpp/tools/raster/
textures.hpp): per map, in the generated lookup's parameter order (``codegen/textured.py``), its
stored 8-bit values and mip chain as RGBA8 rows, with the sRGB flag and the folder's addressing.
The texture unit filters the stored values and the generated code decodes them (docs/CODEGEN.md,
"A textured material in an engine"); a map bound as sRGB is decoded by the texture unit first.
"""

from __future__ import annotations

import json
import os
import pathlib
import struct
from typing import Any, Dict, List

import numpy as np

from hybridbrdf.errors import InputFileError
from hybridbrdf.svbrdf.maps import read_map


def _level_files(folder: str, index: Dict[str, Any], file: str) -> List[str]:
    for entry in index["maps"]:
        if entry["file"] == file:
            return [os.path.join(folder, name) for name in [file] + list(entry.get("mips", []))]
    raise InputFileError(os.path.join(folder, "svbrdf.json"), f"no map entry for {file}")


def write_textures(folder, plan: Dict[str, Any], out: pathlib.Path) -> List[pathlib.Path]:
    """Writes one ``.hbtx`` file per map of ``plan`` (``codegen.textured.textured_plan(folder)``)
    into ``out``, then the normal map's (``plan["normal"]``, when there is one: linear, never sRGB);
    returns them in binding order. InputFileError for maps that are not 8-bit PNG (EXR and KTX2
    maps are not uploaded yet)."""
    folder = os.fspath(folder)
    with open(os.path.join(folder, "svbrdf.json"), "rb") as f:  # checked by the loader that made the plan
        index = json.loads(f.read().decode("utf-8"))
    clamp = 1 if plan["addressing"] == "clamp" else 0
    paths = []
    maps = list(plan["maps"])
    if plan.get("normal") is not None:
        maps.append({"file": plan["normal"], "id": "normal", "srgb_texture": False})
    for k, m in enumerate(maps):
        levels = []
        for file in _level_files(folder, index, m["file"]):
            values, bits = read_map(file)
            if bits != 8:
                raise InputFileError(file, "the raster frame uploads 8-bit PNG maps; this one is floating point")
            rgba = np.full(values.shape[:2] + (4,), 255, np.uint8)
            rgba[..., :3] = np.rint(values * 255.0).astype(np.uint8)
            levels.append(rgba)
        height, width = levels[0].shape[:2]
        path = out / f"map{k}_{m['id']}.hbtx"
        with open(path, "wb") as f:
            f.write(b"HBTX" + struct.pack("<5I", width, height, len(levels), int(m["srgb_texture"]), clamp))
            for level in levels:
                f.write(np.ascontiguousarray(level).tobytes())
        paths.append(path)
    return paths
