"""``hbrdf view --svbrdf DIR``: what the page needs to show a textured material (docs/SVBRDF.md,
docs/VIEWER.md "A textured material"): its layers (materials of the folder's model), its maps as the
decoded values :func:`hybridbrdf.load_svbrdf` returns (float32, one RGB plane per map file, filtered
by the page's shader as the runtimes filter them: decode, then filter), and small images of the maps
shown beside the sphere.

The shader side is :data:`hybridbrdf.viewer.glsl._TEXTURED_MATERIAL` (WebGL2; the WebGPU backend
refuses a textured page in one line).
"""

from __future__ import annotations

import base64
import os
from typing import Any, Dict, List, Tuple

import numpy as np

from hybridbrdf import spec
from hybridbrdf.svbrdf.asset import SVBRDF
from hybridbrdf.svbrdf.entries import LAYER_QUANTITIES
from hybridbrdf.viewer.measured import png_data_uri

#: The most bytes of decoded maps (float32 RGB planes) one page takes: the page carries them as
#: base64 text (4/3 of their size) and uploads them as float textures at load.
MAX_VIEW_MAP_BYTES = 32 << 20
#: Longest side of the maps' images beside the sphere (every n-th texel; the sphere shows them whole).
THUMBNAIL_SIDE = 128
#: Floats per layer the page's uniform arrays take (4 layers x 4 floats per vector; WebGL2 guarantees
#: 224 fragment uniform vectors, the rest of the shader uses about 30).
MAX_LAYER_PACK = 192


class TexturedViewError(ValueError):
    """A textured material ``hbrdf view --svbrdf`` refuses (one line)."""


def _planes(sv: SVBRDF, level: int = 0) -> Tuple[List[np.ndarray], Dict[str, Any]]:
    """Mip level ``level``'s maps as (h, w, 3) float32 planes (a map file's 3 channels each; latent
    codes in runs of 3 components, consecutive planes) and the plane of each: ``weights`` (-1: none)
    and per quantity a list over the layers (-1: the layer's material's own values); ``normal`` the
    normal map's (x, y), -1: none. Every level has the same planes."""
    planes: List[np.ndarray] = []
    weights, maps = (sv.weights, sv.maps) if level == 0 else sv.mips[level - 1]
    normal = sv.normal if level == 0 or sv.normal is None else sv.normal_mips[level - 1]
    w, h = max(1, sv.size[0] >> level), max(1, sv.size[1] >> level)

    def add(values: np.ndarray) -> int:
        plane = np.zeros((h, w, 3), dtype=np.float32)
        plane[..., :values.shape[2]] = values
        planes.append(plane)
        return len(planes) - 1

    index: Dict[str, Any] = {"weights": -1 if weights is None else add(weights),
                             "normal": -1 if normal is None else add(normal)}  # x, y
    for q in LAYER_QUANTITIES:
        index[q] = [-1] * 4
        for k, layer_maps in enumerate(maps):
            if q in layer_maps:
                values = layer_maps[q]
                firsts = range(0, values.shape[2], 3)
                index[q][k] = [add(values[..., f:f + 3]) for f in firsts][0]
    return planes, index


