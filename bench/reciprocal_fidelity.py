#!/usr/bin/env python3
"""How much of a reciprocal model's error is the reference's own non-reciprocity (issue 60).

A reciprocal BRDF f(wi, wo) = f(wo, wi) cannot follow a measurement that is not: on the pairs
where the reference's two directions disagree it must pick one value for both. The closest
reciprocal function to a reference f_ref in the L2 sense is its symmetric part
f_sym(wi, wo) = (f_ref(wi, wo) + f_ref(wo, wi)) / 2, so scoring against f_sym measures what a
reciprocal model *could* reach, and scoring against f_ref what it costs against the measurement.

For each model (a non-reciprocal one and a reciprocal one, fitted to the same sources by the same
recipe) and each source, on the CONVENTIONS metric pairs (cosine-weighted, seed 7):

    recip ref     SMAPE between f_ref(wi, wo) and f_ref(wo, wi): how non-reciprocal the reference is
    ref           SMAPE / cMAE against the measurement (what ``hbrdf eval`` prints)
    sym           SMAPE / cMAE against the reference's symmetric part

and the means over all sources, over those whose reference is nearly reciprocal
(recip ref <= --reciprocal-bound), and with several source arguments over each one's sources.

    python bench/reciprocal_fidelity.py results/rgl54_fast.safetensors \
        results/rgl54_fast_reciprocal.safetensors ../shared/data/nbrdf/rgl [--pairs 200000]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import torch

from hybridbrdf.evaluate.metrics import cmae, metric_directions, smape
from hybridbrdf.model.file import load_model
from hybridbrdf.sources import expand_sources, open_source
from hybridbrdf.sources.names import source_material


def score(model, name, wi, wo, ref, ref_sym):
    f, _ = model._eval(wi, wo, name, torch.float32)
    return (smape(ref, f), cmae(ref, f, wi[:, 2]), smape(ref_sym, f), cmae(ref_sym, f, wi[:, 2]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("plain", help="the non-reciprocal model")
    ap.add_argument("reciprocal", help="the reciprocal model fitted to the same sources")
    ap.add_argument("sources", nargs="+", help="BRDF files or folders (matched by material name)")
    ap.add_argument("--pairs", type=int, default=200_000, help="metric pairs per source (default 200,000)")
    ap.add_argument("--reciprocal-bound", type=float, default=0.2,
                    help="the 'nearly reciprocal reference' subset: recip ref at most this (default 0.2)")
    args = ap.parse_args(argv)

    models = [load_model(args.plain), load_model(args.reciprocal)]
    wi, wo = metric_directions(args.pairs)
    rows = []
    print(f"{'material':30s} {'recip ref':>9s}   {'plain: ref SMAPE':>16s} {'cMAE':>8s} {'sym SMAPE':>9s} "
          f"{'cMAE':>8s}   {'recip: ref SMAPE':>16s} {'cMAE':>8s} {'sym SMAPE':>9s} {'cMAE':>8s}")
    for group, src in ((arg, open_source(s)) for arg in args.sources for s in expand_sources([arg])):
        names = [source_material(m, src) for m in models]
        if None in names:
            print(f"{src.name}: not in both models, skipped", file=sys.stderr)
            continue
        ref = src.eval(wi, wo)
        ref_swapped = src.eval(wo, wi)
        ref_sym = 0.5 * (np.maximum(ref, 0.0) + np.maximum(ref_swapped, 0.0))
        recip_ref = smape(ref, ref_swapped)
        a = score(models[0], names[0], wi, wo, ref, ref_sym)
        b = score(models[1], names[1], wi, wo, ref, ref_sym)
        rows.append((recip_ref, a, b, group))
        print(f"{names[0]:30s} {recip_ref:9.4f}   {a[0]:16.4f} {a[1]:8.5f} {a[2]:9.4f} {a[3]:8.5f}   "
              f"{b[0]:16.4f} {b[1]:8.5f} {b[2]:9.4f} {b[3]:8.5f}")
    if not rows:
        print("no source is in both models", file=sys.stderr)
        return 1
    groups = list(dict.fromkeys(r[3] for r in rows)) if len(args.sources) > 1 else []
    for label, keep in (("all", lambda r: True),
                        (f"recip ref <= {args.reciprocal_bound}", lambda r: r[0] <= args.reciprocal_bound),
                        *((g, lambda r, g=g: r[3] == g) for g in groups)):
        sel = [r for r in rows if keep(r)]
        if not sel:
            continue
        a = np.mean([r[1] for r in sel], axis=0)
        b = np.mean([r[2] for r in sel], axis=0)
        print(f"mean over {len(sel)} ({label}): reciprocal / plain  ref SMAPE {b[0] / a[0]:.3f}x  "
              f"ref cMAE {b[1] / a[1]:.3f}x  sym SMAPE {b[2] / a[2]:.3f}x  sym cMAE {b[3] / a[3]:.3f}x "
              f"(plain {a[0]:.4f} / {a[1]:.5f} / {a[2]:.4f} / {a[3]:.5f}; "
              f"reciprocal {b[0]:.4f} / {b[1]:.5f} / {b[2]:.4f} / {b[3]:.5f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
