#!/usr/bin/env python3
"""Cost of a raster frame (hbrdf raster, docs/RASTER.md "Cost"): ms per 1280x720 frame for f_a only and
for the hybrid materials of one or more models, on the same scene, as ratios from one run.

    python bench/raster_frame.py [--models results/rgl54_hybrid_32x2.safetensors results/rgl54_fast.safetensors]
                                 [--material paper_white_rgb.rgl] [--repeat 3] [--rounds 3] [--lights 2]
                                 [--forms per-pixel] [--width 1280 --height 720] [--sphere-segments 256]
                                 [--tool build/hbrdf_raster] [--device lavapipe|any] [--svbrdf DIR...]

The scene: a sphere (radius 1) on a plane (size 6) filling most of the frame, both of the model's
material, lit by --lights lights (1: one point; 2: a point and a directional; 4: two of each), one
BRDF evaluation per covered pixel and light. "f_a only" draws the same material with "evaluate":
"analytic" (the first model's f_a: the generated hbrdf_eval_analytic, no network). Each hybrid row is
drawn in each of --forms: "generic" (hbrdf_eval per light, the generated code's generic form) and
"per-pixel" (hbrdf_pixel once per pixel, hbrdf_eval_pixel per light: the latent and wo terms of the
first layer, and the energy scale at wo.z, shared by the lights). --svbrdf adds a row per light count
for each textured folder given (hbrdf paint) on both objects: its maps through samplers, every texel's layers of
positive weight evaluated; the row names the maps' formats (a KTX2 folder's as stored, uploaded as such), and a
last table gives each folder's frame against the first folder's (e.g. a PNG folder and the same material
painted with --format ktx2).

Timing: each row is drawn --rounds times, the rows interleaved round by round (so that the machine's
load falls on all of them alike), each time the best of --repeat frames after one warm-up (host
clock around submit + wait, the device's timestamps, and the process's CPU time: on lavapipe the
frame's work, whatever else the machine runs); a row's figure is its best over the rounds, its ratio
to the f_a row of the same light count. Shaders are generated and compiled for each draw, outside
the timing. The machine and driver are printed with the table.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import sys
import tempfile

import hybridbrdf
from hybridbrdf.raster import draw_frame

ROOT = pathlib.Path(__file__).resolve().parents[1]

#: The lights of the scene in the order --lights takes them: 1 = the point, 2 = + the directional, 4 = + one more of each.
LIGHTS = [{"type": "point", "position": [1.5, 2.5, 2.0], "intensity": [6, 5, 4]},
          {"type": "directional", "direction": [-0.5, 1, 0.3], "irradiance": [0.8, 0.9, 1.0]},
          {"type": "point", "position": [-2.0, 1.5, 1.0], "intensity": [3, 4, 5]},
          {"type": "directional", "direction": [0.6, 0.8, -0.4], "irradiance": [0.5, 0.4, 0.3]}]


def scene(model: str, material: str, evaluate: str, width: int, height: int, lights: int = 2) -> dict:
    mat = ({"type": "textured", "svbrdf": os.path.abspath(model)} if evaluate == "textured" else
           {"type": "model", "file": os.path.abspath(model), "material": material, "evaluate": evaluate})
    return {"camera": {"position": [0.0, 0.9, 3.4], "look_at": [0, -0.2, 0], "up": [0, 1, 0], "fov_deg": 45,
                       "width": width, "height": height},
            "environment": {"type": "constant", "radiance": [0, 0, 0]},
            "lights": LIGHTS[:lights],
            "materials": {"m": mat},
            "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"},
                        {"type": "plane", "center": [0, -1, 0], "normal": [0, 1, 0], "size": 6, "material": "m"}],
            "max_depth": 1}


def arch(model: str) -> str:
    a = hybridbrdf.load_model(model).arch
    return f"{a['width']}x{a['depth']}"


def map_formats(folder: str) -> str:
    """The folder's name and its maps' storage: "png", "exr", or each KTX2 map's format."""
    from hybridbrdf.svbrdf.ktx2 import read_ktx2
    index = json.loads((pathlib.Path(folder) / "svbrdf.json").read_text())
    names = []
    for entry in index["maps"]:
        ext = os.path.splitext(entry["file"])[1].lower()
        if ext == ".ktx2":
            names.append(f"{entry['quantity']} {read_ktx2(os.path.join(folder, entry['file'])).name.removesuffix('_BLOCK')}")
        elif ext[1:] not in names:
            names.append(ext[1:])
    levels = index.get("levels", 1)
    return f"{os.path.basename(os.path.abspath(folder))}: {', '.join(names)}; {levels} level(s)"


