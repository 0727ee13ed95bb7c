#!/usr/bin/env python3
"""Training throughput of joint fitting: direction pairs x materials per second.

Fits M materials (LambertGGXDielectric, the synthetic source that is exactly f_a,
with random parameters: the reference values do not change the cost of a step)
for a fixed number of steps at each MLP size and prints pairs x materials / s
measured over the optimisation loop only (the pool evaluation and the final
metrics are excluded). Uses all cores torch is
given (``--threads``, default: all). With ``--compile`` each size is also fitted
with compiled steps (``fit(..., compile_step=True)``, ``hbrdf fit --compile``) in
the same run, and the speed-up and the one-time compilation are printed.

    python bench/bench_training.py [--materials 50] [--steps 200] [--batch 1024] [--sizes 16x3,32x3,64x3]
                                   [--archs hybrid,neural] [--threads N] [--compile]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys

import numpy as np
import torch

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))

from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.fit import fit
from hybridbrdf.fit.settings import parse_mlp
from hybridbrdf.sources.synthetic import LambertGGXDielectric  # noqa: E402
from bench_analytic import cpu_name  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--materials", type=int, default=50)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--batch", type=int, default=1024)
    ap.add_argument("--sizes", default="16x3,32x3,64x3")
    ap.add_argument("--archs", default="hybrid,neural")
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    ap.add_argument("--compile", action="store_true", help="also time compiled steps (torch.compile) at each size")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    rng = np.random.default_rng(0)
    sources = []
    for i in range(args.materials):
        kd, eta, alpha = rng.random(3), 1 + 3 * rng.random(), 0.05 + 0.9 * rng.random()
        sources.append(LambertGGXDielectric(f"m{i}", kd=kd, eta=eta, alpha_x=alpha, alpha_y=alpha))
    print(f"machine: {cpu_name()}, {args.threads} torch threads, torch {torch.__version__}; "
          f"{args.materials} materials, batch {args.batch}, {args.steps} steps per size")
    header = f"{'arch':8s} {'MLP':6s} {'latent':>6s} {'ms/step':>8s} {'pairs x materials / s':>22s}"
    if args.compile:
        header += f" {'compiled ms/step':>16s} {'pairs x materials / s':>22s} {'speed-up':>8s} {'compile s':>9s}"
    print(header)
    for arch in args.archs.split(","):
        for size in args.sizes.split(","):
            width, depth = parse_mlp(size)
            latent = 12 if arch == "neural" else 4
            s = FitSettings(arch=arch, width=width, depth=depth, latent=latent, steps=args.steps, batch=args.batch,
                            pool=1 << 14, eval_pairs=1000)
            rate = fit(sources, s, progress=False).training["pairs_x_materials_per_second"]
            ms = 1000 * args.batch * args.materials / rate
            line = f"{arch:8s} {size:6s} {latent:6d} {ms:8.1f} {rate:22,.0f}"
            if args.compile:
                t = fit(sources, s, progress=False, compile_step=True).training
                c_rate = t["pairs_x_materials_per_second"]  # over the steps after the compiling one
                c_ms = 1000 * args.batch * args.materials / c_rate
                line += f" {c_ms:16.1f} {c_rate:22,.0f} {c_rate / rate:7.2f}x {t['compile_seconds']:9.0f}"
            print(line, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
