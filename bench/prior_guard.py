#!/usr/bin/env python3
"""The shipped prior through the "never worse than f_a" guard (hybridbrdf.fit.guard; issue 49):
every material whose hybrid its training record measures worse than its own f_a (the table's "!")
is restarted from a neutral head on the prior's network, else set to its f_a; the result is
written to OUT (the shipped prior is python/hybridbrdf/data/prior.safetensors).

    python bench/prior_guard.py --out OUT [--data ../shared/data] [--steps 2000]

The sources are the prior's own, from its training record (paths relative to --data); the
settings are its record's. Prints, per changed material, what was done and its SMAPE / cMAE
before and after next to its f_a's, and the count of materials still worse.
"""

from __future__ import annotations

import argparse
import dataclasses
import pathlib
import sys
import time

import hybridbrdf as hb
from hybridbrdf.fit import guard
from hybridbrdf.fit import fit
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.sources import open_source
from hybridbrdf.sources.names import source_material

ROOT = pathlib.Path(__file__).resolve().parents[1]


def settings_from_record(training: dict) -> FitSettings:
    names = {f.name for f in dataclasses.fields(FitSettings)}
    s = FitSettings(**{k: v for k, v in training.items() if k in names and k not in ("sources",)})
    s.check()
    return s


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", help="model file (default: the shipped prior)")
    ap.add_argument("--out", required=True)
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "data"))
    ap.add_argument("--steps", type=int, default=guard.GUARD_STEPS)
    args = ap.parse_args()
    model = hb.load_model(args.model or hb.prior_path())
    worse = [m["name"] for m in model.material_info if guard.is_worse(m.get("metrics", {}))]
    print(f"{len(worse)} of {len(model.materials)} materials worse than their f_a: {', '.join(worse)}")
    srcs, names = [], []
    for rel in model.training["sources"]:
        src = open_source(pathlib.Path(args.data) / rel)
        name = source_material(model, src)
        if name in worse:
            srcs.append(src)
            names.append(name)
    missing = sorted(set(worse) - set(names))
    if missing:
        print(f"no source found for {', '.join(missing)}", file=sys.stderr)
        return 1
    settings = settings_from_record(model.training)
    t0 = time.time()
    fixed = guard.apply(model, srcs, names, settings, fit, log=print, steps=args.steps)
    fixed = fixed.save_checked(args.out)
    still = [m["name"] for m in fixed.material_info if guard.is_worse(m.get("metrics", {}))]
    print(f"{time.time() - t0:.0f} s; wrote {args.out}; still worse than f_a: {len(still)}"
          + (f" ({', '.join(still)})" if still else ""))
    for name in worse:
        m = fixed.material_info[fixed.index(name)]
        b, a = m["guard"]["before"], m["metrics"]
        print(f"  {name:28s} {m['guard']['action']:8s} SMAPE {b['smape']:.4f} -> {a['smape']:.4f} (f_a "
              f"{a['smape_analytic']:.4f})  cMAE {b['cmae']:.5f} -> {a['cmae']:.5f} (f_a {a['cmae_analytic']:.5f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
