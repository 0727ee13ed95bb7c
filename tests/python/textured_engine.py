"""Helpers of tests/python/test_codegen_textured.py: the engine side of a generated textured material
(docs/CODEGEN.md, "A textured material in an engine"): small textured folders, a fragment shader per
dialect that declares the maps the generated lookup takes, a WGSL compute kernel that samples the
maps through real wgpu samplers on lavapipe, and the float64 reference of what a sampler does
(bilinear filter of the stored values, then the index's decode) written here from docs/SVBRDF.md,
independently of hybridbrdf.svbrdf."""

from __future__ import annotations

import json
import pathlib

import numpy as np

from hybridbrdf.svbrdf import SVBRDF
from hybridbrdf.svbrdf.maps import read_map

from helpers import saved_random_model

#: The folders' texture size: powers of two, so that uv = (i + 0.5 + k / 256) / W is exact in float32
#: and a sampler's bilinear fraction at it is k / 256, which 8 fraction bits hold exactly.
W, H = 16, 8


def make_folder(tmp: pathlib.Path, kind: str) -> pathlib.Path:
    """A textured folder of a tiny random model (3 materials, latent 4, material heads, energy tables):
    ``doc``: 2 layers, a weights map only (the shape of scenes/textured.json's painted folder);
    ``linear``: 4 layers (one material twice), weights, an sRGB kd map, an eta map and latent maps:
    every channel either linear or sRGB, so a sampler's filter commutes with the decode;
    ``all``: 3 layers, weights, an sRGB kd map and an alpha map (T = square: filter and decode do not
    commute), clamp addressing; ``normal``: ``all``'s layers and maps but kd, repeat addressing, and a
    tangent-space normal map (glTF convention: x, y in R, G; a smooth bump field with noise, up to
    70 degrees from +z, so that the horizon rule cuts pairs off); ``doc_normal``: ``doc`` with that
    normal map (docs/CODEGEN.md's two lines for a normal map)."""
    tmp.mkdir(parents=True, exist_ok=True)
    _, model = saved_random_model(tmp, "hybrid", output_layer="material", energy_bound=True)
    rng = np.random.default_rng({"doc": 1, "linear": 2, "all": 3, "normal": 4, "doc_normal": 4}[kind])
    mats = model.materials
    # Weights: pure regions, soft ramps and texels whose sum passes 1 (normalised).
    weights = np.zeros((H, W, 3), np.float32)
    weights[:, 8:, 0] = 1.0
    weights[4:, :, 1] = np.linspace(0, 1, W, dtype=np.float32)
    weights[2, :, :] = rng.uniform(0, 0.7, (W, 3))
    kd = rng.uniform(0, 1, (H, W, 3)).astype(np.float32)
    if kind in ("doc", "doc_normal"):
        layers, maps, addressing = mats[:2], [{}, {}], "repeat"
        weights[..., 1:] = 0
    elif kind == "linear":
        layers, addressing = [mats[0], mats[1], mats[2], mats[1]], "repeat"
        maps = [{"kd": kd}, {"eta": rng.uniform(1.1, 4, (H, W, 3)).astype(np.float32)}, {},
                {"latent": rng.uniform(-1, 1, (H, W, 4)).astype(np.float32)}]
    else:
        layers, addressing = mats[:3], "clamp" if kind == "all" else "repeat"
        weights[..., 2] = 0
        maps = [{"kd": kd} if kind == "all" else {}, {"alpha": rng.uniform(0.05, 0.9, (H, W, 2)).astype(np.float32)}, {}]
    normal = None
    if kind in ("normal", "doc_normal"):
        u, v = (np.arange(W) + 0.5) / W, (np.arange(H) + 0.5) / H
        normal = np.stack(np.broadcast_arrays(0.6 * np.sin(4 * np.pi * u)[None, :], 0.5 * np.cos(2 * np.pi * v)[:, None]), 2)
        normal = normal + rng.uniform(-0.25, 0.25, (H, W, 2))
        normal *= np.minimum(1.0, 0.94 / np.linalg.norm(normal, axis=2, keepdims=True))  # within 70 degrees of +z
    folder = tmp / "sv"
    SVBRDF(model, layers, (W, H), weights, maps, addressing,
           normal=None if normal is None else normal.astype(np.float32)).save(folder, format="png")
    return folder


# ---- the reference: what a sampler does, in float64 ----------------------------------------------


