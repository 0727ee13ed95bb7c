"""A textured material's folder as generated code (docs/CODEGEN.md, "A textured material in an
engine"; the folder: docs/SVBRDF.md): the plan the template's textured part (``codegen/textured.j2``)
renders: the layers' materials, and per map of the index its identifier, the shader parameter that
takes it, the layer field each channel fills and the channel's decode ``offset + scale * T(v)``.

The folder is read by the public loader (:func:`hybridbrdf.svbrdf.load_svbrdf`: every check and
one-line refusal of the format), then its index for what the loader decodes away: each map's
decode. Only level 0's decode is read; a map's mip levels (if the folder has them) are the
engine's to upload, and the generated lookup reads whatever level its sampler picks, decoding
after the filter (the decode is the same for every level). A normal map is one more map, read last
(``map_normal``): its x, y decoded, z rebuilt, the texel's shading frame built from it
(``hbrdf_normal_frame``; docs/SVBRDF.md, "Normal maps"). A chain's levels need nothing more: their
alpha maps already hold the widening the normals' lost length asks for (svbrdf/mips.py).
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, List

from hybridbrdf import spec
from hybridbrdf.codegen.literals import float_literal, material_constant
from hybridbrdf.svbrdf import load_svbrdf

SV = spec.SVBRDF
#: Per-layer quantities in the order their maps are passed to the lookup (after the weights map).
LAYER_ORDER = ("kd", "eta", "alpha", "latent")
#: How each shading language takes a map and reads it (none for C++: no sampler; the engine filters).
#: GLSL passes combined sampler2D parameters (function parameters of opaque type are GLSL since 1.10
#: and GLSL ES 1.00; a Vulkan engine with separate images and samplers calls it with
#: sampler2D(image, sampler)); HLSL, Slang and WGSL pass each map's texture and one sampler for all
#: (the maps share the folder's addressing and the engine's filtering).
TEXTURES = {
    "glsl": {"texture": "sampler2D", "sampler": None, "grad": "textureGrad({t}, uv, duv_dx, duv_dy).rgb",
             "lod": "textureLod({t}, uv, lod).rgb"},
    "hlsl": {"texture": "Texture2D<float4>", "sampler": "SamplerState map_sampler",
             "grad": "{t}.SampleGrad(map_sampler, uv, duv_dx, duv_dy).rgb", "lod": "{t}.SampleLevel(map_sampler, uv, lod).rgb"},
    "wgsl": {"texture": "texture_2d<f32>", "sampler": "sampler map_sampler",
             "grad": "textureSampleGrad({t}, map_sampler, uv, duv_dx, duv_dy).rgb",
             "lod": "textureSampleLevel({t}, map_sampler, uv, lod).rgb"},
}
TEXTURES["slang"] = TEXTURES["hlsl"]


def _map_id(quantity: str, layer, first: int) -> str:
    """``weights``, ``normal``, ``layer<k>_<quantity>``, ``layer<k>_latent<j>`` (components 3j .. 3j+2):
    the map's name in the generated code (``map_<id>`` parameters, ``HBRDF_MAP_<ID>_*`` constants)."""
    if quantity in ("weights", "normal"):
        return quantity
    return f"layer{layer}_{quantity}" + (str(first // 3) if quantity == "latent" else "")


def _targets(quantity: str, first: int, used: int, n_layers: int) -> List[str]:
    """The HbrdfMaterial field (or weight) each used channel of a map fills."""
    if quantity == "weights":
        return [f"w{c + 1}" for c in range(min(used, n_layers - 1))]
    if quantity in ("kd", "eta"):
        return [f"{quantity}.{'xyz'[c]}" for c in range(used)]
    if quantity == "alpha":
        return ["alpha_x", "alpha_y"][:used]
    if quantity == "normal":  # the tangent-space x, y (z is rebuilt from them)
        return ["x", "y"][:used]
    return [f"z[{first + c}]" for c in range(used)]


def textured_plan(folder, own_normal: bool = False) -> Dict[str, Any]:
    """What ``codegen/textured.j2`` needs of the textured material in ``folder``: ``layers`` (material
    names, base first), ``model`` (the folder's, loaded), ``materials`` (the distinct ones, the materials to emit), ``size``,
    ``addressing``, ``maps`` (in the lookup's parameter order: weights, then per layer kd, eta,
    alpha, latent maps, then the normal map) and ``layer_maps`` (per layer, its maps). Raises the
    loader's one-line SVBRDFError / ModelFileError for a folder it refuses. ``normal`` is the
    normal map entry's file (None without one); ``has_normal`` whether the generated code reads it
    (a map of ``maps``): not with ``own_normal``, for a caller that reads the map itself and applies
    the frame (the raster frame)."""
    sv = load_svbrdf(folder)
    index_path = os.path.join(os.fspath(folder), SV["index_file"])
    with open(index_path, "rb") as f:  # the loader has just read and checked it (bounded, valid)
        index = json.loads(f.read().decode("utf-8"))
    n_layers, latent = len(sv.layers), sv.model.arch["latent"]
    maps, normal = [], None
    for entry in index["maps"]:
        if entry["quantity"] == "normal":
            normal = entry["file"]
            if own_normal:
                continue
        q, layer, first = entry["quantity"], entry.get("layer"), entry["first"]
        components = 3 if q == "weights" else {"kd": 3, "eta": 3, "alpha": 2, "normal": 2, "latent": latent}[q]
        used = min(SV["map_channels"], components - first)
        targets = _targets(q, first, used, n_layers)
        channels = []
        for c in range(SV["map_channels"]):
            d = entry["decode"][c] if c < len(targets) else None
            channels.append({"transfer": d["transfer"], "scale": float_literal(d["scale"]),
                             "offset": float_literal(d["offset"]), "target": targets[c]} if d else
                            {"transfer": "linear", "scale": "0.0f", "offset": "0.0f", "target": None})
        live = [ch for ch in channels if ch["target"]]
        srgb = [ch["transfer"] == "srgb" for ch in live]
        ident = _map_id(q, layer, first)
        maps.append({"id": ident, "param": f"map_{ident}", "const": f"HBRDF_MAP_{ident.upper()}",
                     "file": entry["file"], "quantity": q, "layer": layer, "first": first, "channels": channels,
                     # An sRGB texture format decodes every colour channel: a map is bound as one (and
                     # HBRDF_SRGB_TEXTURES skips the shader's EOTF) only when all its channels are sRGB.
                     "srgb_texture": bool(srgb) and all(srgb), "live": len(live) > 0,
                     "key": (SV["max_layers"] if q == "normal" else -1 if layer is None else layer,
                             LAYER_ORDER.index(q) if q in LAYER_ORDER else -1, first)})
    maps.sort(key=lambda m: m["key"])
    maps = [m for m in maps if m["live"]]  # a weights map of one layer feeds nothing
    materials = list(dict.fromkeys(sv.layers))
    return {"model": sv.model, "folder": os.path.basename(os.path.abspath(os.fspath(folder))), "layers": sv.layers,
            "materials": materials, "size": list(sv.size), "addressing": sv.addressing, "maps": maps,
            "layer_maps": [[m for m in maps if m["layer"] == k] for k in range(n_layers)],
            "has_weights": any(m["quantity"] == "weights" for m in maps), "n_layers": n_layers,
            "levels": index.get("levels", 1), "normal": normal, "has_normal": normal is not None and not own_normal}


def textured_code(plan: Dict[str, Any], target: str) -> Dict[str, Any]:
    """``plan`` with what the template writes for ``target``: the decode's parameters (one v3 of
    filtered stored values per map), the lookups' texture parameters and reads, the weights' sum,
    each layer's material constant."""
    maps = plan["maps"]
    code = dict(plan, stored_params=[f"const v3 s_{m['id']}" for m in maps],
                layer_constants=[material_constant(n) for n in plan["layers"]],
                weight_sum=" + ".join(f"w{k}" for k in range(1, plan["n_layers"])) or "0.0f")
    tex = TEXTURES.get(target)
    if tex is not None:
        code.update(texture_params=[f"{tex['texture']} {m['param']}" for m in maps] + ([tex["sampler"]] if tex["sampler"] else []),
                    grad_reads=[tex["grad"].format(t=m["param"]) for m in maps],
                    lod_reads=[tex["lod"].format(t=m["param"]) for m in maps])
    return code
