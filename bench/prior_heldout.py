#!/usr/bin/env python3
"""Issue 16's hold-out with the prior's recipe: the five raw RGL files added, with
``hybridbrdf.add``'s defaults only, to a prior that never saw them in any form
(``bench/train_prior.py --leave-out NAME`` for each of the five), scored with the CONVENTIONS
metrics next to the authors' released model (trained on them) and this project's joint fit
(results/rgl54_hybrid_32x2_e09_120k_refit01, also trained on them).

    python bench/prior_heldout.py --prior out/prior_minus5/prior.safetensors [--starts N] [--pairs 1000000]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import tempfile
import time

import hybridbrdf as hb
from hybridbrdf.fit_settings import ADD_STEPS, FitSettings
from hybridbrdf.fitting import evaluate

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
from rgl_paper_comparison import PAPER, verdict  # noqa: E402

JOINT = ROOT / "results" / "rgl54_hybrid_32x2_e09_120k_refit01.safetensors"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--prior", required=True, help="a prior trained without the five (bench/train_prior.py --leave-out)")
    ap.add_argument("--starts", type=int, default=1, help="FitSettings.sparse_starts (default: 1, the default)")
    ap.add_argument("--steps", type=int, default=ADD_STEPS)
    ap.add_argument("--pairs", type=int, default=1_000_000)
    ap.add_argument("--out", help="also keep the model of the five here")
    ap.add_argument("--shared", default=str(ROOT.parent / "shared" / "data"))
    args = ap.parse_args()
    prior = hb.load_model(args.prior)
    seen = set(prior.materials) | {m.rsplit(".", 1)[0] for m in prior.materials}
    leaked = sorted(n for n in PAPER if n in seen)
    if leaked:
        ap.error(f"{args.prior} holds {', '.join(leaked)}: not a hold-out")
    raw = [hb.open_source(os.path.join(args.shared, "rgl", f"{n}.bsdf")) for n in PAPER]
    settings = FitSettings(steps=args.steps, sparse_starts=args.starts)
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or os.path.join(tmp, "five.safetensors")
        t0 = time.perf_counter()
        # hb.add on a BASE keeps BASE's materials; the prior's own are not the point here: drop them.
        added = hb.add(raw, to=args.prior, out=out, settings=settings, progress=False)
        seconds = time.perf_counter() - t0
    rows = evaluate(added, raw, n_pairs=args.pairs, names=list(PAPER))
    joint = evaluate(hb.load_model(JOINT), raw, n_pairs=args.pairs, names=[f"{n}.rgl" for n in PAPER])
    t = prior.training
    print(f"prior {args.prior}: {prior.kind} {prior.arch['width']}x{prior.arch['depth']}, latent {prior.arch['latent']}, "
          f"{len(prior.materials)} materials, {t.get('steps')} steps x {t.get('batch')} pairs, loss eps {t.get('loss_eps')}, "
          f"expectile {t.get('analytic_expectile')}, specular {t.get('specular')}, weight decay {t.get('weight_decay')}")
    print(f"added the five raw RGL files with hybridbrdf.add defaults ({args.steps} steps, {args.starts} start(s)) "
          f"in {seconds:.0f} s ({seconds / len(raw):.0f} s per material, pool evaluation included)")
    print(f"metrics on {args.pairs} pairs, seed 7, negatives clamped; released = authors' model, joint = {JOINT.name}")
    print(f"{'material':24s} {'SMAPE':>8s} {'released':>8s} {'joint':>7s} {'cMAE':>9s} {'released':>9s} {'joint':>8s} "
          f"{'cMAE(a)':>8s}  verdict (both metrics vs released)")
    wins = cmae_wins = 0
    for row, j, name in zip(rows, joint, PAPER):
        ref = PAPER[name]
        ok = row["smape"] < ref[0] and row["cmae"] < ref[2]
        wins += ok
        cmae_wins += row["cmae"] < ref[2]
        print(f"{name[:24]:24s} {row['smape']:8.4f} {ref[0]:8.4f} {j['smape']:7.4f} {row['cmae']:9.5f} {ref[2]:9.5f} "
              f"{j['cmae']:8.5f} {row['cmae_analytic']:8.5f}  {verdict(ok)}")
    mean = sum(r["cmae"] for r in rows) / len(rows)
    mean_joint = sum(r["cmae"] for r in joint) / len(joint)
    print(f"beats the released model on both metrics for {wins} of 5, on cMAE for {cmae_wins} of 5; "
          f"mean cMAE {mean:.5f} = {mean / mean_joint:.2f} x the joint fit's {mean_joint:.5f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
