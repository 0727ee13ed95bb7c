#!/usr/bin/env python3
"""Where a model's error comes from: its cMAE (or SMAPE) share per angle.

cMAE (CONVENTIONS) averages |f - f_ref| cos(theta_i) over cosine-weighted pairs;
on glossy materials a few percent of the pairs, those near the mirror
configuration, carry most of it. This prints, per material, the cMAE of the
model and of its analytic part split into theta_h bins (each bin's sum divided
by the total pair count, so the bins add up to the cMAE) next to the fraction of
pairs in each bin. It is the diagnostic behind ``--specular`` (docs/LOSS.md).
``--by theta_i`` bins by the incident elevation instead, ``--metric smape`` splits
SMAPE the same way (the grazing-angle finding in docs/BENCHMARKS.md).

    python bench/cmae_by_angle.py MODEL SOURCE... [--pairs 1000000] [--bins 0,2,5,10,20,40,90]
        [--by theta_h|theta_i] [--metric cmae|smape]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

import hybridbrdf as hb
from hybridbrdf.sources.names import source_material
from hybridbrdf.evaluate.metrics import metric_directions, smape_terms


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model")
    ap.add_argument("sources", nargs="+", help="files, folders or globs matched to the model's materials by name")
    ap.add_argument("--pairs", type=int, default=1_000_000, help="metric pairs (seed 7; default 10^6)")
    ap.add_argument("--bins", default="0,2,5,10,20,40,90", help="bin edges in degrees")
    ap.add_argument("--by", choices=("theta_h", "theta_i"), default="theta_h", help="angle to bin by")
    ap.add_argument("--metric", choices=("cmae", "smape"), default="cmae", help="error to split")
    args = ap.parse_args()
    edges = [float(e) for e in args.bins.split(",")]
    model = hb.load_model(args.model)
    wi, wo = metric_directions(args.pairs)
    if args.by == "theta_h":
        h = wi + wo
        cos_angle = h[:, 2] / np.linalg.norm(h, axis=1)
    else:
        cos_angle = wi[:, 2]
    angle = np.degrees(np.arccos(np.clip(cos_angle, -1.0, 1.0)))
    in_bin = [(angle >= lo) & (angle < hi) for lo, hi in zip(edges[:-1], edges[1:])]
    labels = [f"{lo:g}-{hi:g}" for lo, hi in zip(edges[:-1], edges[1:])]
    print(f"model {args.model}; {args.pairs} cosine-weighted pairs (seed 7); {args.metric} share per "
          f"{args.by} bin (degrees)")
    print(f"{'material':28s} {'part':9s} {args.metric:>8s} " + " ".join(f"{lab:>8s}" for lab in labels))
    print(f"{'(fraction of pairs)':28s} {'':9s} {'':8s} " + " ".join(f"{m.mean():8.1%}" for m in in_bin))
    for spec in hb.expand_sources(args.sources):
        src = hb.open_source(spec)
        name = source_material(model, src)
        if name is None:
            print(f"{src.name}: not in the model, skipped", file=sys.stderr)
            continue
        ref = np.maximum(src.eval(wi, wo), 0.0)
        parts = [("model", model.eval(wi, wo, name))]
        if model.kind != "neural":
            parts.append(("analytic", model.eval_analytic(wi, wo, name)))
        for part, f in parts:
            if args.metric == "cmae":
                err = (np.abs(ref - f) * wi[:, 2:3]).mean(axis=1)
            else:
                err = smape_terms(ref, f).mean(axis=1)
            print(f"{name[:28]:28s} {part:9s} {err.mean():8.5f} "
                  + " ".join(f"{err[m].sum() / len(err):8.5f}" for m in in_bin))
    return 0


if __name__ == "__main__":
    sys.exit(main())