def _eotf(v):
    v = np.asarray(v, np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((np.maximum(v, 0.04045) + 0.055) / 1.055) ** 2.4)


_T = {"linear": lambda v: v, "square": lambda v: v * v, "srgb": _eotf}


def sampler_reference(folder: pathlib.Path, uv: np.ndarray, srgb_textures: bool, shift=None):
    """Per pair the texel values a bilinear sampler at level 0 gives the generated decode, from the
    stored maps: taps at texel centres ((i + 0.5) / W, v down), repeat or clamp-to-edge, each map's
    stored values filtered (an sRGB map bound as an sRGB texture: decoded per tap, then filtered),
    then decoded; weights normalised as docs/SVBRDF.md says. ``shift`` (file, channel, delta) adds delta
    to that channel's filtered values (before its decode; after the texture unit's for an sRGB texture).
    Returns the model, the material index per layer and the (weight, kd, eta, alpha, latent) texel
    values of libhybridbrdf's eval_texels."""
    import hybridbrdf as hb

    index = json.loads((folder / "svbrdf.json").read_text())
    model = hb.load_model(folder / index["model"])
    names = [layer["material"] for layer in index["layers"]]
    L, n, w, h = len(names), len(uv), *index["size"]
    repeat = index["addressing"] == "repeat"
    u, v = (uv[:, 0], uv[:, 1]) if repeat else (np.clip(uv[:, 0], 0, 1), np.clip(uv[:, 1], 0, 1))
    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    taps = []
    for dy, wy in ((0, 1 - fy), (1, fy)):
        for dx, wx in ((0, 1 - fx), (1, fx)):
            cx, cy = (x0 + dx).astype(int), (y0 + dy).astype(int)
            cx, cy = (cx % w, cy % h) if repeat else (np.clip(cx, 0, w - 1), np.clip(cy, 0, h - 1))
            taps.append((cy, cx, wx * wy))
    t = model.tensors
    vals = {"kd": np.repeat(t["materials.kd"][None, [model.index(m) for m in names]], n, 0).astype(np.float64),
            "eta": np.repeat(t["materials.eta"][None, [model.index(m) for m in names]], n, 0).astype(np.float64),
            "alpha": np.repeat(t["materials.alpha"][None, [model.index(m) for m in names]], n, 0).astype(np.float64),
            "latent": np.repeat(t["materials.z"][None, [model.index(m) for m in names]], n, 0).astype(np.float64),
            "normal": np.zeros((n, 1, 2))}  # the normal map's decoded x, y (one for the texel)
    rest = np.zeros((n, 3))
    for entry in index["maps"]:
        stored, _ = read_map(folder / entry["file"])
        for ch, d in enumerate(entry["decode"]):
            if d is None:
                continue
            by_texture = srgb_textures and all(e is None or e["transfer"] == "srgb" for e in entry["decode"])
            delta = shift[2] if shift is not None and shift[:2] == (entry["file"], ch) else 0.0
            if d["transfer"] == "srgb" and by_texture:  # the texture unit decodes, then filters
                filtered = sum(_eotf(stored[r, c, ch]) * a for r, c, a in taps) + delta
                value = d["offset"] + d["scale"] * filtered
            else:
                filtered = np.clip(sum(stored[r, c, ch] * a for r, c, a in taps) + delta, 0, 1)
                value = d["offset"] + d["scale"] * _T[d["transfer"]](filtered)
            q, k, comp = entry["quantity"], entry.get("layer"), entry["first"] + ch
            if q == "weights":
                rest[:, ch] = value
            elif q == "normal":
                vals[q][:, 0, comp] = value
            else:
                vals[q][:, k, comp] = value
    rest = np.maximum(rest[:, :L - 1], 0)
    total = rest.sum(axis=1, keepdims=True)
    rest = np.where(total > 1, rest / np.maximum(total, 1e-30), rest)
    weight = np.concatenate([np.clip(1 - np.minimum(total, 1), 0, 1), rest], axis=1)
    mat = np.broadcast_to(np.asarray([model.index(m) for m in names], np.int32), (n, L))
    return model, np.ascontiguousarray(mat), weight, vals


