#!/usr/bin/env python3
"""The example scene with a textured object (issue 48; docs/SVBRDF.md, docs/RENDERING.md).

Paints a 512x512 textured material from `results/rgl54_fast.safetensors` (paper_white as the
base, vch_golden_yellow in a soft disc, the metallic paint ilm_l3_37_metallic in soft stripes on
top: bench/svbrdf_mixture.py's masks) into OUT/painted with `hbrdf paint`'s Python API, writes
OUT/textured.json (a textured sphere and a textured tile over an analytic floor, under the sky; the masks
rolled by a quarter turn so that the disc faces the camera)
and renders it with the tracer to OUT/textured.exr and the PNG (default OUT/textured_scene.png; pass
--png docs/figures/textured_scene.png to refresh the docs' figure, which a plain run leaves alone).

    python bench/textured_scene.py [--out out/textured_example] [--png docs/figures/textured_scene.png]
        [--spp 64] [--width 320] [--height 200]
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import time

import numpy as np
from PIL import Image

from hybridbrdf.fit import paint
from hybridbrdf.render.tracer import render

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
from svbrdf_mixture import LAYERS, masks  # noqa: E402


def write_masks(out: str) -> list:
    """bench/svbrdf_mixture.py's masks as OUT/mask1.png, mask2.png (8-bit grey), rolled by a quarter
    turn so that the disc is at u = 0.63, on the sphere's side the camera sees; their paths."""
    paths = []
    for k, m in enumerate(masks(), start=1):
        m = np.roll(m, m.shape[1] // 4, axis=1)
        p = os.path.join(out, f"mask{k}.png")
        Image.fromarray(np.rint(m * 255).astype(np.uint8), "L").save(p)
        paths.append(p)
    return paths


def example_scene(material: dict, width: int, height: int, spp: int) -> dict:
    """The example scene with `material` on a sphere and a tile, over an analytic floor, under the sky."""
    return {
        "camera": {"position": [0, 1.2, 4.6], "look_at": [0, -0.1, 0], "fov_deg": 34, "width": width, "height": height},
        "environment": {"type": "sky", "sun_elevation_deg": 35, "sun_azimuth_deg": 60},
        "materials": {
            "textured": material,
            "floor": {"type": "analytic", "kd": 0.35, "eta": 1.5, "alpha": 0.5},
        },
        "objects": [
            {"type": "sphere", "center": [-0.9, 0, 0], "radius": 1, "material": "textured"},
            {"type": "plane", "center": [1.35, -0.2, 0.2], "normal": [-0.25, 0.35, 1], "tangent": [1, 0, 0.25],
             "size": 1.6, "material": "textured"},
            {"type": "plane", "center": [0, -1, 0], "normal": [0, 1, 0], "size": 20, "material": "floor"},
        ],
        "spp": spp, "max_depth": 4, "sampler": "mis", "seed": 0, "threads": 0,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", default=str(ROOT / "results" / "rgl54_fast.safetensors"))
    ap.add_argument("--out", default=str(ROOT / "out" / "textured_example"))
    ap.add_argument("--png", help="the PNG to write (default: OUT/textured_scene.png)")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=200)
    args = ap.parse_args()
    args.png = args.png or os.path.join(args.out, "textured_scene.png")
    os.makedirs(args.out, exist_ok=True)
    paths = write_masks(args.out)
    t0 = time.perf_counter()
    names = [n for n, _ in LAYERS]
    paint(args.model, names[0], list(zip(names[1:], paths)), os.path.join(args.out, "painted"))
    painted = time.perf_counter() - t0
    scene = example_scene({"type": "textured", "svbrdf": "painted"}, args.width, args.height, args.spp)
    scene_path = os.path.join(args.out, "textured.json")
    with open(scene_path, "w") as fh:
        json.dump(scene, fh, indent=1)
    os.makedirs(os.path.dirname(os.path.abspath(args.png)), exist_ok=True)
    _, stats = render(scene_path, out=os.path.join(args.out, "textured.exr"), png=args.png, quiet=True, tonemap="aces",
                      exposure=-0.5)
    print(f"painted {args.out}/painted in {painted:.1f} s (512x512, layers {', '.join(names)}); rendered {scene_path} "
          f"({args.width}x{args.height}, {args.spp} spp) in {stats['seconds']:.1f} s: {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
