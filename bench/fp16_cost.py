#!/usr/bin/env python3
"""Accuracy cost of --precision fp16: layer weights rounded to IEEE binary16.

    python bench/fp16_cost.py MODEL SOURCE... [--pairs 1000000]

Evaluates the model as fitted (float32 weights) and with its layer weights
rounded to half precision (exactly what `hbrdf-codegen --precision fp16`
stores), both through libhybridbrdf, and prints per-material SMAPE and cMAE
against the sources plus the SMAPE between the two models.
"""

from __future__ import annotations

import argparse
import sys
import tempfile

import numpy as np

import hybridbrdf as hb
from hybridbrdf.sources.names import source_material
from hybridbrdf.evaluate.metrics import cmae, metric_directions, smape
from hybridbrdf.model.precision import half_rounded


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model")
    ap.add_argument("sources", nargs="+")
    ap.add_argument("--pairs", type=int, default=1_000_000)
    args = ap.parse_args()
    model = hb.load_model(args.model)
    half = half_rounded(model)
    with tempfile.NamedTemporaryFile(suffix=".safetensors") as tmp:
        half.save(tmp.name)
        half = hb.load_model(tmp.name)
        wi, wo = metric_directions(args.pairs)
        print(f"{args.model}: {model.kind} {model.arch['width']}x{model.arch['depth']}; {args.pairs} pairs, seed 7")
        print(f"{'material':28s} {'SMAPE fp32':>10s} {'SMAPE fp16':>10s} {'cMAE fp32':>10s} {'cMAE fp16':>10s} "
              f"{'fp16 vs fp32':>12s}")
        d_smape, d_cmae = [], []
        for spec in hb.expand_sources(args.sources):
            src = hb.open_source(spec)
            name = source_material(model, src)
            if name is None:
                continue
            ref = src.eval(wi, wo)
            f32, f16 = model.eval(wi, wo, name), half.eval(wi, wo, name)
            row = (smape(ref, f32), smape(ref, f16), cmae(ref, f32, wi[:, 2]), cmae(ref, f16, wi[:, 2]), smape(f32, f16))
            d_smape.append(row[1] - row[0])
            d_cmae.append(row[3] - row[2])
            print(f"{name[:28]:28s} {row[0]:10.4f} {row[1]:10.4f} {row[2]:10.5f} {row[3]:10.5f} {row[4]:12.2e}")
        if d_smape:
            print(f"mean change from fp16 weights: SMAPE {np.mean(d_smape):+.2e}, cMAE {np.mean(d_cmae):+.2e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
