#!/usr/bin/env python3
"""What editing and blending guarantee, measured: on a grid of edits and blends of the
shipped prior's materials, evaluated by libhybridbrdf (float32, the engines' runtime):

- finite and non-negative: every value on the hard directions of tests/data/hard_directions.json
  crossed with themselves (grazing, normal, subnormal, below the horizon, NaN, Inf) and on 10^5
  random pairs; counts of values that are NaN/Inf or negative (the model's structure promises 0);
- reciprocity: SMAPE between f(wi, wo) and f(wo, wi) (metrics.reciprocity_error), edited against
  the material it came from (the network is not reciprocal by construction; an edit should not
  make it worse);
- energy: the maximum directional albedo (model.albedo), and how many edits exceed 1.

    python bench/edit_guarantees.py [--materials 24] [--pairs 20000] [--albedo-samples 4096]

Edits per material (the corners of the parameter ranges, where a fitted correction is furthest
from what it was fitted with): kd 0, kd 1, eta 1, eta 10, alpha 1e-4, alpha 1, anisotropic
(alpha/4, 4 alpha), and kd 1 with eta 10. Blends: consecutive pairs of the chosen materials at
t = 0.25, 0.5, 0.75.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import tempfile
import time

import numpy as np

import hybridbrdf as hb
from hybridbrdf.evaluate.metrics import reciprocity_error

ROOT = pathlib.Path(__file__).resolve().parents[1]


def hard_pairs():
    table = json.loads((ROOT / "tests" / "data" / "hard_directions.json").read_text())["directions"]
    tiny = float(np.finfo(np.float32).smallest_subnormal)

    def comp(v):
        return tiny if v == "denorm_min" else (-tiny if v == "-denorm_min" else float(v))

    d = np.array([[comp(v) for v in e["w"]] for e in table])
    return np.repeat(d, len(d), axis=0), np.tile(d, (len(d), 1))


def corner_edits(p):
    a = float(p.alpha[0])
    return {"kd 0": {"kd": 0.0}, "kd 1": {"kd": 1.0}, "eta 1": {"eta": 1.0}, "eta 10": {"eta": 10.0},
            "alpha 1e-4": {"alpha": 1e-4}, "alpha 1": {"alpha": 1.0},
            "aniso": {"alpha": [max(a / 4, hb.ALPHA_MIN), min(4 * a, 1.0)]}, "kd 1 eta 10": {"kd": 1.0, "eta": 10.0}}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", help="model file (default: the shipped prior)")
    ap.add_argument("--materials", type=int, default=24, help="materials, evenly spaced over the model's (default 24)")
    ap.add_argument("--pairs", type=int, default=20_000, help="pairs of the reciprocity metric (default 20000)")
    ap.add_argument("--albedo-samples", type=int, default=4096)
    args = ap.parse_args()
    base = hb.load_model(args.model or hb.prior_path())
    chosen = [base.materials[i] for i in np.linspace(0, len(base.materials) - 1, args.materials).round().astype(int)]
    model, kinds = base, {}
    for k, name in enumerate(chosen):
        for label, kw in corner_edits(base.analytic_params(name)).items():
            new = f"e{k}_{len(kinds)}"
            model = model.edit(name, new, **kw)
            kinds[new] = (label, name)
    for k, (a, b) in enumerate(zip(chosen, chosen[1:])):
        for t in (0.25, 0.5, 0.75):
            new = f"m{k}_{int(t * 100)}"
            model = model.mix(a, b, t, new)
            kinds[new] = (f"blend t {t:g}", a)
    t0 = time.time()
    hwi, hwo = hard_pairs()
    rng = np.random.default_rng(5)
    rwi, rwo = rng.normal(size=(100_000, 3)), rng.normal(size=(100_000, 3))
    stats: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        model = model.save_checked(os.path.join(tmp, "edits.safetensors"))
        recip_orig = {n: reciprocity_error(lambda wi, wo, n=n: model.eval(wi, wo, n), args.pairs) for n in chosen}
        for name, (label, origin) in kinds.items():
            bad_values = 0
            for wi, wo in ((hwi, hwo), (rwi, rwo)):
                f = model.eval(wi, wo, name)
                bad_values += int((~np.isfinite(f)).sum() + (f < 0).sum())
            recip = reciprocity_error(lambda wi, wo: model.eval(wi, wo, name), args.pairs)
            albedo = model.albedo(name, samples=args.albedo_samples)["max"]
            s = stats.setdefault(label, {"n": 0, "bad": 0, "recip": [], "recip_ratio": [], "albedo": []})
            s["n"] += 1
            s["bad"] += bad_values
            s["recip"].append(recip)
            s["recip_ratio"].append(recip / max(recip_orig[origin], 1e-12))
            s["albedo"].append(albedo)
    seconds = time.time() - t0
    n_eval = len(hwi) + len(rwi)
    print(f"{base.path}: {len(chosen)} materials, {len(kinds)} edited or blended; libhybridbrdf float32; "
          f"{n_eval} pairs each for finiteness ({len(hwi)} hard), {args.pairs} for reciprocity, "
          f"{args.albedo_samples} x 44 for albedo; {seconds:.0f} s")
    print(f"fitted materials: reciprocity SMAPE mean {np.mean(list(recip_orig.values())):.4f}, "
          f"max albedo mean {np.mean([model.albedo(n, samples=args.albedo_samples)['max'] for n in chosen]):.3f}")
    print(f"{'edit':14s} {'n':>3s} {'NaN/Inf/neg':>11s} {'recip mean':>10s} {'recip max':>9s} {'x fitted':>8s} "
          f"{'albedo mean':>11s} {'max':>6s} {'> 1':>4s}")
    for label, s in stats.items():
        r, a = np.array(s["recip"]), np.array(s["albedo"])
        print(f"{label:14s} {s['n']:3d} {s['bad']:11d} {r.mean():10.4f} {r.max():9.4f} "
              f"{np.median(s['recip_ratio']):8.2f} {a.mean():11.3f} {a.max():6.3f} {int((a > 1).sum()):4d}")
    print("x fitted: median ratio of the edit's reciprocity error to its material's")
    return 0


if __name__ == "__main__":
    sys.exit(main())