def shading_directions(xy, wi, wo):
    """(wi_s, wo_s, visible) of a normal map's filtered x, y (N, 2), in float64 from docs/SVBRDF.md's
    words: n_s = (x, y, sqrt(max(0, 1 - x^2 - y^2))) normalised, t_s = the tangent (+x) minus its
    n_s part, normalised, b_s = n_s x t_s; directions given in the geometric frame (t, b, n = x, y,
    z) expressed in (t_s, b_s, n_s); visible: both above the geometric and the shading horizon."""
    xy = np.asarray(xy, np.float64)
    n_s = np.concatenate([xy, np.sqrt(np.maximum(0.0, 1.0 - (xy ** 2).sum(1, keepdims=True)))], 1)
    n_s /= np.linalg.norm(n_s, axis=1, keepdims=True)
    t_s = np.array([1.0, 0.0, 0.0]) - n_s[:, :1] * n_s
    t_s /= np.linalg.norm(t_s, axis=1, keepdims=True)
    b_s = np.cross(n_s, t_s)
    wi, wo = np.asarray(wi, np.float64), np.asarray(wo, np.float64)
    wi_s, wo_s = (np.stack([(w * a).sum(1) for a in (t_s, b_s, n_s)], 1) for w in (wi, wo))
    visible = (wi[:, 2] > 0) & (wo[:, 2] > 0) & (wi_s[:, 2] > 0) & (wo_s[:, 2] > 0)
    return wi_s, wo_s, visible


def eval_reference(folder, uv, wi, wo, srgb_textures: bool, shift=None, ignore_normal: bool = False) -> np.ndarray:
    """libhybridbrdf's f (HybridModel::eval_texel) at the texel values of :func:`sampler_reference`;
    with a normal map (unless ``ignore_normal``), at the directions in the texel's shading frame
    (:func:`shading_directions`), 0 where the rule cuts them off."""
    model, mat, weight, vals = sampler_reference(folder, uv, srgb_textures, shift)
    visible = None
    if not ignore_normal and any(e["quantity"] == "normal" for e in json.loads((folder / "svbrdf.json").read_text())["maps"]):
        wi, wo, visible = shading_directions(vals["normal"][:, 0], wi, wo)
    f32 = lambda a: np.ascontiguousarray(a, np.float32)  # noqa: E731
    f = model._cpp_model().eval_texels(f32(wi), f32(wo), mat, f32(weight), f32(vals["kd"]), f32(vals["eta"]),
                                       f32(vals["alpha"]), f32(vals["latent"])).astype(np.float64)
    return f if visible is None else np.where(visible[:, None], f, 0.0)


# ---- WGSL through wgpu's samplers ------------------------------------------------------------------

WGSL_KERNEL = """
@group(0) @binding(0) var<storage, read> pairs: array<f32>;
@group(0) @binding(1) var<storage, read_write> out: array<f32>;
@group(0) @binding(2) var map_sampler: sampler;
{TEXTURES}
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3u) {{
    let i = gid.x;
    if (i >= arrayLength(&pairs) / 11u) {{ return; }}
    let uv = vec2f(pairs[11u * i], pairs[11u * i + 1u]);
    let wi = vec3f(pairs[11u * i + 2u], pairs[11u * i + 3u], pairs[11u * i + 4u]);
    let wo = vec3f(pairs[11u * i + 5u], pairs[11u * i + 6u], pairs[11u * i + 7u]);
    let lod = pairs[11u * i + 8u];
    let dx = vec2f(pairs[11u * i + 9u], 0.0);
    let dy = vec2f(0.0, pairs[11u * i + 10u]);
    let f_lod = hbrdf_eval_texel(wi, wo, hbrdf_texel_lod({ARGS}, uv, lod));
    let f_grad = hbrdf_eval_texel(wi, wo, hbrdf_texel_grad({ARGS}, uv, dx, dy));
    out[6u * i] = f_lod.x; out[6u * i + 1u] = f_lod.y; out[6u * i + 2u] = f_lod.z;
    out[6u * i + 3u] = f_grad.x; out[6u * i + 4u] = f_grad.y; out[6u * i + 5u] = f_grad.z;
}}
"""


PROBE_KERNEL = """
@group(0) @binding(0) var<storage, read> uvs: array<vec2f>;
@group(0) @binding(1) var<storage, read_write> out: array<vec4f>;
@group(0) @binding(2) var s: sampler;
@group(0) @binding(3) var t: texture_2d<f32>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3u) {
    if (gid.x < arrayLength(&uvs)) { out[gid.x] = textureSampleLevel(t, s, uvs[gid.x], 0.0); }
}
"""


