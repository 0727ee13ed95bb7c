#!/usr/bin/env python3
"""Sparse fitting on held-out measurements (paper Sec. 4.2, "Sparse Training").

1. Fit one network on a collection from ../shared/data *without* the held-out
   materials in any form (raw file and NBRDF reconstruction): --collection
   nbrdf-rgl (the 49 NBRDF-RGL networks), rgl (those and the five raw files: the
   joint fit's 54) or all (rgl, NBRDF-MERL and NBRDF-Nielsen: the shipped prior's
   collection). --leave-out NAME (repeatable; default: all five raw RGL files)
   picks the held-out materials; protocol (a) (one network per left-out file) runs it once
   per file with --collection rgl --leave-out NAME. --with-reconstructions keeps
   the held-out materials' reconstructions (then it is not a hold-out).
2. Freeze it and fit only (p, z) of the held-out raw RGL files.
3. Print their CONVENTIONS metrics next to the paper authors' released model
   (which saw all 62 RGL materials while training its network).

    python bench/sparse_heldout.py [--steps 20000] [--sparse-steps 5000] [--mlp 32x2] [--loss-eps 0.01] [--specular 0.1]
        [--analytic-expectile 0.9] [--sparse-init nearest|neutral] [--with-reconstructions] [--compile]
        [--checkpoint PATH] [--base-model MODEL] [--sparse-loss-eps E] [--sparse-lr LR] [--sparse-starts N]
        [--weight-decay W] [--seed S] [--collection nbrdf-rgl|rgl|all] [--leave-out NAME]...

--base-model skips step 1 and freezes an existing network; the sparse fit's loss then comes
from the flags given here, not from that network's recorded training settings.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys

import hybridbrdf as hb
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.evaluate.evaluation import evaluate
from hybridbrdf.fit import fit
from hybridbrdf.fit.settings import parse_mlp

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
from model_metrics import collection_means  # noqa: E402
from rgl_paper_comparison import PAPER, print_verdicts  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--sparse-steps", type=int, default=5000)
    ap.add_argument("--mlp", default="32x2")
    ap.add_argument("--loss-eps", type=float, default=0.01)
    ap.add_argument("--specular", type=float, default=0.0,
                    help="fraction of specular training pairs (FitSettings.specular), both fits")
    ap.add_argument("--analytic-expectile", type=float, default=0.5,
                    help="expectile tau of the analytic loss term (FitSettings.analytic_expectile), both fits")
    ap.add_argument("--weight-decay", type=float, default=FitSettings.weight_decay,
                    help="AdamW weight decay of the network fit (FitSettings.weight_decay)")
    ap.add_argument("--seed", type=int, default=FitSettings.seed,
                    help="seed of the network fit (initialisation and pairs); the sparse fit keeps the default")
    ap.add_argument("--sparse-init", default="nearest", choices=("nearest", "neutral"),
                    help="where the sparse fit starts each file's (p, z) (FitSettings.sparse_init)")
    ap.add_argument("--sparse-loss-eps", type=float, default=None,
                    help="loss epsilon of the sparse fit (default: --loss-eps); docs/ADDING.md, 'Re-balancing'")
    ap.add_argument("--sparse-starts", type=int, default=1,
                    help="starts per file of the sparse fit (FitSettings.sparse_starts; default 1)")
    ap.add_argument("--sparse-lr", type=float, default=FitSettings.lr,
                    help="learning rate of the sparse fit (default: FitSettings.lr)")
    ap.add_argument("--compile", action="store_true", help="torch.compile the training steps of both fits")
    ap.add_argument("--checkpoint", help="checkpoint file of the network fit (resumed if it exists)")
    ap.add_argument("--base-model", help="freeze this network instead of fitting one (skips step 1)")
    ap.add_argument("--with-reconstructions", action="store_true",
                    help="train the network on all 49 NBRDF-RGL networks, including the reconstructions of the "
                         "five files (the raw measurements are still added only by sparse fitting)")
    ap.add_argument("--collection", default="nbrdf-rgl", choices=("nbrdf-rgl", "rgl", "all"),
                    help="the network's collection before the held-out materials are removed (see above)")
    ap.add_argument("--leave-out", action="append", choices=sorted(PAPER), metavar="NAME",
                    help="a held-out raw RGL file (repeatable; default: all five)")
    ap.add_argument("--pairs", type=int, default=1_000_000)
    ap.add_argument("--shared", default=str(ROOT.parent / "shared" / "data"))
    ap.add_argument("--out-dir", default="out/sparse")
    args = ap.parse_args()
    width, depth = parse_mlp(args.mlp)
    left_out = [n for n in PAPER if n in set(args.leave_out or PAPER)]
    held_out = set() if args.with_reconstructions else set(left_out)
    folders = {"nbrdf-rgl": ["nbrdf/rgl"], "rgl": ["rgl", "nbrdf/rgl"],
               "all": ["rgl", "nbrdf/rgl", "nbrdf/merl", "nbrdf/nielsen"]}[args.collection]
    # A held-out raw file never trains the network; its reconstruction only with --with-reconstructions.
    base_specs = [p for p in hb.expand_sources([os.path.join(args.shared, f) for f in folders])
                  if pathlib.Path(p).stem not in (set(left_out) if p.endswith(".bsdf") else held_out)]
    base = [hb.open_source(p) for p in base_specs]
    raw = [hb.open_source(os.path.join(args.shared, "rgl", f"{n}.bsdf")) for n in left_out]
    os.makedirs(args.out_dir, exist_ok=True)
    common = dict(width=width, depth=depth, latent=4, loss_eps=args.loss_eps, specular=args.specular,
                  analytic_expectile=args.analytic_expectile, eval_pairs=10_000)
    if args.base_model:
        net_path = args.base_model
        print(f"network: {net_path} (given)", flush=True)
    else:
        net = fit(base, FitSettings(steps=args.steps, sources=base_specs, weight_decay=args.weight_decay,
                                    seed=args.seed, **common),
                  progress=False,
                  checkpoint=args.checkpoint, resume=args.checkpoint is not None, compile_step=args.compile)
        net_path = os.path.join(args.out_dir, f"base{len(base)}_{args.mlp}.safetensors")
        net.save(net_path)
        print(f"network: {len(base)} materials of {args.collection} (held out: {', '.join(sorted(held_out)) or 'none'}), "
              f"{args.mlp}, {args.steps} steps, seed {args.seed}, {net.training['train_seconds']:.0f} s -> {net_path}", flush=True)
    frozen = hb.load_model(net_path)
    print(f"network's own fit (its eval pairs): {collection_means(frozen)}", flush=True)
    sparse_settings = dict(common, loss_eps=args.loss_eps if args.sparse_loss_eps is None else args.sparse_loss_eps)
    sparse = fit(raw, FitSettings(steps=args.sparse_steps, sources=[s.path for s in raw], frozen_from=net_path,
                                  sparse_init=args.sparse_init, sparse_starts=args.sparse_starts, lr=args.sparse_lr,
                                  **sparse_settings),
                 frozen=frozen, progress=False, compile_step=args.compile)
    sparse_path = os.path.join(args.out_dir, f"sparse_rgl{len(raw)}_{args.mlp}_{args.sparse_init}.safetensors")
    sparse.save(sparse_path)
    rows = evaluate(sparse, raw, n_pairs=args.pairs)
    # The start's cMAE (nearest start): how far the frozen network's best (p, z) was off before the
    # sparse fit moved it; a fit that ends near its start is bounded by the network.
    starts = [m.get("sparse_start", {}).get("material") for m in sparse.material_info]
    start_cmae = ([r["cmae"] for r in evaluate(frozen, raw, n_pairs=args.pairs, names=starts)]
                  if all(starts) else [float("nan")] * len(raw))
    print(f"sparse fit of the {len(raw)} raw RGL file(s) on the frozen network: {args.sparse_steps} steps, "
          f"start {args.sparse_init}, loss eps {sparse_settings['loss_eps']}, lr {args.sparse_lr} -> {sparse_path}")
    print(f"metrics on {args.pairs} pairs, seed 7, negatives clamped; paper = authors' released model")
    print(f"{'material':24s} {'SMAPE':>8s} {'paper':>7s} {'cMAE':>9s} {'paper':>8s} {'SMAPE(a)':>9s} "
          f"{'cMAE(a)':>9s} {'cMAE(start)':>11s}  verdict")
    start_of = dict(zip(left_out, start_cmae))
    wins = print_verdicts(rows, left_out, lambda name, row, ref: (
        f"{name[:24]:24s} {row['smape']:8.4f} {ref[0]:7.4f} {row['cmae']:9.5f} {ref[2]:8.5f} "
        f"{row['smape_analytic']:9.4f} {row['cmae_analytic']:9.5f} {start_of[name]:11.5f}"))
    print(f"sparse-fitted hybrid beats the released model on both metrics for {wins} of {len(left_out)} materials")
    return 0


if __name__ == "__main__":
    sys.exit(main())
