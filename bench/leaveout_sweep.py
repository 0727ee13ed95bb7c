#!/usr/bin/env python3
"""Leave-out sweep (issue 49): NBRDF-RGL materials **each added alone** with ``hybridbrdf.add``'s
defaults to a prior that never saw any RGL material in any form
(results/prior88_merl_nielsen_32x2_l8_heads_20k.safetensors: 80 MERL + 8 Nielsen, the shipped
prior's recipe), scored with the CONVENTIONS metrics against the material's own f_a and against the
shipped prior's fit of the same material (trained jointly WITH it: the bar of a joint fit).

    python bench/leaveout_sweep.py [--prior FILE] [--count 24] [--materials A,B] [--loss-eps EPS] [--steps N]
        [--finetune-steps N] [--pairs 100000]
        [--shared ../shared/data] [--out ROWS.jsonl]

The materials are every other one of the 49 NBRDF-RGL reconstructions in sorted order (24 by
default; --count 49 takes all). Per material: SMAPE and cMAE of the hybrid, of its f_a and of the
shipped prior's fit, the guard's action (hybridbrdf.fit.guard), and the seconds from the call to
the model in memory (one process, torch threads as set by OMP_NUM_THREADS / torch defaults).
"at least as good as f_a" is strict (hybrid <= f_a); "within margin" is the table's margin
(hybridbrdf.fit.guard.is_worse).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import time

import torch

import hybridbrdf as hb
from hybridbrdf.evaluate.evaluation import evaluate
from hybridbrdf.fit.adding import add
from hybridbrdf.fit.guard import is_worse
from hybridbrdf.fit.settings import ADD_LOSS_EPS, ADD_STEPS, FINETUNE_STEPS, FitSettings
from hybridbrdf.model.prior import prior_path

ROOT = pathlib.Path(__file__).resolve().parents[1]
PRIOR88 = ROOT / "results" / "prior88_merl_nielsen_32x2_l8_heads_20k.safetensors"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--prior", default=str(PRIOR88), help="a prior that never saw the materials (default: %(default)s)")
    ap.add_argument("--count", type=int, default=24, help="materials in the sweep (every other NBRDF-RGL one)")
    ap.add_argument("--materials", help="only these NBRDF-RGL materials, comma-separated (default: the sweep's)")
    ap.add_argument("--loss-eps", type=float, default=None, help="FitSettings.loss_eps (default: hbrdf add's, ADD_LOSS_EPS)")
    ap.add_argument("--steps", type=int, default=None, help="sparse steps (default: hbrdf add's, ADD_STEPS)")
    ap.add_argument("--finetune-steps", type=int, default=None, help="fine-tune steps (default: hbrdf add's)")
    ap.add_argument("--pairs", type=int, default=100_000, help="metric pairs per material (CONVENTIONS: 10^5)")
    ap.add_argument("--shared", default=str(ROOT.parent / "shared" / "data"))
    ap.add_argument("--out", help="append one JSON line per material to this file; rows already in it (same "
                                  "loss eps) are kept and not fitted again")
    args = ap.parse_args()
    folder = pathlib.Path(args.shared) / "nbrdf" / "rgl"
    stems = sorted(p.stem for p in folder.glob("*.json"))
    stride = max(1, len(stems) // args.count) if args.count < len(stems) else 1
    stems = stems[::stride][:args.count]
    if args.materials:
        stems = [m.strip() for m in args.materials.split(",") if m.strip()]
    prior = hb.load_model(args.prior)
    seen = set(prior.materials) | {m.rsplit(".", 1)[0] for m in prior.materials}
    leaked = sorted(s for s in stems if s in seen)
    if leaked:
        ap.error(f"{args.prior} holds {', '.join(leaked)}: not a hold-out")
    joint = hb.load_model(prior_path())
    settings = FitSettings(steps=args.steps or ADD_STEPS, loss_eps=ADD_LOSS_EPS)  # hbrdf add's defaults
    if args.loss_eps is not None:
        settings.loss_eps = args.loss_eps
    print(f"prior {args.prior} ({len(prior.materials)} materials); {len(stems)} NBRDF-RGL materials, each added alone; "
          f"loss eps {settings.loss_eps}; {settings.steps} sparse + {args.finetune_steps or FINETUNE_STEPS} fine-tune steps; {args.pairs} metric pairs; torch threads {torch.get_num_threads()}", flush=True)
    print(f"{'material':28s} {'SMAPE':>7s} {'f_a':>7s} {'joint':>7s} {'cMAE':>8s} {'f_a':>8s} {'joint':>8s} "
          f"{'s':>5s}  guard", flush=True)
    rows = []
    if args.out and os.path.exists(args.out):  # a sweep resumed: its finished rows are kept
        with open(args.out) as fh:
            rows = [r for r in map(json.loads, fh) if r["loss_eps"] == settings.loss_eps and r["material"] in stems
                    and r.get("steps", ADD_STEPS) == settings.steps
                    and r.get("finetune_steps", FINETUNE_STEPS) == (args.finetune_steps or FINETUNE_STEPS)]
        for r in rows:
            print(f"{r['material'][:28]:28s} {r['smape']:7.4f} {r['smape_a']:7.4f} {r['smape_joint']:7.4f} {r['cmae']:8.5f} "
                  f"{r['cmae_a']:8.5f} {r['cmae_joint']:8.5f} {r['seconds']:5.0f}  {r['guard']}  (earlier run)")
    done = {r["material"] for r in rows}
    sink = open(args.out, "a") if args.out else None
    for stem in stems:
        if stem in done:
            continue
        src = hb.open_source(str(folder / f"{stem}.h5"))
        t0 = time.perf_counter()
        log = []
        model = add([src], settings=settings, progress=False, prior=args.prior, log=log.append,
                    finetune_steps=args.finetune_steps)
        seconds = time.perf_counter() - t0
        row = evaluate(model, [src], n_pairs=args.pairs, names=[model.materials[0]])[0]
        joint_name = stem if stem in joint.materials else f"{stem}.nbrdf"  # the raw file's twin is <stem>.rgl
        ref = evaluate(joint, [src], n_pairs=args.pairs, names=[joint_name])[0]
        guard = model.material_info[0].get("guard")
        action = guard.get("action") if isinstance(guard, dict) else "-"
        rec = dict(material=stem, smape=row["smape"], cmae=row["cmae"], smape_a=row["smape_analytic"],
                   cmae_a=row["cmae_analytic"], smape_joint=ref["smape"], cmae_joint=ref["cmae"],
                   seconds=seconds, guard=action, loss_eps=settings.loss_eps, steps=settings.steps,
                   finetune_steps=model.training.get("steps"))
        rows.append(rec)
        if sink:
            sink.write(json.dumps(rec) + "\n")
            sink.flush()
        print(f"{stem[:28]:28s} {rec['smape']:7.4f} {rec['smape_a']:7.4f} {rec['smape_joint']:7.4f} {rec['cmae']:8.5f} "
              f"{rec['cmae_a']:8.5f} {rec['cmae_joint']:8.5f} {seconds:5.0f}  {action}", flush=True)
    n = len(rows)
    strict = sum(r["smape"] <= r["smape_a"] and r["cmae"] <= r["cmae_a"] for r in rows)
    margin = sum(not is_worse({"smape": r["smape"], "smape_analytic": r["smape_a"], "cmae": r["cmae"],
                               "cmae_analytic": r["cmae_a"]}) for r in rows)
    beat_joint = sum(r["smape"] <= r["smape_joint"] and r["cmae"] <= r["cmae_joint"] for r in rows)

    def mean(key):
        return sum(r[key] for r in rows) / n

    print(f"at least as good as f_a on both metrics: {strict} of {n} strictly, {margin} of {n} within the table's margin")
    print(f"as good as the joint fit (shipped prior, trained with them) on both metrics: {beat_joint} of {n}")
    print(f"mean SMAPE {mean('smape'):.4f} (f_a {mean('smape_a'):.4f}, joint {mean('smape_joint'):.4f}); mean cMAE "
          f"{mean('cmae'):.5f} (f_a {mean('cmae_a'):.5f}, joint {mean('cmae_joint'):.5f})")
    print(f"seconds per material: mean {mean('seconds'):.1f}, max {max(r['seconds'] for r in rows):.1f}; guard actions: "
          + ", ".join(f"{a} {sum(r['guard'] == a for r in rows)}" for a in sorted({r['guard'] for r in rows})))
    return 0


if __name__ == "__main__":
    sys.exit(main())
