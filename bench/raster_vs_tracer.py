#!/usr/bin/env python3
"""The raster frame against the tracer on a glTF scene (issue 59's target; docs/RASTER.md): mean
relative error over lit pixels <= 1%, no pixel NaN or negative.

    python bench/raster_vs_tracer.py [--width 320 --height 192] [--segments 64] [--model results/rgl54_fast.safetensors]
                                     [--tool build/hbrdf_raster] [--device lavapipe|any] [--keep DIR]

The scene: one GLB (written by trimesh, a second writer) of three objects, its three glTF materials
bound three ways: "Uniform" (an icosphere) to the hybrid model material MODEL#cc_ibiza_sunset_rgb.rgl,
"Painted" (a latitude-longitude sphere with its own uvs; its tangents are assimp's from them) to a
textured folder painted from the same model (paper_white with vch_golden_yellow in a soft disc, and a
generated normal map), "Plain" (the ground quad) left unbound: the f_a of its metallic-roughness
factors. One point and one directional light, a black environment. The tracer renders it with
max_depth 1, "pixel_jitter": false (every camera ray through its pixel's centre: one sample is the
converged value, no noise to subtract), "shadows": false and "mip_lod": false (the folder has no
chain; both read level 0 bilinearly); the raster frame draws it with `hbrdf raster`'s pipeline.

The mask of lit pixels (float64 rays through the pixel centres against the exact spheres and plane
the meshes approximate): pixels whose 3x3 neighbourhood sees one object (a silhouette pixel may be
covered by either the tessellation or the other triangle set), lit by at least one light, and no
light with |cos theta_i| < 0.05 (there the facets' normal error is a percent of the cosine); on the
normal-mapped sphere no light and not the camera within the map's largest tilt + 0.05 rad of the
horizon (there the horizon rule switches f to 0, and the texture unit's 8-bit filtered normal may
fall on the other side). Relative error |raster - tracer| / max(tracer, 1e-3 of the image's largest
value), per channel, over the kept pixels.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import sys
import tempfile

import numpy as np

import hybridbrdf

ROOT = pathlib.Path(__file__).resolve().parents[1]
UNIFORM_MATERIAL = "cc_ibiza_sunset_rgb.rgl"
BASE, LAYER = "paper_white_rgb.rgl", "vch_golden_yellow_rgb.rgl"
SPHERES = {"Uniform": ([-0.75, 0.0, 0.0], 0.6), "Painted": ([0.75, 0.0, 0.2], 0.6)}
GROUND_Y, GROUND_SIZE = -0.6, 5.0
POINT = {"type": "point", "position": [1.2, 2.2, 2.4], "intensity": [7.0, 6.0, 5.0]}
SUN = {"type": "directional", "direction": [-0.6, 1.0, 0.5], "irradiance": [0.8, 0.9, 1.0]}
CAMERA = {"position": [0.2, 1.1, 3.6], "look_at": [0.0, -0.15, 0.0], "up": [0, 1, 0], "fov_deg": 40}
NORMAL_AMPLITUDE = (0.3, 0.25)  #: the normal map's largest x and y


def unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def normal_map(w: int, h: int) -> np.ndarray:
    """Tangent-space (x, y) of the generated normal map: bumps along u, a tilt along v that is not
    symmetric (a flipped green reads differently)."""
    u, v = (np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h
    x = NORMAL_AMPLITUDE[0] * np.sin(6 * np.pi * u)[None, :] * np.ones((h, 1))
    y = NORMAL_AMPLITUDE[1] * (0.5 + 0.5 * np.cos(4 * np.pi * v))[:, None] * np.ones((1, w))
    return np.stack([x, y], -1)


def paint_folder(tmp: pathlib.Path, model: pathlib.Path) -> pathlib.Path:
    """`hbrdf paint` of the model's paper_white with vch_golden_yellow in a soft disc and the normal map."""
    from PIL import Image
    w, h = 64, 32
    u, v = np.meshgrid((np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h)
    disc = np.clip((0.3 - np.hypot((u - 0.75) * 2, v - 0.5)) / 0.1, 0, 1)  # u 0.75 faces the camera
    Image.fromarray(np.rint(disc * 255).astype(np.uint8), "L").save(tmp / "mask.png")
    xy = normal_map(w, h)
    z = np.sqrt(1 - (xy * xy).sum(-1, keepdims=True))
    Image.fromarray(np.rint(np.concatenate([xy, z], -1) * 127.5 + 127.5).astype(np.uint8), "RGB").save(tmp / "normal.png")
    out = tmp / "painted"
    code = hybridbrdf.cli.main(["paint", str(model), "--base", BASE, "--layer", f"{LAYER}={tmp / 'mask.png'}",
                                "--normal", str(tmp / "normal.png"), "--out", str(out), "--quiet"])
    if code not in (0, None):
        raise RuntimeError(f"hbrdf paint failed with status {code}")
    return out


def lat_long_sphere(center, radius, segments: int):
    """A sphere with uvs (u around +y, v from the +y pole, glTF's v = 0 at the top) and vertex normals."""
    import trimesh
    rings = segments // 2
    theta = np.linspace(0, np.pi, rings + 1)[:, None]
    phi = np.linspace(0, 2 * np.pi, segments + 1)[None, :]
    n = np.stack(np.broadcast_arrays(np.sin(theta) * np.cos(phi), np.cos(theta), -np.sin(theta) * np.sin(phi)), -1)
    uv = np.stack(np.broadcast_arrays(phi / (2 * np.pi), 1 - theta / np.pi), -1)  # trimesh flips v on export
    idx = np.arange((rings + 1) * (segments + 1)).reshape(rings + 1, segments + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    mesh = trimesh.Trimesh(n.reshape(-1, 3) * radius + center, faces, vertex_normals=n.reshape(-1, 3), process=False)
    return mesh, uv.reshape(-1, 2)


def write_asset(path: pathlib.Path, segments: int) -> None:
    """The GLB: "Uniform" icosphere, "Painted" latitude-longitude sphere, "Plain" ground quad."""
    import trimesh
    pbr = trimesh.visual.material.PBRMaterial
    (c0, r0), (c1, r1) = SPHERES["Uniform"], SPHERES["Painted"]
    ico = trimesh.creation.icosphere(subdivisions=4, radius=r0)
    ico.apply_translation(c0)
    ico.visual = trimesh.visual.TextureVisuals(uv=np.zeros((len(ico.vertices), 2)),
                                               material=pbr(name="Uniform", baseColorFactor=[200, 60, 40, 255]))
    ball, uv = lat_long_sphere(np.array(c1), r1, segments)
    ball.visual = trimesh.visual.TextureVisuals(uv=uv, material=pbr(name="Painted", baseColorFactor=[255] * 4))
    s = GROUND_SIZE / 2
    ground = trimesh.Trimesh([[-s, GROUND_Y, s], [s, GROUND_Y, s], [s, GROUND_Y, -s], [-s, GROUND_Y, -s]],
                             [[0, 1, 2], [0, 2, 3]], vertex_normals=[[0, 1, 0]] * 4, process=False)
    ground.visual = trimesh.visual.TextureVisuals(
        uv=[[0, 0], [1, 0], [1, 1], [0, 1]],
        material=pbr(name="Plain", baseColorFactor=[90, 140, 200, 255], metallicFactor=0.0, roughnessFactor=0.5))
    trimesh.Scene({"uniform": ico, "painted": ball, "plain": ground}).export(path)


def scene_dict(asset: pathlib.Path, folder: pathlib.Path, model: pathlib.Path, width: int, height: int) -> dict:
    return {"camera": {**CAMERA, "width": width, "height": height},
            "environment": {"type": "constant", "radiance": [0, 0, 0]}, "lights": [POINT, SUN],
            "objects": [{"type": "gltf", "file": str(asset),
                         "bind": {"Uniform": f"{model}#{UNIFORM_MATERIAL}", "Painted": str(folder)}}],
            "max_depth": 1, "spp": 1, "threads": 1}


def surfaces(width: int, height: int):
    """Per pixel centre (float64 pinhole rays, render/camera.hpp): object id (0 none, 1 Uniform,
    2 Painted, 3 Plain), hit point, normal of the exact sphere or plane the mesh approximates."""
    pos, look, up = (np.array(CAMERA[k], float) for k in ("position", "look_at", "up"))
    forward = unit(look - pos)
    right = unit(np.cross(forward, up))
    up = np.cross(right, forward)
    th = np.tan(np.radians(CAMERA["fov_deg"]) / 2)
    px, py = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    d = unit(forward + right * ((2 * px / width - 1) * th * width / height)[..., None]
             + up * ((1 - 2 * py / height) * th)[..., None])
    best, ids = np.full(px.shape, np.inf), np.zeros(px.shape, int)
    for k, (c, r) in enumerate(SPHERES.values(), start=1):
        oc = pos - np.array(c)
        bq = d @ oc
        disc = bq * bq - (oc @ oc - r * r)
        t = np.where(disc > 0, -bq - np.sqrt(np.maximum(disc, 0)), np.inf)
        ids, best = np.where(t < best, k, ids), np.minimum(t, best)
    t = (GROUND_Y - pos[1]) / d[..., 1]
    hit = pos + t[..., None] * d
    inside = (t > 0) & (np.abs(hit[..., 0]) <= GROUND_SIZE / 2) & (np.abs(hit[..., 2]) <= GROUND_SIZE / 2)
    t = np.where(inside, t, np.inf)
    ids, best = np.where(t < best, 3, ids), np.minimum(t, best)
    p = pos + np.where(np.isfinite(best), best, 0)[..., None] * d
    n = np.broadcast_to(np.array([0.0, 1.0, 0.0]), p.shape).copy()
    for k, (c, r) in enumerate(SPHERES.values(), start=1):
        n[ids == k] = (p[ids == k] - np.array(c)) / r
    return ids, p, -d, n


def lit_mask(width: int, height: int) -> np.ndarray:
    """The module docstring's mask of lit pixels."""
    ids, p, wo, n = surfaces(width, height)
    tilt = np.arctan(np.hypot(*NORMAL_AMPLITUDE) / np.sqrt(1 - np.hypot(*NORMAL_AMPLITUDE) ** 2))
    near_map_horizon = np.sin(tilt + 0.05)
    keep, lit = ids > 0, np.zeros(ids.shape, bool)
    mapped = ids == 2
    keep &= ~(mapped & (np.abs((wo * n).sum(-1)) < near_map_horizon))
    for light in (POINT, SUN):
        wi = (unit(np.array(light["position"]) - p) if light["type"] == "point"
              else np.broadcast_to(unit(np.array(light["direction"], float)), p.shape))
        cos = (wi * n).sum(-1)
        keep &= np.abs(cos) >= 0.05
        keep &= ~(mapped & (np.abs(cos) < near_map_horizon))
        lit |= cos > 0
    padded = np.pad(ids, 1, mode="edge")
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            keep &= padded[dy:dy + height, dx:dx + width] == ids
    return keep & lit


def compare(width: int = 320, height: int = 192, segments: int = 64, model=None, tool=None, lavapipe: bool = True,
            keep=None) -> dict:
    """Writes the scene into a temporary folder (or ``keep``), renders it both ways and returns the
    figures: mean, max and 99th-percentile relative error over the lit pixels, their count, and the
    NaN and negative pixel counts of each image."""
    from hybridbrdf.raster import draw_frame
    model = pathlib.Path(model or ROOT / "results" / "rgl54_fast.safetensors").resolve()
    with tempfile.TemporaryDirectory(prefix="raster_vs_tracer_") as tmp:
        folder = pathlib.Path(keep) if keep else pathlib.Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        painted = paint_folder(folder, model)
        write_asset(folder / "scene.glb", segments)
        scene = scene_dict(folder / "scene.glb", painted, model, width, height)
        (folder / "scene.json").write_text(json.dumps(scene, indent=1))
        stats = draw_frame(folder / "scene.json", folder / "raster.exr", lavapipe=lavapipe, tool=tool,
                           validation=lavapipe)
        raster = hybridbrdf.render.read_exr(folder / "raster.exr").astype(np.float64)
        traced = np.asarray(hybridbrdf.render.render({**scene, "pixel_jitter": False, "shadows": False,
                                                      "mip_lod": False})[0], np.float64)
    mask = lit_mask(width, height)
    err = (np.abs(raster - traced) / np.maximum(traced, 1e-3 * traced.max()))[mask]
    bad = {f"{name}_{kind}": int(test(img).any(-1).sum()) for name, img in (("raster", raster), ("tracer", traced))
           for kind, test in (("nan", np.isnan), ("negative", lambda a: a < 0))}
    return {"device": stats["device"], "size": f"{width}x{height}", "lit_pixels": int(mask.sum()),
            "covered_pixels": int((traced.max(-1) > 0).sum()), "mean_rel": float(err.mean()),
            "p99_rel": float(np.percentile(err, 99)), "max_rel": float(err.max()), **bad}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--width", type=int, default=320, help="frame width in pixels")
    ap.add_argument("--height", type=int, default=192, help="frame height in pixels")
    ap.add_argument("--segments", type=int, default=64, help="the painted sphere's segments around its axis")
    ap.add_argument("--model", default=None, help="the hybrid model (default results/rgl54_fast.safetensors)")
    ap.add_argument("--tool", default=None, help="the hbrdf_raster executable (default build/hbrdf_raster)")
    ap.add_argument("--device", choices=["lavapipe", "any"], default="lavapipe",
                    help="lavapipe (validation layer on) or the Vulkan loader's first device")
    ap.add_argument("--keep", default=None, help="a folder that keeps the scene, the folder and both images")
    args = ap.parse_args(argv)
    tool = args.tool or os.environ.get("HBRDF_RASTER") or ROOT / "build" / "hbrdf_raster"
    r = compare(args.width, args.height, args.segments, args.model, tool, args.device == "lavapipe", args.keep)
    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cpus; {r['device']}; {r['size']}")
    print(f"lit pixels {r['lit_pixels']} of {r['covered_pixels']} covered")
    print(f"relative error over lit pixels: mean {r['mean_rel']:.3g}, p99 {r['p99_rel']:.3g}, max {r['max_rel']:.3g}"
          f" (target: mean <= 0.01)")
    print(f"NaN pixels: raster {r['raster_nan']}, tracer {r['tracer_nan']}; negative: raster {r['raster_negative']},"
          f" tracer {r['tracer_negative']}")
    return 0 if r["mean_rel"] <= 0.01 and not any(r[k] for k in r if k.endswith(("_nan", "_negative"))) else 1


if __name__ == "__main__":
    sys.exit(main())
