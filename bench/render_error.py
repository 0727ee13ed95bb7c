#!/usr/bin/env python3
"""Rendering error (paper Sec. 4.1): a sphere under the procedural sky rendered with each
material's measured BRDF (the reference) and with the analytic part, the hybrid and the
neural baseline fitted to it; MAE and PSNR of each against the reference.

All renders of one material use the same seed and the cosine sampler (plus next-event
estimation toward the sky), so every render traces the same directions and the difference
between images is mostly the BRDF (the noise that remains scales with the BRDF error); the
table also states the noise level (MAE between two reference renders with different seeds).
MAE: mean over the sphere's pixels and RGB of |image - reference| on the linear HDR images;
PSNR: on the displayed images (linear clipped to [0, 1], then the sRGB curve), peak 1.

    python bench/render_error.py --hybrid out/compare_rgl/hybrid_32x3_l4.safetensors \\
        --neural out/compare_rgl/neural_32x3_l12.safetensors SOURCE... [--size 128] [--spp 64]

A SOURCE is a measured file (or synthetic:NAME) whose material is in both models (matched by
name, with or without the .rgl/.nbrdf suffix the fitter adds).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

import hybridbrdf as hb
from hybridbrdf.sources.names import format_tag, source_material
from hybridbrdf.render.tracer import render


def scene(material, size, spp, seed):
    return {
        "camera": {"position": [0, 0, 3.2], "look_at": [0, 0, 0], "fov_deg": 40, "width": size, "height": size},
        "environment": {"type": "sky", "sun_elevation_deg": 40, "sun_azimuth_deg": 35, "turbidity": 3},
        "materials": {"m": material},
        "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}],
        "spp": spp, "max_depth": 3, "sampler": "cosine", "seed": seed, "threads": 0,
    }


def srgb(x):
    """The sRGB transfer curve (IEC 61966-2-1) of linear values in [0, 1]."""
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def model_name(model, src):
    name = source_material(model, src)
    if name is None:
        raise KeyError(f"{src.name} is not in {model.path}")
    return name


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sources", nargs="+", help="measured files / synthetic:NAME (the references)")
    ap.add_argument("--hybrid", required=True, help="hybrid model file containing the materials")
    ap.add_argument("--neural", required=True, help="neural-baseline model file containing the materials")
    ap.add_argument("--size", type=int, default=128, help="image width = height (default 128)")
    ap.add_argument("--spp", type=int, default=64, help="samples per pixel (default 64)")
    args = ap.parse_args()
    hyb, neu = hb.load_model(args.hybrid), hb.load_model(args.neural)
    print(f"sphere under the procedural sky, {args.size}x{args.size}, {args.spp} spp, cosine sampling + NEE, "
          f"max depth 3, same seed for all renders of a material")
    print(f"hybrid: {args.hybrid}; neural: {args.neural}")
    print(f"{'material':30s} {'reference':8s} {'noise MAE':>9s} | {'MAE analytic':>12s} {'hybrid':>8s} {'neural':>8s} | "
          f"{'PSNR analytic':>13s} {'hybrid':>7s} {'neural':>7s}")
    totals = {"analytic": [], "hybrid": [], "neural": []}
    wins = 0
    for path in hb.expand_sources(args.sources):
        src = hb.open_source(path)
        measured = {"type": "measured", "source": str(path)}
        ref, _ = render(scene(measured, args.size, args.spp, 1))
        ref2, _ = render(scene(measured, args.size, args.spp, 2))
        mask = render(scene(measured, args.size, 1, 1), max_depth=0)[0].sum(-1) == 0  # the sphere's pixels
        shown = lambda img: srgb(np.clip(img[mask], 0.0, 1.0))  # noqa: E731
        h, n = model_name(hyb, src), model_name(neu, src)
        imgs = {"analytic": render(scene({"type": "model", "file": args.hybrid, "material": h, "evaluate": "analytic"},
                                         args.size, args.spp, 1))[0],
                "hybrid": render(scene({"type": "model", "file": args.hybrid, "material": h}, args.size, args.spp, 1))[0],
                "neural": render(scene({"type": "model", "file": args.neural, "material": n}, args.size, args.spp, 1))[0]}
        mae = {k: float(np.abs(v[mask] - ref[mask]).mean()) for k, v in imgs.items()}
        psnr = {k: float(-10 * np.log10(np.mean((shown(v) - shown(ref)) ** 2))) for k, v in imgs.items()}
        noise = float(np.abs(ref2[mask] - ref[mask]).mean())
        for k in totals:
            totals[k].append(mae[k])
        wins += mae["hybrid"] < mae["neural"]
        print(f"{src.name[:30]:30s} {format_tag(src):8s} {noise:9.5f} | {mae['analytic']:12.5f} {mae['hybrid']:8.5f} "
              f"{mae['neural']:8.5f} | {psnr['analytic']:13.2f} {psnr['hybrid']:7.2f} {psnr['neural']:7.2f}", flush=True)
    k = len(totals["hybrid"])
    print(f"{'mean':30s} {'':8s} {'':9s} | {np.mean(totals['analytic']):12.5f} {np.mean(totals['hybrid']):8.5f} "
          f"{np.mean(totals['neural']):8.5f} |")
    print(f"hybrid render MAE below the neural baseline's on {wins}/{k} materials, below its analytic part's on "
          f"{sum(a > b for a, b in zip(totals['analytic'], totals['hybrid']))}/{k}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
