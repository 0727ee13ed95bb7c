#!/usr/bin/env python3
"""Where a model's cMAE comes from: its share per half-vector angle theta_h.

cMAE (CONVENTIONS) averages |f - f_ref| cos(theta_i) over cosine-weighted pairs;
on glossy materials a few percent of the pairs, those near the mirror
configuration, carry most of it. This prints, per material, the cMAE of the
model and of its analytic part split into theta_h bins (each bin's sum divided
by the total pair count, so the bins add up to the cMAE) next to the fraction of
pairs in each bin. It is the diagnostic behind ``--specular`` (docs/FITTING.md).

    python bench/cmae_by_angle.py MODEL SOURCE... [--pairs 1000000] [--bins 0,2,5,10,20,40,90]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

import hybridbrdf as hb
from hybridbrdf.fitting import format_tag
from hybridbrdf.metrics import metric_directions


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model")
    ap.add_argument("sources", nargs="+", help="files, folders or globs matched to the model's materials by name")
    ap.add_argument("--pairs", type=int, default=1_000_000, help="metric pairs (seed 7; default 10^6)")
    ap.add_argument("--bins", default="0,2,5,10,20,40,90", help="theta_h bin edges in degrees")
    args = ap.parse_args()
    edges = [float(e) for e in args.bins.split(",")]
    model = hb.load_model(args.model)
    wi, wo = metric_directions(args.pairs)
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    theta_h = np.degrees(np.arccos(np.clip(h[:, 2], -1.0, 1.0)))
    in_bin = [(theta_h >= lo) & (theta_h < hi) for lo, hi in zip(edges[:-1], edges[1:])]
    labels = [f"{lo:g}-{hi:g}" for lo, hi in zip(edges[:-1], edges[1:])]
    print(f"model {args.model}; {args.pairs} cosine-weighted pairs (seed 7); cMAE share per theta_h bin (degrees)")
    print(f"{'material':28s} {'part':9s} {'cMAE':>8s} " + " ".join(f"{lab:>8s}" for lab in labels))
    print(f"{'(fraction of pairs)':28s} {'':9s} {'':8s} " + " ".join(f"{m.mean():8.1%}" for m in in_bin))
    for spec in hb.expand_sources(args.sources):
        src = hb.open_source(spec)
        name = next((c for c in (src.name, f"{src.name}.{format_tag(src)}") if c in model.materials), None)
        if name is None:
            print(f"{src.name}: not in the model, skipped", file=sys.stderr)
            continue
        ref = np.maximum(src.eval(wi, wo), 0.0)
        parts = [("model", model.eval(wi, wo, name))]
        if model.kind != "neural":
            parts.append(("analytic", model.eval_analytic(wi, wo, name)))
        for part, f in parts:
            err = (np.abs(ref - f) * wi[:, 2:3]).mean(axis=1)
            print(f"{name[:28]:28s} {part:9s} {err.mean():8.5f} "
                  + " ".join(f"{err[m].sum() / len(err):8.5f}" for m in in_bin))
    return 0


if __name__ == "__main__":
    sys.exit(main())
