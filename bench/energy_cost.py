#!/usr/bin/env python3
"""What the energy bound costs in fidelity and time (docs/ENERGY.md): a model's materials with and
without their energy-bound tables, against their sources, by the CONVENTIONS metrics.

    python bench/energy_cost.py MODEL SOURCE... [--pairs 100000] [--out BOUNDED]

MODEL: a model file; bounded here (``hybridbrdf.model.energy.with_bound``, timed) when it has no
tables, else compared with its own f_t (``energy.unbounded``). SOURCE: files, folders or globs as
``hbrdf eval`` takes them; sources whose material the model does not hold are skipped. Prints the
seconds the tables took, mean SMAPE and cMAE of all matched materials without and with the bound,
the same for the dimmed materials only (the others are unchanged by construction: a table of ones),
one row per dimmed material, and for the five raw RGL rows of bench/rgl_paper_comparison.py the
verdict against the released model with the bound. ``--out``: write the bounded model there.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np

import hybridbrdf as hb
from hybridbrdf.evaluate.evaluation import evaluate
from hybridbrdf.model import energy
from hybridbrdf.sources import expand_sources, open_source
from hybridbrdf.sources.names import source_material

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
from rgl_paper_comparison import PAPER, beats_paper  # noqa: E402


def matched_sources(model, specs):
    out = []
    for path in expand_sources(specs):
        src = open_source(path)
        name = source_material(model, src)
        if name is not None:
            out.append((name, src))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model")
    ap.add_argument("sources", nargs="+")
    ap.add_argument("--pairs", type=int, default=100_000)
    ap.add_argument("--out", help="write the bounded model here")
    args = ap.parse_args()
    model = hb.load_model(args.model)
    seconds = None
    if model.arch.get("energy_bound", "none") == "none":
        t0 = time.time()
        bounded = energy.with_bound(model)
        seconds = time.time() - t0
        free = model
    else:
        bounded, free = model, energy.unbounded(model)
    if args.out:
        bounded = bounded.save_checked(args.out)
    pairs = matched_sources(bounded, args.sources)
    names = [n for n, _ in pairs]
    srcs = [s for _, s in pairs]
    rows_b = evaluate(bounded, srcs, n_pairs=args.pairs, names=names)
    rows_f = evaluate(free, srcs, n_pairs=args.pairs, names=names)
    table = bounded.tensors["materials.energy_bound"]
    dimmed = [i for i, n in enumerate(names) if table[bounded.index(n)].min() < 1.0]
    print(f"{args.model}: {len(bounded.materials)} materials, {len(names)} matched to sources, "
          f"{int((table.min(axis=1) < 1).sum())} dimmed by the bound"
          + (f"; tables fitted in {seconds:.1f} s" if seconds is not None else " (tables already in the file)"))

    def means(rows, idx):
        return (np.mean([rows[i]["smape"] for i in idx]), np.mean([rows[i]["cmae"] for i in idx])) if idx else (0, 0)

    for label, idx in (("all matched", list(range(len(names)))), ("dimmed", dimmed)):
        sf, cf = means(rows_f, idx)
        sb, cb = means(rows_b, idx)
        print(f"  {label:12s} ({len(idx):3d}): SMAPE {sf:.4f} -> {sb:.4f}, cMAE {cf:.5f} -> {cb:.5f} "
              f"(x{cb / cf if cf else float('nan'):.3f})")
    for i in dimmed:
        print(f"    {names[i]:32s} SMAPE {rows_f[i]['smape']:.4f} -> {rows_b[i]['smape']:.4f}  cMAE "
              f"{rows_f[i]['cmae']:.5f} -> {rows_b[i]['cmae']:.5f}  smallest factor {table[bounded.index(names[i])].min():.3f}")
    five = [(i, n.split(".")[0]) for i, n in enumerate(names) if n.split(".")[0] in PAPER and srcs[i].path
            and srcs[i].path.endswith(".bsdf")]
    if five:
        wins = sum(beats_paper(rows_b[i], PAPER[k]) for i, k in five)
        print(f"  the five raw RGL rows with the bound: {wins} of {len(five)} beat the released model on both metrics")
    return 0


if __name__ == "__main__":
    sys.exit(main())
