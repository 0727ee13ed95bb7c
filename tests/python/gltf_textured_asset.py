"""A small textured glTF asset written by pygltflib (a second writer), and its float64 reference
(docs/GLTF.md, "Textures"): shared by test_gltf_textures.py (the tracer) and
test_raster_gltf_textures.py (the raster frame).

The asset: a 3 x 2 quad in the z = 0 plane facing +z (the camera), TANGENT (1, 0, 0, 1) given,
uv an affine function of the position (u from -0.5 to 1.5 along +x, v from -0.25 at the top to
1.25 at the bottom: every wrap mode leaves [0, 1]). Its material "Painted": baseColorFactor times
a two-colour sRGB baseColorTexture (REPEAT), metallicRoughnessTexture with a roughness ramp along
u in G and metallic along v in B (MIRRORED_REPEAT, magFilter NEAREST), and a tilted normalTexture
with scale 0.8 (CLAMP_TO_EDGE).

The reference computes, at each pixel centre, the pinhole ray's hit on the exact plane, its uv,
the texel lookups by hand (wrap, bilinear or nearest, sRGB decoded per texel before filtering), the
mapping of docs/GLTF.md, the normal map's frame (glTF: +Y up in the image; this library's b = n x t
= +y world here, the image's top: a green above 128 tilts n_s toward +y) and the textbook f_a."""

import io
import json

import numpy as np
from PIL import Image

from textbook_reference import textbook_fa

W, H = 48, 32
CAMERA = {"position": [0.0, 0.0, 3.0], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 40, "width": W, "height": H}
LIGHTS = [{"type": "point", "position": [0.6, 0.9, 1.6], "intensity": [3.0, 2.5, 2.0]},
          {"type": "directional", "direction": [-0.4, 0.5, 1.0], "irradiance": [0.9, 1.0, 1.1]}]
HALF = (1.5, 1.0)  # the quad's half sizes along x and y

BASE_FACTOR = (0.9, 0.8, 1.0)
METALLIC, ROUGHNESS = 0.7, 0.9
BASE_TEXELS = np.array([[[230, 40, 30], [30, 90, 200]]], np.uint8)  # 1 x 2: red | blue
MR_TEXELS = np.zeros((2, 8, 3), np.uint8)
MR_TEXELS[:, :, 1] = 40 + 30 * np.arange(8)  # G: roughness ramp along u
MR_TEXELS[1, :, 2] = 255  # B: metallic 0 in the top row, 1 in the bottom one
NORMAL_TEXELS = np.array([[[160, 185, 235], [110, 150, 240]]], np.uint8)  # tilted: +x/-x, +y (up)
NORMAL_SCALE = 0.8
REPEAT, CLAMP, MIRRORED = 10497, 33071, 33648
SAMPLERS = {"base": (REPEAT, REPEAT, 9729, 9987), "mr": (MIRRORED, MIRRORED, 9728, 9728), "normal": (CLAMP, CLAMP, 9729, 9729)}


def png_bytes(texels, fmt="PNG") -> bytes:
    out = io.BytesIO()
    Image.fromarray(texels).save(out, format=fmt)
    return out.getvalue()


def uv_of(x, y):
    return (x + HALF[0]) / (2 * HALF[0]) * 2.0 - 0.5, -0.25 + (HALF[1] - y) / (2 * HALF[1]) * 1.5


