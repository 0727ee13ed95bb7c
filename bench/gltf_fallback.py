"""The glTF fallback of every material of a model (default: the shipped prior), as ``hbrdf export``
fits it (docs/GLTF.md, "The fallback, measured"): SMAPE and cMAE against f_a and against the
hybrid, of the closed-form mapping before the fit and of the fallback kept, on cosine-weighted
pairs (hybridbrdf.gltf.fallback: EVAL_PAIRS, EVAL_SEED).

    python bench/gltf_fallback.py [--model MODEL] [--limit N] [--out results/gltf_fallback_X1.txt]

Prints a Markdown table (per material and the means) and the CPU seconds of the fits.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import hybridbrdf
from hybridbrdf.gltf import fit_fallback


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None, help="model file (default: the shipped prior)")
    ap.add_argument("--limit", type=int, default=0, help="only the first N materials (0: all)")
    ap.add_argument("--out", default=None, help="also write the report to this file")
    args = ap.parse_args()
    path = args.model or hybridbrdf.prior_path()
    model = hybridbrdf.load_model(path)
    names = model.materials[:args.limit] if args.limit else model.materials
    rows, cpu0 = [], time.process_time()
    for i, name in enumerate(names):
        p = model.analytic_params(i)
        r = fit_fallback(p.kd, p.eta, p.alpha, hybrid=lambda wi, wo, i=i: model.eval(wi, wo, i))
        m = r.metrics
        rows.append((name, r.kept, *m[("closed_form", "f_a")], *m[(r.kept, "f_a")], *m[("closed_form", "hybrid")],
                     *m[(r.kept, "hybrid")]))
    cpu = time.process_time() - cpu0
    lines = [f"model {os.path.basename(path)}: {len(rows)} materials; fits {cpu:.1f} s of CPU "
             f"({cpu / max(len(rows), 1):.2f} s per material); simd {hybridbrdf.simd_path()}",
             "", "| material | kept | closed form vs f_a SMAPE / cMAE | fallback vs f_a | closed form vs hybrid | "
             "fallback vs hybrid |", "|---|---|---|---|---|---|"]
    for name, kept, *v in rows:
        lines.append(f"| {name} | {kept} | {v[0]:.4f} / {v[1]:.5f} | {v[2]:.4f} / {v[3]:.5f} | {v[4]:.4f} / {v[5]:.5f} "
                     f"| {v[6]:.4f} / {v[7]:.5f} |")
    mean = np.mean([r[2:] for r in rows], axis=0)
    fitted = sum(r[1] == "fitted" for r in rows)
    lines.append(f"| **mean** ({fitted} of {len(rows)} fitted) | | {mean[0]:.4f} / {mean[1]:.5f} | "
                 f"{mean[2]:.4f} / {mean[3]:.5f} | {mean[4]:.4f} / {mean[5]:.5f} | {mean[6]:.4f} / {mean[7]:.5f} |")
    text = "\n".join(lines)
    print(text)
    if args.out:
        with open(args.out, "w") as fh:
            fh.write(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