def rows_of(args, models) -> list:
    """(label, model, evaluate, lights, per_pixel) of every row: for each light count f_a first, then the
    hybrid rows in each form, then the textured folder's."""
    rows = []
    for lights in args.lights:
        rows.append((f"f_a only, {lights} light(s)", models[0], "analytic", lights, False))
        for m in models:
            for form in args.forms:
                rows.append((f"hybrid {arch(m)} ({os.path.basename(m)}), {form}, {lights} light(s)", m, "full", lights,
                             form == "per-pixel"))
        for folder in args.svbrdf or []:
            rows.append((f"textured ({map_formats(folder)}), {lights} light(s)", folder, "textured", lights, True))
    return rows


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", nargs="+", default=[str(ROOT / "results/rgl54_hybrid_32x2.safetensors"),
                                                    str(ROOT / "results/rgl54_fast.safetensors")])
    ap.add_argument("--material", default="paper_white_rgb.rgl")
    ap.add_argument("--repeat", type=int, default=3, help="frames timed per draw, after one warm-up (best taken)")
    ap.add_argument("--rounds", type=int, default=3, help="draws of every row, interleaved (best taken)")
    ap.add_argument("--lights", type=int, nargs="+", choices=[1, 2, 4], default=[2],
                    help="light counts to measure (1: a point; 2: and a directional; 4: two of each)")
    ap.add_argument("--forms", nargs="+", choices=["generic", "per-pixel"], default=["per-pixel"],
                    help="the hybrid rows' shader forms: generic (hbrdf_eval per light) and/or per-pixel "
                         "(hbrdf_pixel per pixel, hbrdf_eval_pixel per light; what hbrdf raster draws)")
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--sphere-segments", type=int, default=256)
    ap.add_argument("--tool", default=os.environ.get("HBRDF_RASTER", str(ROOT / "build" / "hbrdf_raster")))
    ap.add_argument("--device", choices=["lavapipe", "any"], default="lavapipe",
                    help="lavapipe: pin Mesa's CPU driver; any: the Vulkan loader's choice (a GPU first)")
    ap.add_argument("--svbrdf", nargs="+", help="textured materials' folders (hbrdf paint): one more row each per light count")
    return ap.parse_args(argv)


def main() -> int:
    args = parse_args()
    models = [m for m in args.models if os.path.exists(m)]
    rows = rows_of(args, models)
    best = {}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.rounds):
            for label, model, evaluate, lights, per_pixel in rows:
                path = pathlib.Path(tmp) / "scene.json"
                path.write_text(json.dumps(scene(model, args.material, evaluate, args.width, args.height, lights)))
                stats = draw_frame(path, pathlib.Path(tmp) / "frame.exr", repeat=args.repeat,
                                   sphere_segments=args.sphere_segments, lavapipe=args.device == "lavapipe",
                                   tool=args.tool, per_pixel=per_pixel)
                kept = best.setdefault(label, dict(stats))
                for key in ("best_ms", "best_cpu_ms", "best_gpu_ms"):
                    if key in stats:
                        kept[key] = min(kept[key], stats[key])
    first = best[rows[0][0]]
    print(f"{args.width}x{args.height}, {int(first['triangles'])} triangles, material {args.material}; {first['device']}; "
          f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"LP_NUM_THREADS={os.environ.get('LP_NUM_THREADS', 'unset')}; best of {args.repeat} frames x {args.rounds} rounds")
    print(f"{'frame':72s} {'host ms':>8s} {'device ms':>9s} {'CPU ms':>8s} {'x f_a (host)':>12s} {'x f_a (CPU)':>11s}")
    for label, _, evaluate, lights, _ in rows:
        s, base = best[label], best[f"f_a only, {lights} light(s)"]
        gpu = s.get("best_gpu_ms", float("nan"))
        print(f"{label:72s} {s['best_ms']:8.1f} {gpu:9.1f} {s['best_cpu_ms']:8.1f} "
              f"{s['best_ms'] / base['best_ms']:12.2f} {s['best_cpu_ms'] / base['best_cpu_ms']:11.2f}")
    for lights in args.lights if args.svbrdf and len(args.svbrdf) > 1 else []:
        textured = [label for label, _, evaluate, n, _ in rows if evaluate == "textured" and n == lights]
        first = best[textured[0]]
        for label in textured[1:]:
            s = best[label]
            print(f"{label} / the first folder's frame: host {s['best_ms'] / first['best_ms']:.2f}x, "
                  f"CPU {s['best_cpu_ms'] / first['best_cpu_ms']:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