def _dispatch(kernel: str, entries, inputs: np.ndarray, out_bytes: int, constants=None) -> np.ndarray:
    """One compute dispatch of ``kernel`` (``main``, 64 per workgroup) on lavapipe: binding 0 the input
    floats, 1 the output, then ``entries`` (sampler, textures); returns the output as float32."""
    import wgpu

    from slang_wgsl_tools import wgpu_device

    device = wgpu_device()
    try:  # one module: naga parses and validates the kernel once (slang_wgsl_tools.run_wgsl's way)
        module = device.create_shader_module(code=kernel)
    except wgpu.GPUValidationError as e:
        raise AssertionError(str(e)[-3000:]) from None
    compute_stage = {"module": module, "entry_point": "main"}
    if constants:
        compute_stage["constants"] = constants
    pipeline = device.create_compute_pipeline(layout="auto", compute=compute_stage)
    buf_in = device.create_buffer_with_data(data=np.ascontiguousarray(inputs, np.float32).ravel(),
                                            usage=wgpu.BufferUsage.STORAGE)
    buf_out = device.create_buffer(size=out_bytes, usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC)
    entries = [{"binding": 0, "resource": {"buffer": buf_in}}, {"binding": 1, "resource": {"buffer": buf_out}}] + entries
    bind = device.create_bind_group(layout=pipeline.get_bind_group_layout(0), entries=entries)
    encoder = device.create_command_encoder()
    compute = encoder.begin_compute_pass()
    compute.set_pipeline(pipeline)
    compute.set_bind_group(0, bind)
    compute.dispatch_workgroups((len(inputs) + 63) // 64, 1, 1)
    compute.end()
    device.queue.submit([encoder.finish()])
    return np.frombuffer(device.queue.read_buffer(buf_out), dtype=np.float32).copy()


def mip_chain(stored: np.ndarray, levels: int):
    """[level 0, 1, ...] of 8-bit (H, W, 3) values, each level the bottom-right texel of each 2x2 block of
    the one above: not a filter an engine would use, but any chain does for the lookup (the reference
    reads the same), and this one differs from what level 0's filter gives at level 1's texel centres,
    so that a lookup reading the wrong level is seen."""
    chain = [stored]
    for _ in range(1, levels):
        chain.append(np.ascontiguousarray(chain[-1][1::2, 1::2]))
    return chain


def _texture(stored_rgb, format: str, levels: int = 1):
    """An (H, W) texture of ``format`` holding 8-bit (H, W, 3) values (alpha 255) and ``levels`` mip
    levels of them (:func:`mip_chain`), or ``stored_rgb`` a list of levels (a folder's own chain), its view."""
    chain = list(stored_rgb) if isinstance(stored_rgb, list) else mip_chain(stored_rgb, levels)
    stored_rgb, levels = chain[0], len(chain)
    import wgpu

    from slang_wgsl_tools import wgpu_device

    device = wgpu_device()
    h, w = stored_rgb.shape[:2]
    tex = device.create_texture(size=(w, h, 1), format=format, mip_level_count=levels,
                                usage=wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_DST)
    for level, values in enumerate(chain):
        lh, lw = values.shape[:2]
        rgba = np.concatenate([values, np.full((lh, lw, 1), 255, np.uint8)], axis=2)
        device.queue.write_texture({"texture": tex, "mip_level": level}, np.ascontiguousarray(rgba),
                                   {"bytes_per_row": 4 * lw, "rows_per_image": lh}, (lw, lh, 1))
    return tex.create_view()


def sample_probe(format: str, row: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The red channel lavapipe's linear sampler (clamp, level 0) returns at (u, 0.5) of a one-row
    texture of ``format`` whose texels' red bytes are ``row``."""
    from slang_wgsl_tools import wgpu_device

    sampler = wgpu_device().create_sampler(mag_filter="linear", min_filter="linear", mipmap_filter="nearest")
    rgb = np.zeros((1, len(row), 3), np.uint8)
    rgb[0, :, 0] = row
    uv = np.stack([u, np.full_like(u, 0.5)], axis=1)
    out = _dispatch(PROBE_KERNEL, [{"binding": 2, "resource": sampler}, {"binding": 3, "resource": _texture(rgb, format)}],
                    uv, 16 * len(u))
    return out.reshape(-1, 4)[:, 0].astype(np.float64)


def map_params(code: str):
    """The lookup's map parameters, in order, from the generated hbrdf_texel_lod's signature."""
    import re

    sig = re.search(r"fn hbrdf_texel_lod\((.*?)\)", code).group(1)
    return re.findall(r"(map_\w+): texture_2d<f32>", sig)


def run_wgsl_textured(code: str, folder: pathlib.Path, pairs: np.ndarray, srgb_textures: bool,
                      levels: int = 1, lod=0) -> np.ndarray:
    """The generated WGSL's hbrdf_texel_lod (level ``lod``: one for all pairs, or one per pair) and
    hbrdf_texel_grad (derivatives of 2^lod texels along u and v: the same level) with hbrdf_eval_texel,
    in a compute kernel on lavapipe: the lod and the derivatives are inputs of the kernel, not literals,
    so that pairs at several levels cost one pipeline (lavapipe compiling it is most of a call's time). The
    folder's STORED 8-bit maps uploaded as rgba8unorm textures (rgba8unorm-srgb for sRGB maps where
    ``srgb_textures``; the kernel's HBRDF_SRGB_TEXTURES override set to match) with the folder's own
    mip chain where its index has one, else ``levels`` levels of :func:`mip_chain`, one linear sampler with a nearest mip filter and the index's
    addressing. Returns (n, 6): f through the lod lookup, then through the grad one."""
    from slang_wgsl_tools import wgpu_device

    index = json.loads((folder / "svbrdf.json").read_text())
    by_param = {}
    for e in index["maps"]:
        ident = e["quantity"] if e["quantity"] in ("weights", "normal") else f"layer{e['layer']}_{e['quantity']}" + (
            str(e["first"] // 3) if e["quantity"] == "latent" else "")
        by_param["map_" + ident] = e
    params = map_params(code)
    textures = "\n".join(f"@group(0) @binding({3 + j}) var {p}: texture_2d<f32>;" for j, p in enumerate(params))
    w, h = index["size"]
    kernel = code + WGSL_KERNEL.format(TEXTURES=textures, ARGS=", ".join(params + ["map_sampler"]))
    lods = np.broadcast_to(np.asarray(lod, np.float64), (len(pairs),))
    pairs = np.concatenate([pairs, lods[:, None], (2.0 ** lods / w)[:, None], (2.0 ** lods / h)[:, None]], 1)
    address = "repeat" if index["addressing"] == "repeat" else "clamp-to-edge"
    sampler = wgpu_device().create_sampler(address_mode_u=address, address_mode_v=address, mag_filter="linear",
                                           min_filter="linear", mipmap_filter="nearest")
    entries = [{"binding": 2, "resource": sampler}]
    for j, p in enumerate(params):
        entry = by_param[p]
        files = [entry["file"]] + list(entry.get("mips", []))  # a format-2 folder's own chain, when it has one
        stored = [np.rint(read_map(folder / f)[0] * 255).astype(np.uint8) for f in files]
        srgb = srgb_textures and all(d is None or d["transfer"] == "srgb" for d in entry["decode"])
        chain = stored if len(stored) > 1 else mip_chain(stored[0], levels)
        entries.append({"binding": 3 + j, "resource": _texture(chain, "rgba8unorm-srgb" if srgb else "rgba8unorm")})
    out = _dispatch(kernel, entries, pairs, 4 * 6 * len(pairs), {"HBRDF_SRGB_TEXTURES": 1.0 if srgb_textures else 0.0})
    return out.reshape(len(pairs), 6)


#: Lavapipe's texture unit returns a filtered rgba8unorm value, and an rgba8unorm-srgb value decoded to
#: linear, as 8-bit values (measured by test_codegen_textured.py::test_lavapipe_filters_to_8_bits): one
#: step, 1/255, is what a map's filtered value may be off by there.
STEP = 1.0 / 255


def step_tolerance(folder, uv, wi, wo, srgb_textures: bool, f_ref: np.ndarray) -> np.ndarray:
    """Per pair and channel of f, how far f may move when each map channel's filtered value is off by
    up to one 8-bit step: the sum over map channels of the larger of |f(value + step) - f| and
    |f(value - step) - f|, a first-order bound of all of them off at once, with 25% for curvature."""
    index = json.loads((pathlib.Path(folder) / "svbrdf.json").read_text())
    total = np.zeros_like(f_ref)
    for entry in index["maps"]:
        for ch, d in enumerate(entry["decode"]):
            if d is None:
                continue
            moved = [np.abs(eval_reference(folder, uv, wi, wo, srgb_textures, (entry["file"], ch, s)) - f_ref)
                     for s in (STEP, -STEP)]
            total += np.maximum(*moved)
    return 1.25 * total


# ---- the documented WGSL fragment shader, drawn ------------------------------------------------------

VERTEX_WGSL = """
struct VertexOut {
    @builtin(position) position: vec4f,
    @location(0) uv: vec2f,
    @location(1) normal: vec3f,
    @location(2) tangent: vec4f,
    @location(3) to_eye: vec3f,
};
@vertex
fn vs(@builtin(vertex_index) k: u32) -> VertexOut {
    // One triangle over the viewport; uv (0, 0) at the top-left corner, v down (framebuffer y down).
    let p = vec2f(f32((k << 1u) & 2u), f32(k & 2u)) * 2.0 - 1.0;
    var o: VertexOut;
    o.position = vec4f(p, 0.0, 1.0);
    o.uv = vec2f(0.5 * p.x + 0.5, 0.5 - 0.5 * p.y);
    o.normal = vec3f(0.0, 0.0, 1.0);
    o.tangent = vec4f(1.0, 0.0, 0.0, 1.0);
    o.to_eye = vec3f(EYE);
    return o;
}
"""


def draw_wgsl_fragment(module_code: str, weights_png: pathlib.Path, light, eye, normal_png=None) -> np.ndarray:
    """``module_code`` (the generated WGSL followed by docs/CODEGEN.md's textured.wgsl, whose fragment
    entry point is ``main``) drawn over a viewport of the weights map's size on lavapipe: one pixel per
    texel, uv at the texel centres, the surface frame the identity (normal +z, tangent +x), the light
    ``light`` with radiance 1, the eye toward ``eye``. The map as rgba8unorm, a linear repeat sampler;
    ``normal_png`` (a folder's normal map) as rgba8unorm at binding 3. Returns the (H, W, 3) float32
    radiance."""
    import wgpu

    from slang_wgsl_tools import wgpu_device, wgsl_errors

    device = wgpu_device()
    code = module_code + VERTEX_WGSL.replace("EYE", ", ".join(f"{float(x):.9g}" for x in eye))
    errors = wgsl_errors(code)
    assert errors is None, errors[-3000:]
    stored = np.rint(read_map(weights_png)[0] * 255).astype(np.uint8)
    h, w = stored.shape[:2]
    module = device.create_shader_module(code=code)
    pipeline = device.create_render_pipeline(
        layout="auto", vertex={"module": module, "entry_point": "vs"},
        primitive={"topology": "triangle-list"},
        fragment={"module": module, "entry_point": "main", "targets": [{"format": "rgba32float"}]})
    target = device.create_texture(size=(w, h, 1), format="rgba32float",
                                   usage=wgpu.TextureUsage.RENDER_ATTACHMENT | wgpu.TextureUsage.COPY_SRC)
    light_buf = device.create_buffer_with_data(data=np.array([*light, 0, 1, 1, 1, 0], np.float32),
                                               usage=wgpu.BufferUsage.UNIFORM)
    sampler = device.create_sampler(address_mode_u="repeat", address_mode_v="repeat", mag_filter="linear",
                                    min_filter="linear", mipmap_filter="nearest")
    bind = device.create_bind_group(layout=pipeline.get_bind_group_layout(0), entries=[
        {"binding": 0, "resource": _texture(stored, "rgba8unorm")}, {"binding": 1, "resource": sampler},
        {"binding": 2, "resource": {"buffer": light_buf}}] + ([] if normal_png is None else [
        {"binding": 3, "resource": _texture(np.rint(read_map(normal_png)[0] * 255).astype(np.uint8), "rgba8unorm")}]))
    encoder = device.create_command_encoder()
    draw = encoder.begin_render_pass(color_attachments=[{"view": target.create_view(), "load_op": "clear",
                                                         "store_op": "store", "clear_value": (0, 0, 0, 0)}])
    draw.set_pipeline(pipeline)
    draw.set_bind_group(0, bind)
    draw.draw(3)
    draw.end()
    device.queue.submit([encoder.finish()])
    pixels = device.queue.read_texture({"texture": target}, {"bytes_per_row": 16 * w, "rows_per_image": h}, (w, h, 1))
    return np.frombuffer(pixels, np.float32).reshape(h, w, 4)[..., :3].copy()

