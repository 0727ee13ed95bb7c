#!/usr/bin/env python3
"""How far each NBRDF-RGL reconstruction (../shared/data/nbrdf/rgl) is from the raw RGL
measurement it was fitted to (../shared/data/rgl), in the CONVENTIONS metrics (10^6
cosine-weighted pairs, seed 7, negatives clamped to 0). Bounds what a network trained on
the reconstructions alone can know of the raw files (docs/ADDING.md, "Adding
measurements later").

    python bench/reconstruction_error.py [--pairs 1000000]
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

import hybridbrdf as hb
from hybridbrdf.evaluate.metrics import cmae, metric_directions, smape

ROOT = pathlib.Path(__file__).resolve().parents[1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=1_000_000)
    ap.add_argument("--shared", default=str(ROOT.parent / "shared" / "data"))
    args = ap.parse_args()
    shared = pathlib.Path(args.shared)
    raw_files = sorted((shared / "rgl").glob("*.bsdf"))
    if not raw_files:
        print(f"no .bsdf files in {shared / 'rgl'}", file=sys.stderr)
        return 1
    wi, wo = metric_directions(args.pairs, seed=7)
    print(f"NBRDF reconstruction against the raw measurement; {args.pairs} pairs, seed 7, negatives clamped")
    print(f"{'material':24s} {'SMAPE':>8s} {'cMAE':>9s}")
    for path in raw_files:
        twin = shared / "nbrdf" / "rgl" / f"{path.stem}.h5"
        if not twin.exists():
            print(f"{path.stem[:24]:24s} (no reconstruction)")
            continue
        raw = np.maximum(hb.open_source(str(path)).eval(wi, wo), 0.0)
        rec = np.maximum(hb.open_source(str(twin)).eval(wi, wo), 0.0)
        print(f"{path.stem[:24]:24s} {smape(raw, rec):8.4f} {cmae(raw, rec, wi[:, 2]):9.5f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
