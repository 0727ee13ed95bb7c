#!/usr/bin/env python3
"""Learning-rate sweep of the RGL 54 joint fit at a fixed, short step count.

Fits the 54 RGL materials (5 raw files + 49 NBRDF reconstructions) with the network and loss of
``results/rgl54_hybrid_32x2_e09_120k`` (hybrid 32x2, latent 4, loss eps 0.01, specular 0.1,
expectile 0.9), compiled, once per learning rate (cosine decay to 0 over ``--steps``), and prints
the mean SMAPE and cMAE over the 54 and the five raw rows' cMAE against the authors' released
model. A screening tool: its metrics use ``--eval-pairs`` (default 200,000) pairs, fewer than the
CONVENTIONS 10^6, which estimates the highlight-dominated rows' cMAE low; judge only the ranking.

    python bench/fit_lr_sweep.py [--steps 6000] [--lrs 0.005,0.01,0.02,0.04,0.08,0.16] [--threads 2]
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np
import torch

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))

import hybridbrdf as hb  # noqa: E402
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.fit import fit
from bench_analytic import cpu_name  # noqa: E402
from bench_fit_time import COMMON, DATA  # noqa: E402
from rgl_paper_comparison import PAPER  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=6000)
    ap.add_argument("--lrs", default="0.005,0.01,0.02,0.04,0.08,0.16")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--eval-pairs", type=int, default=200_000)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    sources = [hb.open_source(p) for p in hb.expand_sources([str(DATA / "rgl"), str(DATA / "nbrdf" / "rgl")])]
    print(f"machine: {cpu_name()}, {args.threads} torch threads; {len(sources)} RGL materials, {args.steps} steps, "
          f"metrics on {args.eval_pairs} pairs")
    print(f"{'lr':>7s} {'train s':>8s} {'SMAPE':>7s} {'cMAE':>8s}  " + " ".join(f"{n[:12]:>12s}" for n in PAPER))
    print(f"{'paper':>7s} {'':8s} {'':7s} {'':8s}  " + " ".join(f"{v[2]:12.5f}" for v in PAPER.values()))
    for lr in (float(x) for x in args.lrs.split(",")):
        settings = FitSettings(**COMMON, steps=args.steps, lr=lr, eval_pairs=args.eval_pairs)
        t = time.perf_counter()
        model = fit(sources, settings, progress=False, log=lambda msg: None, compile_step=True)
        rows = [m["metrics"] for m in model.material_info]
        five = [rows[model.materials.index(n if n in model.materials else f"{n}.rgl")]["cmae"] for n in PAPER]
        print(f"{lr:7.3g} {time.perf_counter() - t:8.0f} {np.mean([r['smape'] for r in rows]):7.4f} "
              f"{np.mean([r['cmae'] for r in rows]):8.5f}  " + " ".join(f"{c:12.5f}" for c in five), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
