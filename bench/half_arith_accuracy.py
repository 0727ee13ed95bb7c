#!/usr/bin/env python3
"""What packed half-precision arithmetic costs in accuracy (bench/shader_forms.py's ``half2`` and
``half2acc8`` forms: hidden layers in f16vec2, the output layer, exp/combine and f_a in float32),
measured under lavapipe, which implements shaderFloat16 by rounding every half operation: per
material of the model, the GLSL's f on 16,384 cosine-weighted pairs (bench/gpu_measure.py's pairs:
seed 7) in the default float32 form and in each half form, against the float64 PyTorch model:
max relative difference (max |a - b| / max(|b|, 1e-6)), SMAPE and cMAE against float64 (the
metrics of hybridbrdf.evaluate.metrics; a model's own SMAPE against measurements is ~0.03-0.7, so
what matters is how much the half form adds to it). Speed is not measured here (the GPU's).

    python bench/half_arith_accuracy.py [MODEL] [--materials 5]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np
import torch

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
sys.path.insert(0, str(ROOT / "tests" / "python"))

import hybridbrdf as hb  # noqa: E402
from hybridbrdf.codegen.literals import material_constant  # noqa: E402
from hybridbrdf.evaluate.directions import cosine_hemisphere  # noqa: E402
from hybridbrdf.evaluate.metrics import cmae, smape  # noqa: E402
from shader_forms import HALF_FORMS, RUNNER, form_glsl  # noqa: E402
from shader_kernels import eval_compute_shader  # noqa: E402

LVP = "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json"
DEFAULT_MODEL = "results/rgl54_hybrid_32x2_e09_120k_refit01.safetensors"
N = 16384


def run_lavapipe(d, model_glsl, kernel, n):
    d = pathlib.Path(d)
    (d / "model.glsl").write_text(model_glsl)
    (d / "w.comp").write_text(kernel)
    subprocess.run(["glslangValidator", "-V", "--target-env", "vulkan1.1", f"-I{d}", str(d / "w.comp"), "-o",
                    str(d / "w.spv")], check=True, capture_output=True)
    r = subprocess.run([str(RUNNER), str(d / "w.spv"), str(d / "in.bin"), str(d / "out.bin"), str(n), "3"],
                       check=True, capture_output=True, text=True, env=dict(os.environ, VK_DRIVER_FILES=LVP))
    if "shader_float16 1" not in r.stdout and "float16" in model_glsl:
        raise SystemExit("lavapipe did not enable shaderFloat16: the half forms cannot run here")
    return np.fromfile(d / "out.bin", dtype=np.float32).reshape(n, 3).astype(np.float64)


def max_rel(a, b):
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-6)))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model", nargs="?", default=DEFAULT_MODEL, help=f"a hybrid model (default {DEFAULT_MODEL})")
    ap.add_argument("--materials", type=int, default=5, help="the model's first N materials (default 5)")
    args = ap.parse_args()
    model = hb.load_model(args.model if pathlib.Path(args.model).exists() else ROOT / args.model)
    rng = np.random.default_rng(7)  # bench/gpu_measure.py's pairs
    wi, wo = cosine_hemisphere(rng, N), cosine_hemisphere(rng, N)
    forms = ["unrolled", *HALF_FORMS]
    print(f"{args.model} ({model.arch['width']}x{model.arch['depth']}), {N} pairs, lavapipe (half rounded per "
          "operation), against the float64 PyTorch model")
    print(f"{'material':28s} {'form':10s} {'max rel':>9s} {'SMAPE':>10s} {'cMAE':>10s} {'cMAE / f mean':>14s}")
    totals = {f: [] for f in forms}
    with tempfile.TemporaryDirectory() as d:
        np.concatenate([wi, wo], axis=1).astype(np.float32).tofile(pathlib.Path(d) / "in.bin")
        for mat in model.materials[:args.materials]:
            ref = np.asarray(model.eval(wi, wo, mat, dtype=torch.float64), dtype=np.float64)
            kernel = eval_compute_shader("hbrdf_eval", material_constant(mat), "model.glsl")
            for form in forms:
                got = run_lavapipe(d, form_glsl(model, mat, form), kernel, N)
                row = (max_rel(got, ref), smape(ref, got), cmae(ref, got, wi[:, 2]))
                totals[form].append(row)
                print(f"{mat:28s} {form:10s} {row[0]:9.2e} {row[1]:10.3e} {row[2]:10.3e} "
                      f"{row[2] / float(np.mean(ref * wi[:, 2:3])):14.3e}", flush=True)
    for form in forms:
        t = np.array(totals[form])
        print(f"{'mean over materials':28s} {form:10s} {t[:, 0].max():9.2e} {t[:, 1].mean():10.3e} "
              f"{t[:, 2].mean():10.3e}   (max rel: the largest)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