def _thumbnail(rgb: np.ndarray) -> str:
    """An (H, W, 3) image in [0, 1] (display values), every n-th texel so that its longest side is at
    most :data:`THUMBNAIL_SIDE`, as a PNG data URI."""
    step = max(1, -(-max(rgb.shape[:2]) // THUMBNAIL_SIDE))
    small = np.clip(rgb[::step, ::step], 0.0, 1.0)
    return png_data_uri(np.round(small * 255.0).astype(np.uint8))


def _srgb(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def _display(quantity: str, values: np.ndarray) -> Tuple[np.ndarray, str]:
    """A map's values as an image to look at, and how they are shown."""
    v = values.astype(np.float64)
    out = np.zeros(v.shape[:2] + (3,))
    if quantity == "weights":
        out[..., :v.shape[2]] = v
        return out, "w_1, w_2, w_3 in red, green, blue"
    if quantity == "kd":
        return _srgb(v), "sRGB"
    if quantity == "eta":
        return (v - 1.0) / 9.0, "(eta - 1) / 9"
    if quantity == "normal":  # glTF's normalTexture: (x, y, z + 1) / 2 with z rebuilt
        xy = np.clip(v, -1.0, 1.0)
        out[..., :2] = (xy + 1.0) / 2.0
        out[..., 2] = (np.sqrt(np.maximum(0.0, 1.0 - (xy ** 2).sum(axis=2))) + 1.0) / 2.0
        return out, "(x + 1) / 2, (y + 1) / 2, (z + 1) / 2 (glTF style)"
    if quantity == "alpha":
        out[..., :2] = np.sqrt(v)
        return out, "sqrt(alpha_x), sqrt(alpha_y) in red, green"
    lo, hi = v.min(axis=(0, 1)), v.max(axis=(0, 1))
    span = np.where(hi > lo, hi - lo, 1.0)
    out[..., :v.shape[2]] = (v - lo) / span
    return out, "each component from its smallest to its largest value"


def thumbnails(sv: SVBRDF) -> List[Dict[str, str]]:
    """The maps as small images: [{"label", "how", "src"}], the weights first, then each layer's
    maps (latent codes 3 components an image)."""
    shown = []
    if sv.weights is not None:
        image, how = _display("weights", sv.weights)
        shown.append({"label": "weights", "how": how, "src": _thumbnail(image)})
    if sv.normal is not None:
        image, how = _display("normal", sv.normal)
        shown.append({"label": "normal map", "how": how, "src": _thumbnail(image)})
    for k, (name, maps) in enumerate(zip(sv.layers, sv.maps)):
        for q in LAYER_QUANTITIES:
            if q not in maps:
                continue
            values = maps[q]
            for f in range(0, values.shape[2], 3):
                part = values[..., f:f + 3]
                image, how = _display(q, part)
                label = q if q != "latent" else f"latent z_{f}..z_{f + part.shape[2] - 1}"
                shown.append({"label": f"layer {k} ({name}): {label}", "how": how, "src": _thumbnail(image)})
    return shown


def page_textured(sv: SVBRDF, folder: str, n_pack: int) -> Dict[str, Any]:
    """What the page's script reads for a textured material: layers (names and indices into the page's
    materials), size, addressing, the planes (base64 float32, row 0 the top of the texture; level 0's,
    then each mip level's) and their indices, the level count, the thumbnails. Raises :class:`TexturedViewError` when the maps or the layers' uniforms
    exceed what one page takes."""
    if n_pack > MAX_LAYER_PACK:
        raise TexturedViewError(f"{folder}: {n_pack} floats per layer (latent code and output layer) is more than "
                                f"the page's uniforms hold for 4 layers ({MAX_LAYER_PACK})")
    planes, index = _planes(sv)
    for level in range(1, sv.levels):  # the chain's levels after level 0, each the same planes
        planes += _planes(sv, level)[0]
    n_bytes = 4 * sum(p.size for p in planes)
    if n_bytes > MAX_VIEW_MAP_BYTES:
        raise TexturedViewError(f"{folder}: {n_bytes / 2**20:.1f} MiB of decoded maps ({len(planes)} maps of "
                                f"{sv.size[0]}x{sv.size[1]} float32 RGB texels) is more than one page takes "
                                f"(hbrdf view's limit: {MAX_VIEW_MAP_BYTES / 2**20:g} MiB)")
    raw = np.concatenate([p.ravel() for p in planes]).astype("<f4").tobytes() if planes else b""
    return {
        "folder": os.path.abspath(folder), "layers": list(sv.layers), "layer_index": list(sv.indices),
        "size": list(sv.size), "addressing": sv.addressing, "filter": "bilinear",
        "n_planes": len(planes) // sv.levels, "levels": sv.levels, "planes": base64.b64encode(raw).decode("ascii"),
        "plane": index,
        "thumbnails": thumbnails(sv), "index_file": spec.SVBRDF["index_file"],
    }


__all__ = ["MAX_VIEW_MAP_BYTES", "TexturedViewError", "page_textured", "thumbnails"]
