#!/usr/bin/env python3
"""A highlight's profile: reference, model and its analytic part along the plane of incidence.

wo is fixed at --theta-o degrees (azimuth 0); wi sweeps away from the mirror direction by the
offsets of --offsets degrees, in the plane of incidence. Prints RGB values of the measured (or
reconstructed) source, the fitted model f_t and its analytic part f_a, and the ratio f_t / f_ref
per channel: shows whether a model's peak is too low (the gate f_g <= 1 can only dim f_a, so a
peak above f_a must come from the correction exp(o)) or its tail too heavy.

    python bench/highlight_profile.py MODEL SOURCE [--theta-o 30] [--offsets 0,1,2,4,8,12,20,40]

SOURCE is a file whose name matches one of the model's materials (``<name>`` or
``<name>.<format>``), e.g. ../shared/data/rgl/vch_golden_yellow_rgb.bsdf.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

import hybridbrdf as hb
from hybridbrdf.sources.names import source_material


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model")
    ap.add_argument("source")
    ap.add_argument("--theta-o", type=float, default=30.0, help="elevation of wo in degrees (default 30)")
    ap.add_argument("--offsets", default="0,1,2,3,4,6,8,12,20,40",
                    help="comma-separated angles in degrees between wi and the mirror direction of wo")
    args = ap.parse_args()
    model = hb.load_model(args.model)
    src = hb.open_source(args.source)
    name = source_material(model, src)
    if name is None:
        print(f"error: {args.source}: {src.name} is not a material of {args.model}", file=sys.stderr)
        return 2
    t_o = np.radians(args.theta_o)
    wo = np.array([[np.sin(t_o), 0.0, np.cos(t_o)]])
    print(f"{name}: wo at {args.theta_o:g} deg; wi in the plane of incidence, offset from the mirror direction")
    print(f"{'offset':>6s} {'reference':>24s} {'model':>24s} {'analytic part':>24s} {'model / reference':>20s}")
    fmt = lambda v: " ".join(f"{x:7.3f}" for x in v)  # noqa: E731
    for offset in (float(x) for x in args.offsets.split(",")):
        t_i = t_o + np.radians(offset)
        if t_i >= np.pi / 2:
            break
        wi = np.array([[-np.sin(t_i), 0.0, np.cos(t_i)]])
        ref = np.maximum(src.eval(wi, wo)[0], 0.0)
        f_t, f_a = model.eval(wi, wo, name)[0], model.eval_analytic(wi, wo, name)[0]
        ratio = np.divide(f_t, ref, out=np.full(3, np.nan), where=ref > 0)
        print(f"{offset:6g} {fmt(ref):>24s} {fmt(f_t):>24s} {fmt(f_a):>24s} {' '.join(f'{r:6.2f}' for r in ratio):>20s}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
