#!/usr/bin/env python3
"""Importance sampling (paper Sec. 5.2): for a hybrid material on a sphere under the
procedural sky, the error of each BSDF-sampling strategy against a high-spp reference at
equal samples per pixel, and its time per sample, measured in one run.

Strategies: cosine; GGX visible normals of the analytic part; MIS of both (the paper's
choice, no network evaluation while sampling); the tabulated baseline (1 degree, in the spirit
of Lawrence et al. 2004; table memory and build time reported). The reference uses MIS at
``--ref-spp`` with another seed. Each strategy is rendered ``--runs`` times with different
seeds; the table gives the mean over runs of the image MAE (sphere pixels, RGB) against the
reference, and the mean time. Next-event estimation is off (``--nee`` turns it on) so that
the BSDF sampler alone carries the lighting, as in the paper's variance figure.

    python bench/render_sampling.py [--model results/rgl54_hybrid_32x3_10k.safetensors]
        [--material cc_ibiza_sunset_rgb.rgl] [--size 96] [--spp 16] [--ref-spp 1024] [--runs 3]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time

import numpy as np

from hybridbrdf.render.tracer import render

ROOT = pathlib.Path(__file__).resolve().parents[1]
THREADS = [0]  # set from --threads


def scene(model, material, size, spp, sampler, seed, nee):
    return {
        "camera": {"position": [0, 0, 3.2], "look_at": [0, 0, 0], "fov_deg": 40, "width": size, "height": size},
        "environment": {"type": "sky", "sun_elevation_deg": 40, "sun_azimuth_deg": 35, "turbidity": 3,
                        "sun_size_deg": 4},
        "materials": {"m": {"type": "model", "file": model, "material": material}},
        "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}],
        "spp": spp, "max_depth": 3, "sampler": sampler, "seed": seed, "threads": THREADS[0], "nee": nee,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", default=str(ROOT / "results" / "rgl54_hybrid_32x3_10k.safetensors"))
    ap.add_argument("--material", default="cc_ibiza_sunset_rgb.rgl")
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--ref-spp", type=int, default=1024)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--nee", action="store_true", help="keep next-event estimation on")
    ap.add_argument("--threads", type=int, default=0, help="render threads (default 0: all cores)")
    args = ap.parse_args()
    THREADS[0] = args.threads
    model = os.path.abspath(args.model)
    ref, rs = render(scene(model, args.material, args.size, args.ref_spp, "mis", 1000, args.nee))
    mask = render(scene(model, args.material, args.size, 1, "mis", 0, args.nee), max_depth=0)[0].sum(-1) == 0
    print(f"{args.material} ({args.model}), sphere under the procedural sky, {args.size}x{args.size}, max depth 3, "
          f"NEE {'on' if args.nee else 'off'}; reference: MIS at {args.ref_spp} spp ({rs['seconds']:.1f} s); "
          f"{args.spp} spp per strategy, {args.runs} seeds; {rs['threads']} threads")
    print(f"{'strategy':10s} {'MAE':>9s} {'rel. MAE':>9s} {'ns/sample':>10s} {'setup s':>8s} {'table memory':>13s}")
    rows = {}
    for sampler in ("cosine", "ggx", "mis", "tabulated"):
        maes, secs, setup = [], [], []
        stats = None
        for run in range(args.runs):
            t0 = time.perf_counter()
            img, stats = render(scene(model, args.material, args.size, args.spp, sampler, run + 1, args.nee))
            setup.append(time.perf_counter() - t0 - stats["seconds"])  # scene load (+ table build)
            maes.append(float(np.abs(img[mask] - ref[mask]).mean()))
            secs.append(stats["seconds"])
        mem = sum(stats["sampler_memory_bytes"].values()) if stats["sampler_memory_bytes"] else 0
        per_sample = np.mean(secs) / (args.size * args.size * args.spp) * 1e9
        rows[sampler] = (np.mean(maes), per_sample, np.mean(setup), mem)
    base = rows["mis"][0]
    for sampler, (mae, ns, setup, mem) in rows.items():
        memory = f"{mem / 2**20:.1f} MiB" if mem >= 2**20 else f"{mem} B"
        print(f"{sampler:10s} {mae:9.5f} {mae / base:9.2f} {ns:10.0f} {setup:8.2f} {memory:>13s}")
    print("ns/sample: render time per camera sample (a path of up to 3 bounces) over all threads; setup: scene "
          "load, including the table build for 'tabulated'; rel. MAE: relative to MIS")
    return 0


if __name__ == "__main__":
    sys.exit(main())
