#!/usr/bin/env python3
"""Dark materials: one loss epsilon for all against a per-material one.

With ``log(eps + cos f)`` the loss is relative only where ``cos f >> eps``. A
material whose values sit far below eps everywhere (dark films and fabrics) is
then fitted in absolute terms, and its hybrid can end up *worse* than its own
analytic part on SMAPE. ``--loss-eps-relative`` scales eps per material by its
mean ``cos f`` (``FitSettings.loss_eps_relative``).

This fits the five raw RGL files plus nine NBRDF-RGL materials (the darkest and
the ones that failed in earlier campaigns) once per setting and prints, per
material, SMAPE of the analytic part and of the hybrid (and whether the hybrid
beats it), then cMAE of both, and the material's brightness (mean cos f).

    python bench/dark_materials.py [--mlp 16x3] [--steps 10000] [--settings abs:0.01,rel:0.05,rel:0.1,rel:0.2]
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import torch

import hybridbrdf as hb
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.fit.pool import TrainingPool
from hybridbrdf.fit import fit
from hybridbrdf.fit.settings import parse_mlp

ROOT = pathlib.Path(__file__).resolve().parents[1]
NBRDF = ["ilm_solo_m_68_rgb", "chm_orange_rgb", "cm_military_green_rgb", "ilm_l3_37_dark_green_rgb",
         "vch_silk_blue_rgb", "leaf_maple_rgb", "paper_blue_rgb", "satin_gold_rgb", "cc_blue_agat_rgb"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mlp", default="16x3")
    ap.add_argument("--steps", type=int, default=10000)
    ap.add_argument("--pairs", type=int, default=300_000, help="metric pairs (seed 7)")
    ap.add_argument("--settings", default="abs:0.01,rel:0.05,rel:0.1,rel:0.2",
                    help="comma-separated abs:EPS (one epsilon) or rel:K (K x mean cos f per material)")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--shared", default=str(ROOT.parent / "shared" / "data"))
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    width, depth = parse_mlp(args.mlp)
    specs = [f"{args.shared}/rgl"] + [f"{args.shared}/nbrdf/rgl/{n}.h5" for n in NBRDF]
    sources = [hb.open_source(p) for p in hb.expand_sources(specs)]
    brightness = TrainingPool(sources, 1 << 16, 0).brightness
    for setting in args.settings.split(","):
        mode, value = setting.split(":")
        model = fit(sources, FitSettings(width=width, depth=depth, latent=4, steps=args.steps, loss_eps=float(value),
                                         loss_eps_relative=mode == "rel", eval_pairs=args.pairs), progress=False)
        label = f"eps {value} x mean cos f" if mode == "rel" else f"eps {value}"
        print(f"hybrid {args.mlp}, latent 4, {args.steps} steps, loss {label}; {args.pairs} metric pairs (seed 7)")
        print(f"{'material':28s} {'mean cos f':>10s} {'SMAPE analytic':>14s} {'hybrid':>8s} {'':6s} "
              f"{'cMAE analytic':>13s} {'hybrid':>8s}")
        wins = 0
        for info, b in zip(model.material_info, brightness):
            m = info["metrics"]
            ok = m["smape"] < m["smape_analytic"]
            wins += ok
            print(f"{info['name'][:28]:28s} {float(b):10.4f} {m['smape_analytic']:14.4f} {m['smape']:8.4f} "
                  f"{'' if ok else 'WORSE':6s} {m['cmae_analytic']:13.5f} {m['cmae']:8.5f}")
        mean = sum(i["metrics"]["smape"] for i in model.material_info) / len(sources)
        print(f"hybrid beats its analytic part on {wins}/{len(sources)}; mean SMAPE {mean:.4f}\n", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