def write_asset(path, images=None, edit=None, normal=True, mirrored=False):
    """The quad GLB at `path`; `images` replaces the encoded images {"base", "mr", "normal"} (bytes,
    mimeType); `edit(doc)` edits the glTF JSON before it is written (hostile cases). `mirrored`: u
    decreases along +x (uv_of(-x, y), a mirrored uv island) and TANGENT is (-1, 0, 0, -1): t = dP/du
    = -x and b = w n x t = +y, still the image's top."""
    import pygltflib

    xs, ys = np.array([-HALF[0], HALF[0], HALF[0], -HALF[0]]), np.array([-HALF[1], -HALF[1], HALF[1], HALF[1]])
    pos = np.stack([xs, ys, np.zeros(4)], 1).astype(np.float32)
    nrm = np.tile(np.float32([0, 0, 1]), (4, 1))
    tan = np.tile(np.float32([-1, 0, 0, -1] if mirrored else [1, 0, 0, 1]), (4, 1))
    uv = np.stack(uv_of(-xs if mirrored else xs, ys), 1).astype(np.float32)
    idx = np.array([0, 1, 2, 0, 2, 3], np.uint32)
    encoded = {"base": (png_bytes(BASE_TEXELS), "image/png"), "mr": (png_bytes(MR_TEXELS), "image/png"),
               "normal": (png_bytes(NORMAL_TEXELS), "image/png")}
    encoded.update(images or {})
    blobs = [pos.tobytes(), nrm.tobytes(), tan.tobytes(), uv.tobytes(), idx.tobytes()] + [encoded[k][0] for k in encoded]
    views, data = [], b""
    for blob in blobs:
        views.append({"buffer": 0, "byteOffset": len(data), "byteLength": len(blob)})
        data += blob + b"\0" * (-len(blob) % 4)
    acc = [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": pos.min(0).tolist(),
            "max": pos.max(0).tolist()},
           {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
           {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC4"},
           {"bufferView": 3, "componentType": 5126, "count": 4, "type": "VEC2"},
           {"bufferView": 4, "componentType": 5125, "count": 6, "type": "SCALAR"}]
    keys = list(encoded)
    material = {"name": "Painted", "pbrMetallicRoughness": {
        "baseColorFactor": [*BASE_FACTOR, 1.0], "metallicFactor": METALLIC, "roughnessFactor": ROUGHNESS,
        "baseColorTexture": {"index": keys.index("base")}, "metallicRoughnessTexture": {"index": keys.index("mr")}}}
    if normal:
        material["normalTexture"] = {"index": keys.index("normal"), "scale": NORMAL_SCALE}
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TANGENT": 2, "TEXCOORD_0": 3},
                                       "indices": 4, "material": 0}]}],
           "materials": [material], "accessors": acc, "bufferViews": views, "buffers": [{"byteLength": len(data)}],
           "images": [{"bufferView": 5 + i, "mimeType": encoded[k][1]} for i, k in enumerate(keys)],
           "samplers": [dict(zip(("wrapS", "wrapT", "magFilter", "minFilter"), SAMPLERS[k])) for k in keys],
           "textures": [{"source": i, "sampler": i} for i in range(len(keys))]}
    if edit:
        edit(doc)
    gltf = pygltflib.GLTF2.from_dict(json.loads(json.dumps(doc)))
    gltf.set_binary_blob(data)
    gltf.save_binary(str(path))
    return path


def scene(asset, bind=None, materials=None):
    obj = {"type": "gltf", "file": str(asset)}
    if bind:
        obj["bind"] = bind
    s = {"camera": CAMERA, "environment": {"type": "constant", "radiance": 0}, "lights": LIGHTS, "objects": [obj],
         "max_depth": 1, "spp": 1, "pixel_jitter": False, "shadows": False, "threads": 1}
    if materials:
        s["materials"] = materials
    return s


# ---- the float64 reference ----------------------------------------------------------------------

def srgb_to_linear(x):
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def wrap(i, n, mode):
    if mode == CLAMP:
        return np.clip(i, 0, n - 1)
    if mode == MIRRORED:
        m = np.mod(i, 2 * n)
        return np.where(m < n, m, 2 * n - 1 - m)
    return np.mod(i, n)


def lookup(texels, u, v, sampler, srgb=False):
    """Texels (h, w, 3) uint8 at (u, v) through a glTF sampler (level 0, magnification)."""
    ws, wt, mag, _ = sampler
    values = texels.astype(np.float64) / 255.0
    if srgb:
        values = srgb_to_linear(values)
    h, w = texels.shape[:2]
    if mag == 9728:
        return values[wrap(int(np.floor(v * h)), h, wt), wrap(int(np.floor(u * w)), w, ws)]
    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = int(np.floor(x)), int(np.floor(y))
    ax, ay = x - x0, y - y0
    xa, xb, ya, yb = wrap(x0, w, ws), wrap(x0 + 1, w, ws), wrap(y0, h, wt), wrap(y0 + 1, h, wt)
    return ((values[ya, xa] * (1 - ax) + values[ya, xb] * ax) * (1 - ay) +
            (values[yb, xa] * (1 - ax) + values[yb, xb] * ax) * ay)


