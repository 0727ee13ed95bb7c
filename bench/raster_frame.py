#!/usr/bin/env python3
"""Cost of a raster frame (hbrdf raster, docs/RASTER.md): ms per 1280x720 frame for f_a only and for
the hybrid materials of one or more models, on the same scene, as ratios from one run.

    python bench/raster_frame.py [--models results/rgl54_hybrid_32x2.safetensors results/rgl54_fast.safetensors]
                                 [--material paper_white_rgb.rgl] [--repeat 3] [--width 1280 --height 720]
                                 [--sphere-segments 256] [--tool build/hbrdf_raster] [--device lavapipe|any]
                                 [--svbrdf DIR]

The scene: a sphere (radius 1) on a plane (size 6) filling most of the frame, both of the model's
material, lit by one point and one directional light (two BRDF evaluations per covered pixel).
"f_a only" draws the same material with "evaluate": "analytic" (the first model's f_a: the
generated hbrdf_eval_analytic, no network). --svbrdf adds a row for a textured folder (hbrdf paint)
on both objects: its maps through samplers, every texel's layers of positive weight evaluated. Each row is the best of --repeat frames after one
warm-up (host clock around submit + wait, the device's timestamps, and the process's CPU time: on
lavapipe the frame's work, whatever else the machine runs), shaders generated and
compiled once per row outside the timing. The machine and driver are printed with the table.
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


def scene(model: str, material: str, evaluate: str, width: int, height: int) -> dict:
    mat = ({"type": "textured", "svbrdf": os.path.abspath(model)} if evaluate == "textured" else
           {"type": "model", "file": os.path.abspath(model), "material": material, "evaluate": evaluate})
    return {"camera": {"position": [0.0, 0.9, 3.4], "look_at": [0, -0.2, 0], "up": [0, 1, 0], "fov_deg": 45,
                       "width": width, "height": height},
            "environment": {"type": "constant", "radiance": [0, 0, 0]},
            "lights": [{"type": "point", "position": [1.5, 2.5, 2.0], "intensity": [6, 5, 4]},
                       {"type": "directional", "direction": [-0.5, 1, 0.3], "irradiance": [0.8, 0.9, 1.0]}],
            "materials": {"m": mat},
            "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"},
                        {"type": "plane", "center": [0, -1, 0], "normal": [0, 1, 0], "size": 6, "material": "m"}],
            "max_depth": 1}


def arch(model: str) -> str:
    a = hybridbrdf.load_model(model).arch
    return f"{a['width']}x{a['depth']}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", nargs="+", default=[str(ROOT / "results/rgl54_hybrid_32x2.safetensors"),
                                                    str(ROOT / "results/rgl54_fast.safetensors")])
    ap.add_argument("--material", default="paper_white_rgb.rgl")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--sphere-segments", type=int, default=256)
    ap.add_argument("--tool", default=os.environ.get("HBRDF_RASTER", str(ROOT / "build" / "hbrdf_raster")))
    ap.add_argument("--device", choices=["lavapipe", "any"], default="lavapipe",
                    help="lavapipe: pin Mesa's CPU driver; any: the Vulkan loader's choice (a GPU first)")
    ap.add_argument("--svbrdf", help="a textured material's folder (hbrdf paint) for one more row")
    args = ap.parse_args()
    models = [m for m in args.models if os.path.exists(m)]
    rows = [("f_a only", models[0], "analytic")] + [
        (f"hybrid {arch(m)} "
         f"({os.path.basename(m)})", m, "full") for m in models]
    if args.svbrdf:
        rows.append((f"textured ({os.path.basename(os.path.abspath(args.svbrdf))})", args.svbrdf, "textured"))
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for label, model, evaluate in rows:
            path = pathlib.Path(tmp) / "scene.json"
            path.write_text(json.dumps(scene(model, args.material, evaluate, args.width, args.height)))
            stats = draw_frame(path, pathlib.Path(tmp) / "frame.exr", repeat=args.repeat,
                               sphere_segments=args.sphere_segments, lavapipe=args.device == "lavapipe",
                               tool=args.tool)
            results.append((label, stats))
    device = results[0][1]["device"]
    print(f"{args.width}x{args.height}, {int(results[0][1]['triangles'])} triangles, 2 lights, material "
          f"{args.material}; {device}; {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"LP_NUM_THREADS={os.environ.get('LP_NUM_THREADS', 'unset')}; best of {args.repeat} frames")
    base = results[0][1]
    print(f"{'frame':44s} {'host ms':>8s} {'device ms':>9s} {'CPU ms':>8s} {'x f_a (host)':>12s} {'x f_a (CPU)':>11s}")
    for label, s in results:
        gpu = s.get("best_gpu_ms", float("nan"))
        print(f"{label:44s} {s['best_ms']:8.1f} {gpu:9.1f} {s['best_cpu_ms']:8.1f} "
              f"{s['best_ms'] / base['best_ms']:12.2f} {s['best_cpu_ms'] / base['best_cpu_ms']:11.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
