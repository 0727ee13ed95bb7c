#!/usr/bin/env python3
"""Selective neural evaluation (paper Sec. 5.3) and thread scaling.

A hybrid sphere on a hybrid floor under the procedural sky, max depth 7: render time for
``neural_max_depth`` 0 (analytic part everywhere) .. 7 (network at every bounce), relative to
the analytic-only render, and the MAE against the full evaluation, all with the same seed
(same paths), measured in one run. Then the further rule ``neural_min_throughput`` (network
only while the path throughput is at least the threshold) at a few thresholds, and samples
per second with 1 and 2 threads.

    python bench/render_selective.py [--model results/rgl54_hybrid_32x3_10k.safetensors]
        [--sphere cc_ibiza_sunset_rgb.rgl] [--floor paper_white_rgb.rgl] [--size 128] [--spp 16]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys

import numpy as np

from hybridbrdf.render.tracer import render

ROOT = pathlib.Path(__file__).resolve().parents[1]


def scene(model, sphere, floor, size, spp):
    return {
        "camera": {"position": [0, 0.8, 4.0], "look_at": [0, -0.1, 0], "fov_deg": 38, "width": size, "height": size},
        "environment": {"type": "sky", "sun_elevation_deg": 35, "sun_azimuth_deg": 60, "turbidity": 3},
        "materials": {"sphere": {"type": "model", "file": model, "material": sphere},
                      "floor": {"type": "model", "file": model, "material": floor}},
        "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "sphere"},
                    {"type": "plane", "center": [0, -1, 0], "normal": [0, 1, 0], "size": 30, "material": "floor"}],
        "spp": spp, "max_depth": 7, "sampler": "mis", "seed": 3, "threads": 0,
    }


def best_of(n, fn):
    out = [fn() for _ in range(n)]
    return min(out, key=lambda r: r[1]["seconds"])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", default=str(ROOT / "results" / "rgl54_hybrid_32x3_10k.safetensors"))
    ap.add_argument("--sphere", default="cc_ibiza_sunset_rgb.rgl")
    ap.add_argument("--floor", default="paper_white_rgb.rgl")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--repeats", type=int, default=3, help="renders per setting; the fastest counts (default 3)")
    ap.add_argument("--threads", type=int, default=0, help="render threads (default 0: all cores)")
    args = ap.parse_args()
    sc = scene(os.path.abspath(args.model), args.sphere, args.floor, args.size, args.spp)
    sc["threads"] = args.threads
    full, fs = best_of(args.repeats, lambda: render(sc, neural_max_depth=7))
    analytic, an = best_of(args.repeats, lambda: render(sc, neural_max_depth=0))
    print(f"sphere {args.sphere} on floor {args.floor} ({args.model}), {args.size}x{args.size}, {args.spp} spp, "
          f"max depth 7, MIS sampling + NEE, {fs['threads']} threads, fastest of {args.repeats}")
    print(f"{'rule':28s} {'seconds':>8s} {'x analytic':>10s} {'network share':>13s} {'MAE vs full':>11s}")

    def row(label, img, st):
        share = st["network_evals"] / max(st["brdf_evals"], 1)
        print(f"{label:28s} {st['seconds']:8.2f} {st['seconds'] / an['seconds']:10.2f} {share:13.2f} "
              f"{float(np.abs(img - full).mean()):11.5f}", flush=True)

    row("neural_max_depth 0 (f_a)", analytic, an)
    for d in range(1, 7):
        img, st = best_of(args.repeats, lambda: render(sc, neural_max_depth=d))
        row(f"neural_max_depth {d}", img, st)
    row("neural_max_depth 7 (full)", full, fs)
    for t in (0.5, 0.2, 0.05):
        img, st = best_of(args.repeats, lambda: render(sc, neural_min_throughput=t))
        row(f"neural_min_throughput {t}", img, st)
    print()
    rates = {}
    for threads in (1, 2) if args.threads == 0 else ():
        _, st = best_of(args.repeats, lambda: render(sc, neural_max_depth=7, threads=threads))
        rates[threads] = st["samples_per_second"]
        print(f"{threads} thread(s): {st['samples_per_second'] / 1e3:8.1f} k samples/s (full network)")
    if rates:
        print(f"scaling 1 -> 2 threads: {rates[2] / rates[1]:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