def mapping(base, metallic, roughness, ior=1.5):
    """docs/GLTF.md's glTF -> f_a, float64 (specular 1, specularColor 1, no anisotropy)."""
    f0 = np.clip(((ior - 1) / (ior + 1)) ** 2 * (1 - metallic) + base * metallic, 0, 1)
    s = np.sqrt(f0)
    eta = np.where(s < 1, np.clip((1 + s) / np.maximum(1 - s, 1e-300), 1, 10), 10)
    alpha = np.clip(roughness * roughness, 1e-4, 1)
    return base * (1 - metallic), eta, (alpha, alpha)


def shading_frame(tn):
    """normal_map.hpp's frame of tangent-space normal tn on t = +x, b = +y, n = +z."""
    ns = tn / np.linalg.norm(tn)
    ts = np.array([1.0, 0, 0]) - ns * ns[0]
    ts /= np.linalg.norm(ts)
    return ts, np.cross(ns, ts), ns


_CACHE = {}


def reference(params_of=None, normal=True, flip_y=False):
    """Cached per (normal, flip_y) for the asset's own textures (params_of None); see _reference."""
    if params_of is not None:
        return _reference(params_of, normal, flip_y)
    if (normal, flip_y) not in _CACHE:
        _CACHE[normal, flip_y] = _reference(None, normal, flip_y)
    return _CACHE[normal, flip_y]


def _reference(params_of, normal, flip_y):
    """(H, W, 3) radiance at the pixel centres and the mask of pixels on the quad. `params_of(u, v)`
    gives f_a's (kd, eta, alpha) at a uv (default: the asset's textures through the mapping)."""
    pos, look, up = (np.array(CAMERA[k], float) for k in ("position", "look_at", "up"))
    forward = (look - pos) / np.linalg.norm(look - pos)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    th = np.tan(np.radians(CAMERA["fov_deg"]) / 2)
    image, on = np.zeros((H, W, 3)), np.zeros((H, W), bool)
    for py in range(H):
        for px in range(W):
            sx, sy = (2 * (px + 0.5) / W - 1) * th * W / H, (1 - 2 * (py + 0.5) / H) * th
            d = forward + right * sx + up * sy
            d /= np.linalg.norm(d)
            p = pos + d * (-pos[2] / d[2])
            if abs(p[0]) >= HALF[0] or abs(p[1]) >= HALF[1]:
                continue
            on[py, px] = True
            u, v = uv_of(p[0], p[1])
            if params_of is None:
                base = np.array(BASE_FACTOR) * lookup(BASE_TEXELS, u, v, SAMPLERS["base"], srgb=True)
                mr = lookup(MR_TEXELS, u, v, SAMPLERS["mr"])
                kd, eta, alpha = mapping(base, METALLIC * mr[2], ROUGHNESS * mr[1])
            else:
                kd, eta, alpha = params_of(u, v)
            frame = np.eye(3)
            if normal:
                rgb = lookup(NORMAL_TEXELS, u, v, SAMPLERS["normal"])
                tn = (2 * rgb - 1) * np.array([NORMAL_SCALE, -NORMAL_SCALE if flip_y else NORMAL_SCALE, 1.0])
                frame = np.array(shading_frame(tn))
            wo_world = (pos - p) / np.linalg.norm(pos - p)
            for light in LIGHTS:
                if light["type"] == "point":
                    dl = np.array(light["position"]) - p
                    wi_world, arriving = dl / np.linalg.norm(dl), np.array(light["intensity"]) / (dl @ dl)
                else:
                    dl = np.array(light["direction"], float)
                    wi_world, arriving = dl / np.linalg.norm(dl), np.array(light["irradiance"])
                if wi_world[2] <= 0:
                    continue
                wi, wo = frame @ wi_world, frame @ wo_world  # rows t_s, b_s, n_s
                if wi[2] <= 0 or wo[2] <= 0:
                    continue
                f = textbook_fa(wi[None], wo[None], kd, eta, alpha)[0]
                image[py, px] += f * wi_world[2] * arriving
    return image, on
