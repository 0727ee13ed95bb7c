#!/usr/bin/env python3
"""The new-measurement hold-out: the five raw RGL files, **each added alone**
with ``hybridbrdf.add``'s defaults, to a prior that never saw them in any form
(``bench/train_prior.py --leave-out NAME`` for each of the five), scored with the CONVENTIONS
metrics next to the authors' released model (trained on them) and this project's joint fit
(results/rgl54_hybrid_32x2_e09_120k_refit01, also trained on them). f_a's metrics beside the
hybrid's, and the seconds per material from the call to the written file.

    python bench/prior_heldout.py --prior out/prior_minus5/prior.safetensors [--keep-network]
        [--finetune-steps N] [--network-lr X] [--steps N] [--starts N] [--loss-eps EPS] [--pairs 1000000]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import tempfile
import time

import torch

import hybridbrdf as hb
from hybridbrdf.fit.settings import ADD_LOSS_EPS, ADD_STEPS, FitSettings
from hybridbrdf.evaluate.evaluation import evaluate

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
from rgl_paper_comparison import PAPER, print_verdicts  # noqa: E402

JOINT = ROOT / "results" / "rgl54_hybrid_32x2_e09_120k_refit01.safetensors"


def add_to(prior: str, src, out: str, settings: FitSettings, args) -> "hb.HybridModel":
    """``src`` added alone to ``prior`` as ``hbrdf add SRC --out OUT`` adds it to the shipped prior:
    a fine-tune unless --keep-network (the prior's own materials are not kept)."""
    from hybridbrdf.fit.adding import add

    return add([src], out=out, settings=settings, progress=False, keep_network=args.keep_network,
               finetune_steps=args.finetune_steps, prior=prior)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--prior", required=True, help="a prior trained without the five (bench/train_prior.py --leave-out)")
    ap.add_argument("--starts", type=int, default=1, help="FitSettings.sparse_starts (default: 1, the default)")
    ap.add_argument("--steps", type=int, default=ADD_STEPS)
    ap.add_argument("--pairs", type=int, default=1_000_000)
    ap.add_argument("--out", help="folder to keep the five models in (NAME.safetensors)")
    ap.add_argument("--keep-network", action="store_true", help="the sparse fit only (hbrdf add --keep-network)")
    ap.add_argument("--finetune-steps", type=int, default=None, help="the fine-tune's steps (default: FINETUNE_STEPS)")
    ap.add_argument("--network-lr", type=float, default=None, help="FitSettings.network_lr of the fine-tune")
    ap.add_argument("--finetune-lr", type=float, default=None, help="FitSettings.lr (default: the recipe's)")
    ap.add_argument("--loss-eps", type=float, default=None, help="FitSettings.loss_eps of both stages (default: hbrdf add's, ADD_LOSS_EPS)")
    ap.add_argument("--shared", default=str(ROOT.parent / "shared" / "data"))
    args = ap.parse_args()
    prior = hb.load_model(args.prior)
    seen = set(prior.materials) | {m.rsplit(".", 1)[0] for m in prior.materials}
    leaked = sorted(n for n in PAPER if n in seen)
    if leaked:
        ap.error(f"{args.prior} holds {', '.join(leaked)}: not a hold-out")
    raw = [hb.open_source(os.path.join(args.shared, "rgl", f"{n}.bsdf")) for n in PAPER]
    settings = FitSettings(steps=args.steps, sparse_starts=args.starts, loss_eps=ADD_LOSS_EPS)  # hbrdf add's defaults
    if args.network_lr is not None:
        settings.network_lr = args.network_lr
    if args.finetune_lr is not None:
        settings.lr = args.finetune_lr  # the sparse fit's too: FitSettings has one lr
    if args.loss_eps is not None:
        settings.loss_eps = args.loss_eps
    rows, seconds, models = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for n, src in zip(PAPER, raw):
            out = os.path.join(args.out or tmp, f"{n}.safetensors")
            t0 = time.perf_counter()
            added = add_to(args.prior, src, out, settings, args)
            seconds.append(time.perf_counter() - t0)
            rows += evaluate(added, [src], n_pairs=args.pairs, names=[n])
            models.append(added)
    joint = evaluate(hb.load_model(JOINT), raw, n_pairs=args.pairs, names=[f"{n}.rgl" for n in PAPER])
    t = prior.training
    print(f"prior {args.prior}: {prior.kind} {prior.arch['width']}x{prior.arch['depth']}, latent {prior.arch['latent']}, "
          f"{len(prior.materials)} materials, {t.get('steps')} steps x {t.get('batch')} pairs, loss eps {t.get('loss_eps')}, "
          f"expectile {t.get('analytic_expectile')}, specular {t.get('specular')}, weight decay {t.get('weight_decay')}")
    mode = "sparse fit only (--keep-network)" if args.keep_network else (
        f"fine-tune of {models[0].training.get('steps')} steps, network lr x {settings.network_lr}")
    print(f"added each raw RGL file alone with hybridbrdf.add ({args.steps} sparse steps, {args.starts} start(s), "
          f"{mode}): {sum(seconds) / len(seconds):.0f} s per material on average, at most {max(seconds):.0f} s "
          f"(call to written file, pool evaluation included; torch threads {torch.get_num_threads()})")
    print(f"metrics on {args.pairs} pairs, seed 7, negatives clamped; released = authors' model, joint = {JOINT.name}")
    print(f"{'material':24s} {'SMAPE':>8s} {'released':>8s} {'joint':>7s} {'cMAE':>9s} {'released':>9s} {'joint':>8s} "
          f"{'SMAPE(a)':>8s} {'cMAE(a)':>8s}  verdict (both metrics vs released)")
    joint_of = dict(zip(PAPER, joint))
    wins = print_verdicts(rows, PAPER, lambda name, row, ref: (
        f"{name[:24]:24s} {row['smape']:8.4f} {ref[0]:8.4f} {joint_of[name]['smape']:7.4f} {row['cmae']:9.5f} "
        f"{ref[2]:9.5f} {joint_of[name]['cmae']:8.5f} {row['smape_analytic']:8.4f} {row['cmae_analytic']:8.5f}"))
    cmae_wins = sum(row["cmae"] < ref[2] for row, ref in zip(rows, PAPER.values()))
    mean = sum(r["cmae"] for r in rows) / len(rows)
    mean_joint = sum(r["cmae"] for r in joint) / len(joint)
    print(f"beats the released model on both metrics for {wins} of 5, on cMAE for {cmae_wins} of 5; "
          f"mean cMAE {mean:.5f} = {mean / mean_joint:.2f} x the joint fit's {mean_joint:.5f}; mean SMAPE "
          f"{sum(r['smape'] for r in rows) / len(rows):.4f}; f_a mean SMAPE "
          f"{sum(r['smape_analytic'] for r in rows) / len(rows):.4f}, cMAE "
          f"{sum(r['cmae_analytic'] for r in rows) / len(rows):.5f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
