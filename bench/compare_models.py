#!/usr/bin/env python3
"""Per-material SMAPE: analytic part vs hybrid vs fully neural baseline, fitted
on the same collection with the same MLP (the paper's Fig. 4 comparison).

For every ``--mlp`` size, fits ``--arch hybrid`` (latent --latent) and
``--arch neural`` (latent --latent + 8, the hybrid's per-material parameter
count) and prints, per material, SMAPE and cMAE of the analytic part, the hybrid
and the neural model, then how often the hybrid beats its analytic part and the
neural model. Fitted models go to ``--out-dir`` and are reused when present
(delete them to refit), and each fit checkpoints every 1000 steps, so an
interrupted campaign resumes where it stopped (``--only`` fits one of the two,
for running them as parallel jobs);
each table is also written to ``<out-dir>/compare_<mlp>.txt``. A CPU run on a
full collection takes hours: run it as a background job.

    python bench/compare_models.py SOURCE... [--mlp 16x3,32x3] [--latent 4] [--steps 10000]
        [--loss-eps 0.01] [--loss-eps-relative] [--loss-no-cos] [--analytic-loss-eps E] [--analytic-expectile 0.5]
        [--specular 0]
        [--only hybrid|neural] [--threads 1] [--out-dir out/compare]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import torch

import hybridbrdf as hb
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.evaluate.evaluation import evaluate
from hybridbrdf.fit import fit
from hybridbrdf.sources.names import material_names
from hybridbrdf.fit.settings import parse_mlp


def fitted_model(sources, args, arch: str, mlp: str, latent: int) -> hb.HybridModel:
    """Fit (or reload) one model of the campaign."""
    path = os.path.join(args.out_dir, f"{arch}_{mlp}_l{latent}.safetensors")
    if os.path.exists(path):
        model = hb.load_model(path)
        print(f"reusing {path} ({model.training['steps']} steps)", flush=True)
        return model
    width, depth = parse_mlp(mlp)
    settings = FitSettings(arch=arch, width=width, depth=depth, latent=latent, steps=args.steps,
                           eval_pairs=1000, loss_eps=args.loss_eps, loss_eps_relative=args.loss_eps_relative,
                           analytic_loss_eps=args.analytic_loss_eps, loss_cos=not args.loss_no_cos,
                           analytic_expectile=args.analytic_expectile, specular=args.specular, seed=args.seed,
                           sources=list(args.sources))
    t0 = time.perf_counter()
    checkpoint = path + ".ckpt"  # an interrupted fit continues from its last checkpoint
    model = fit(sources, settings, progress=False, checkpoint=checkpoint, checkpoint_every=1000, resume=True)
    model.save(path)
    if os.path.exists(checkpoint):
        os.remove(checkpoint)
    print(f"fitted {arch} {mlp} latent {latent}: {args.steps} steps in {time.perf_counter() - t0:.0f} s -> {path}",
          flush=True)
    return model


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sources", nargs="+", help="files, folders or globs (formats may be mixed)")
    ap.add_argument("--mlp", default="32x3", help="comma-separated MLP sizes WIDTHxDEPTH (default 32x3)")
    ap.add_argument("--latent", type=int, default=4, help="hybrid latent size; the neural model gets latent + 8")
    ap.add_argument("--steps", type=int, default=10000, help="optimiser steps per fit (default 10000)")
    ap.add_argument("--pairs", type=int, default=1_000_000, help="metric pairs per material (default 10^6)")
    ap.add_argument("--loss-eps", type=float, default=0.01, help="loss epsilon for both models (default 0.01)")
    ap.add_argument("--loss-eps-relative", action="store_true",
                    help="per-material loss epsilon, --loss-eps times the material's mean cos f (both models)")
    ap.add_argument("--loss-no-cos", action="store_true",
                    help="fit log(eps + f) instead of log(eps + cos f) (FitSettings.loss_cos = False; both models)")
    ap.add_argument("--analytic-loss-eps", type=float, default=None,
                    help="epsilon of the hybrid's analytic loss term (FitSettings.analytic_loss_eps; default --loss-eps)")
    ap.add_argument("--analytic-expectile", type=float, default=0.5,
                    help="expectile of the hybrid's analytic loss term (FitSettings.analytic_expectile; default 0.5)")
    ap.add_argument("--specular", type=float, default=0.0,
                    help="fraction of specular training pairs for both models (FitSettings.specular; default 0)")
    ap.add_argument("--only", choices=("hybrid", "neural"),
                    help="fit only this model and stop (run the two as parallel jobs, then once more for the table)")
    ap.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    ap.add_argument("--threads", type=int, default=0, help="torch CPU threads (default: torch's choice)")
    ap.add_argument("--out-dir", default="out/compare", help="where models and tables go (default out/compare)")
    args = ap.parse_args()
    if args.threads > 0:
        torch.set_num_threads(args.threads)
    sources = [hb.open_source(s) for s in hb.expand_sources(args.sources)]
    names = material_names(sources)
    os.makedirs(args.out_dir, exist_ok=True)
    for mlp in args.mlp.split(","):
        results, steps = {}, {}
        if args.only:
            fitted_model(sources, args, args.only, mlp, args.latent + (8 if args.only == "neural" else 0))
            continue
        for arch, latent in (("hybrid", args.latent), ("neural", args.latent + 8)):
            model = fitted_model(sources, args, arch, mlp, latent)
            steps[arch] = model.training["steps"]
            results[arch] = {r["material"]: r for r in evaluate(model, sources, n_pairs=args.pairs, names=names)}
        lines = [f"# {mlp}: hybrid latent {args.latent} ({steps['hybrid']} steps) vs neural latent "
                 f"{args.latent + 8} ({steps['neural']} steps), loss eps {args.loss_eps}"
                 f"{(' x mean f' if args.loss_no_cos else ' x mean cos f') + ' per material' if args.loss_eps_relative else ''}"
                 f"{f', analytic term eps {args.analytic_loss_eps}' if args.analytic_loss_eps else ''}"
                 f"{f', specular {args.specular}' if args.specular else ''}"
                 f"{', loss without cos' if args.loss_no_cos else ''}"
                 f"{f', analytic expectile {args.analytic_expectile}' if args.analytic_expectile != 0.5 else ''}, "
                 f"metrics on {args.pairs} pairs (seed 7)",
                 f"{'material':36s} {'SMAPE analytic':>14s} {'hybrid':>9s} {'neural':>9s} "
                 f"{'cMAE analytic':>13s} {'hybrid':>9s} {'neural':>9s}"]
        beat_a = beat_n = 0
        for n in names:
            h, nn = results["hybrid"][n], results["neural"][n]
            beat_a += h["smape"] < h["smape_analytic"]
            beat_n += h["smape"] < nn["smape"]
            lines.append(f"{n[:36]:36s} {h['smape_analytic']:14.4f} {h['smape']:9.4f} {nn['smape']:9.4f} "
                         f"{h['cmae_analytic']:13.5f} {h['cmae']:9.5f} {nn['cmae']:9.5f}")
        total = len(names)
        mean = lambda key, arch: sum(r[key] for r in results[arch].values()) / total  # noqa: E731
        lines.append(f"{'mean':36s} {mean('smape_analytic', 'hybrid'):14.4f} {mean('smape', 'hybrid'):9.4f} "
                     f"{mean('smape', 'neural'):9.4f} {mean('cmae_analytic', 'hybrid'):13.5f} "
                     f"{mean('cmae', 'hybrid'):9.5f} {mean('cmae', 'neural'):9.5f}")
        lines.append(f"hybrid {mlp} beats its analytic part on {beat_a}/{total} materials and the neural baseline "
                     f"on {beat_n}/{total} ({100.0 * beat_n / total:.0f}%) on SMAPE")
        text = "\n".join(lines) + "\n"
        print(text, flush=True)
        with open(os.path.join(args.out_dir, f"compare_{mlp}.txt"), "w") as fh:
            fh.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
