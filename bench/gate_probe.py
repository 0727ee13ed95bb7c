#!/usr/bin/env python3
"""What a gated hybrid's network does for a material: f_g and f_c over cosine-weighted pairs.

The gated combine is f = f_c + f_g f_a per channel, and for the architectures whose network does
not see f_a (all gated ones but analytic-input) f_c and f_g do not depend on kd. So an edit of the
material's kd alone (``model.edit``: same latent code, same head) changes f by f_g times the
change of f_a, and

    f_g = (f_edit - f) / (f_a,edit - f_a),    f_c = f - f_g f_a,

from public evaluations only. Prints, per material, the range of f_g, the largest and median f_c,
and the range of f / f_a: a material whose f_g sits at 1 and f_c near 0 everywhere is left at its
f_a by the network (a saturated gate passes almost no gradient; docs/FITTING.md, "Reciprocal by
construction").

    python bench/gate_probe.py MODEL [MATERIAL ...] [--pairs 2000] [--seed 0]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

import hybridbrdf as hb
from hybridbrdf import spec
from hybridbrdf.evaluate.directions import cosine_directions


def gate(model, material, wi, wo):
    """(f_g, f_c, f, f_a), each (N, 3), of ``material`` at the pairs."""
    kd = np.asarray(model.analytic_params(material).kd, dtype=np.float64)
    kd_edit = np.where(kd > 0.5, kd - 0.4, kd + 0.4)  # f_a moves by 0.4 / pi in every channel
    edited = model.edit(material, "gate_probe_edit", kd=kd_edit)
    f, fa = model.eval(wi, wo, material), model.eval_analytic(wi, wo, material)
    f2, fa2 = edited.eval(wi, wo, "gate_probe_edit"), edited.eval_analytic(wi, wo, "gate_probe_edit")
    f_g = (f2 - f) / (fa2 - fa)
    return f_g, f - f_g * fa, f, fa


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model")
    ap.add_argument("materials", nargs="*", help="default: every material of the model")
    ap.add_argument("--pairs", type=int, default=2000, help="cosine-weighted direction pairs (default 2000)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    model = hb.load_model(args.model)
    a = spec.ARCHS[model.kind]
    if a["combine"] != "gated" or a["extra"] != "none":
        ap.error(f"{model.kind}: the probe needs a gated architecture whose network does not see f_a")
    rng = np.random.default_rng(args.seed)
    wi, wo = cosine_directions(rng, args.pairs), cosine_directions(rng, args.pairs)
    print(f"{args.model}: {model.kind}, {args.pairs} cosine-weighted pairs (seed {args.seed})")
    print(f"{'material':28s} {'f_g min':>8s} {'f_g med':>8s} {'f_g max':>8s} {'f_c med':>9s} {'f_c max':>9s} "
          f"{'f/f_a min':>9s} {'f/f_a max':>9s}")
    for name in args.materials or model.materials:
        f_g, f_c, f, fa = gate(model, name, wi, wo)
        ratio = f / np.maximum(fa, 1e-30)
        print(f"{name[:28]:28s} {f_g.min():8.4f} {np.median(f_g):8.4f} {f_g.max():8.4f} {np.median(f_c):9.2e} "
              f"{f_c.max():9.2e} {ratio.min():9.4f} {ratio.max():9.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
