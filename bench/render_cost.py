#!/usr/bin/env python3
"""The cost table at render level: frame time of the tracer's example scene
(scenes/sphere_env.json) against its render MAE, for each representation of the five raw
RGL measurements: the analytic part alone, the hybrid models (the released model's
architecture and the fast one), and the measurement itself and its NBRDF network through
the Python readers.

The sphere's material is each RGL measurement in turn; every render uses the cosine
sampler with next-event estimation and the same seed, so all renders of a material trace
the same directions and their difference is mostly the BRDF (docs/RENDERING.md,
"Rendering error"). The reference is the raw measurement at the same spp and seed; the
noise level is the MAE between two reference renders with different seeds. MAE: mean
over the pixels of the objects and RGB of |image - reference| (linear HDR). Frame time:
wall seconds of ``hybridbrdf.render.tracer.render`` on all cores, best of ``--runs``; rows marked
"python" evaluate their BRDF through a Python reader (a GIL round trip per batch) and are
not the cost a C++ or GPU renderer would pay.

    python bench/render_cost.py [--models results/rgl54_hybrid_32x2_e09_120k_refit01.safetensors,...]
        [--spp 16] [--runs 2]
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

import numpy as np

import hybridbrdf as hb
from hybridbrdf.sources.names import source_material
from hybridbrdf.render.tracer import render

ROOT = pathlib.Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
NAMES = ("cc_ibiza_sunset_rgb", "cg_sunflower_rgb", "colodur_napoli_4f_rgb", "paper_white_rgb", "vch_golden_yellow_rgb")
MODELS = ("results/rgl54_hybrid_32x2_e09_120k_refit01.safetensors,results/rgl54_hybrid_16x2_e09_100k_refit01.safetensors,"
          "results/rgl54_fast.safetensors")


def example_scene(material, spp, seed):
    scene = json.loads((ROOT / "scenes" / "sphere_env.json").read_text())
    scene.pop("description", None)
    scene["materials"]["paper"] = material
    scene.update(spp=spp, seed=seed, sampler="cosine")
    return scene


def timed(scene, runs):
    best, image = float("inf"), None
    for _ in range(runs):
        image, stats = render(scene)
        best = min(best, stats["seconds"])
    return image, best


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", default=MODELS, help=f"comma-separated hybrid model files (default {MODELS})")
    ap.add_argument("--spp", type=int, default=16, help="samples per pixel (the example scene's 16)")
    ap.add_argument("--runs", type=int, default=2, help="renders per row, the fastest counts (default 2)")
    args = ap.parse_args()
    models = [str(ROOT / p) for p in args.models.split(",") if p and (ROOT / p).exists()]
    rows = {}  # label -> list of (mae, seconds) per material

    def add(label, mae, seconds):
        rows.setdefault(label, []).append((mae, seconds))

    noise = []
    for name in NAMES:
        measured = {"type": "measured", "source": str(DATA / "rgl" / f"{name}.bsdf")}
        ref, t_ref = timed(example_scene(measured, args.spp, 1), args.runs)
        ref2, _ = timed(example_scene(measured, args.spp, 2), 1)
        mask = render(example_scene(measured, 1, 1), max_depth=0)[0].sum(-1) == 0
        mae = lambda img: float(np.abs(img[mask] - ref[mask]).mean())  # noqa: E731
        noise.append(mae(ref2))
        add("measured, raw RGL file (python; the reference)", 0.0, t_ref)
        nbrdf = {"type": "measured", "source": str(DATA / "nbrdf" / "rgl" / f"{name}.h5")}
        img, t = timed(example_scene(nbrdf, args.spp, 1), args.runs)
        add("NBRDF network, one per material (python)", mae(img), t)
        for path in models:
            model = hb.load_model(path)
            mat = source_material(model, hb.open_source(str(DATA / "rgl" / f"{name}.bsdf")))
            tag = f"{model.arch['width']}x{model.arch['depth']} {pathlib.Path(path).stem}"
            for evaluate, label in (("full", f"hybrid {tag}"), ("analytic", f"f_a of {tag}")):
                img, t = timed(example_scene({"type": "model", "file": path, "material": mat, "evaluate": evaluate},
                                             args.spp, 1), args.runs)
                add(label, mae(img), t)
        print(f"{name} done", file=sys.stderr, flush=True)

    print(f"example scene (scenes/sphere_env.json), sphere material = each raw RGL measurement, {args.spp} spp, "
          f"cosine sampling + NEE, same seed; noise level (two reference seeds) MAE {np.mean(noise):.5f}")
    print(f"{'representation':60s} {'render MAE':>10s} {'frame s':>8s}")
    for label, vals in rows.items():
        print(f"{label:60s} {np.mean([v[0] for v in vals]):10.5f} {np.mean([v[1] for v in vals]):8.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
