#!/usr/bin/env python3
"""Per-material SMAPE: analytic part vs hybrid vs fully neural baseline, fitted
on the same collection with the same MLP (the paper's Fig. 4 comparison).

Fits ``--arch hybrid`` (latent --latent) and ``--arch neural`` (latent
--latent + 8, the hybrid's per-material parameter count) and prints, per
material, SMAPE of the analytic part, the hybrid and the neural model, then
how often the hybrid beats its analytic part and the neural model. A CPU run on
a full collection takes hours: run it as a background job.

    python bench/compare_models.py SOURCE... [--mlp 32x3] [--latent 4] [--steps 20000] [--out-dir out/compare]
"""

from __future__ import annotations

import argparse
import os
import sys

import hybridbrdf as hb
from hybridbrdf.fitting import FitSettings, evaluate, fit, material_names
from hybridbrdf.models import parse_mlp


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sources", nargs="+")
    ap.add_argument("--mlp", default="32x3")
    ap.add_argument("--latent", type=int, default=4)
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--pairs", type=int, default=1_000_000)
    ap.add_argument("--loss-eps", type=float, default=1.0)
    ap.add_argument("--out-dir", default="out/compare")
    args = ap.parse_args()
    width, depth = parse_mlp(args.mlp)
    sources = [hb.open_source(s) for s in hb.expand_sources(args.sources)]
    names = material_names(sources)
    os.makedirs(args.out_dir, exist_ok=True)
    results = {}
    for arch, latent in (("hybrid", args.latent), ("neural", args.latent + 8)):
        path = os.path.join(args.out_dir, f"{arch}_{args.mlp}_l{latent}.safetensors")
        settings = FitSettings(arch=arch, width=width, depth=depth, latent=latent, steps=args.steps,
                               eval_pairs=1000, loss_eps=args.loss_eps, sources=list(args.sources))
        model = fit(sources, settings, progress=False)
        model.save(path)
        results[arch] = {r["material"]: r for r in evaluate(model, sources, n_pairs=args.pairs, names=names)}
        print(f"fitted {arch} {args.mlp} latent {latent}: {model.training['train_seconds']:.0f} s -> {path}", flush=True)
    print(f"{'material':32s} {'reference':30s} {'analytic':>9s} {'hybrid':>9s} {'neural':>9s}")
    beat_a = beat_n = 0
    for n, src in zip(names, sources):
        h, nn = results["hybrid"][n], results["neural"][n]
        beat_a += h["smape"] < h["smape_analytic"]
        beat_n += h["smape"] < nn["smape"]
        print(f"{n[:32]:32s} {src.origin[:30]:30s} {h['smape_analytic']:9.4f} {h['smape']:9.4f} {nn['smape']:9.4f}")
    total = len(names)
    print(f"hybrid beats its analytic part on {beat_a}/{total} materials and the neural baseline on {beat_n}/{total} "
          f"({100.0 * beat_n / total:.0f}%); {args.mlp}, {args.steps} steps, metrics on {args.pairs} pairs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
