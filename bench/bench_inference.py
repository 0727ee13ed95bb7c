#!/usr/bin/env python3
"""What accuracy costs in time: evaluation throughput of the analytic model and of
hybrid and neural models at 16x2 .. 64x3, on the C++ batched path (one core) and
as generated GLSL under lavapipe (both cores), measured in one run, next to each
model's SMAPE; writes a table and a PNG plot (error against cost).

- FLOPs per evaluation count the network's multiply-adds (2 per weight); the
  achieved GFLOP/s is set against one core's FMA peak measured in the same run by
  ``hbrdf_fma_peak`` on the same pinned core.
- Lavapipe runs the generated shader (default form: unrolled network with literal
  weights) as a compute shader over ``--pairs`` pairs, 64 invocations per workgroup;
  three extra rows run the hybrid 32x2 with fp16 weights and with the network as loops
  over constant arrays (``--mlp-form loops``).
- SMAPE columns come from a fitting campaign (``bench/compare_models.py`` with all six
  sizes, e.g. ``--models-dir out/cost``): the mean over its materials of the hybrid
  (latent 4), the neural baseline (latent 12) and, for the analytic row, the analytic
  part of the hybrid 32x3. Its fitted models are also the ones timed; without it,
  models with random weights are timed (throughput does not depend on the values).

    python bench/bench_inference.py [--pairs 1048576] [--models-dir out/cost] [--no-lavapipe]
        [--out docs/figures/cost_accuracy]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import re
import subprocess
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))

import hybridbrdf as hb  # noqa: E402
from hybridbrdf import _core  # noqa: E402
from hybridbrdf.codegen import eval_compute_shader, generate, material_constant  # noqa: E402
from hybridbrdf.random_model import random_model  # noqa: E402
from bench_analytic import best_rate  # noqa: E402

RUNNER = ROOT / "build" / "hbrdf_vk_runner"
FMA_PEAK = ROOT / "build" / "hbrdf_fma_peak"
LVP = "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json"
SIZES = [(16, 2), (16, 3), (32, 2), (32, 3), (64, 2), (64, 3)]

def lavapipe_rate(model, fn, n, wi, wo, d, **generate_options):
    """Evaluations per second of the generated GLSL ``fn`` for the model's first material."""
    (pathlib.Path(d) / "model.glsl").write_text(generate(model, "glsl", [model.materials[0]], **generate_options))
    src = pathlib.Path(d) / "w.comp"
    src.write_text(eval_compute_shader(fn, material_constant(model.materials[0]), "model.glsl"))
    spv = pathlib.Path(d) / "w.spv"
    subprocess.run(["glslangValidator", "-V", "--target-env", "vulkan1.1", f"-I{d}", str(src), "-o", str(spv)],
                   check=True, capture_output=True)
    np.concatenate([wi, wo], axis=1).astype(np.float32).tofile(pathlib.Path(d) / "in.bin")
    r = subprocess.run([str(RUNNER), str(spv), f"{d}/in.bin", f"{d}/out.bin", str(n), "3", "--repeat", "7"],
                       check=True, capture_output=True, text=True, env=dict(os.environ, VK_DRIVER_FILES=LVP))
    ms = float([ln for ln in r.stdout.splitlines() if ln.startswith("best_ms")][0].split()[1])
    return n / (ms / 1000.0)


def fma_peak_gflops(core: int) -> float:
    r = subprocess.run(["taskset", "-c", str(core), str(FMA_PEAK), "2"], check=True, capture_output=True, text=True)
    return float([ln for ln in r.stdout.splitlines() if ln.startswith("peak_gflops")][0].split()[1])


def campaign_smape(models_dir):
    """{mlp: (analytic, hybrid, neural)} mean SMAPE from compare_<mlp>.txt files, plus the header line."""
    out, header = {}, ""
    if not models_dir:
        return out, header
    for w, d in SIZES:
        p = pathlib.Path(models_dir) / f"compare_{w}x{d}.txt"
        if not p.exists():
            continue
        lines = p.read_text().splitlines()
        header = header or lines[0].split(": ", 1)[-1]  # drop the "# WxD: " prefix
        mean = [ln for ln in lines if ln.startswith("mean ")][0].split()
        out[(w, d)] = (float(mean[1]), float(mean[2]), float(mean[3]))
    return out, header


def models_dir_label(models_dir):
    return models_dir or "none"


def model_for(arch, width, depth, models_dir, d):
    latent = 12 if arch == "neural" else 4
    fitted = pathlib.Path(models_dir or "-") / f"{arch}_{width}x{depth}_l{latent}.safetensors"
    if fitted.exists():
        return str(fitted), True
    _, model = random_model(arch, latent=latent, width=width, depth=depth)
    path = f"{d}/{arch}{width}x{depth}.safetensors"
    model.save(path)
    return path, False


def plot(rows, path_png, title):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, key, label in ((axes[0], "cpp", "C++ batched, 1 core"), (axes[1], "vk", "GLSL under lavapipe, 2 cores")):
        for arch, marker in (("analytic", "s"), ("hybrid", "o"), ("neural", "^")):
            pts = [(1e9 / r[key], r["smape"], r["name"]) for r in rows
                   if r["arch"] == arch and r.get(key) and r.get("smape") is not None]
            if not pts:
                continue
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker=marker, linestyle="-" if arch != "analytic" else "",
                    label=arch)
            for x, y, name in pts:
                ax.annotate(name.split()[-1] if arch != "analytic" else "f_a", (x, y), textcoords="offset points",
                            xytext=(4, 4), fontsize=7)
        ax.set_xscale("log")
        ax.set_xlabel("ns per evaluation (" + label + ")")
        ax.set_ylabel("mean SMAPE")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path_png, dpi=120)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=1 << 20, help="direction pairs per measurement (default 2^20)")
    ap.add_argument("--models-dir", default="out/cost",
                    help="fitting campaign with compare_<mlp>.txt tables and fitted models (default out/cost)")
    ap.add_argument("--no-lavapipe", action="store_true", help="skip the GLSL-under-lavapipe column")
    ap.add_argument("--out", default="", help="write OUT.txt (the table) and OUT.png (the plot)")
    args = ap.parse_args()
    n = args.pairs
    rng = np.random.default_rng(7)
    from hybridbrdf.metrics import cosine_hemisphere

    wi = cosine_hemisphere(rng, n).astype(np.float32)
    wo = cosine_hemisphere(rng, n).astype(np.float32)
    use_vk = not args.no_lavapipe and RUNNER.exists() and os.path.exists(LVP)
    all_cores = os.sched_getaffinity(0)
    core = sorted(all_cores)[0]
    smapes, campaign = campaign_smape(args.models_dir)
    peak = fma_peak_gflops(core) if FMA_PEAK.exists() else float("nan")
    os.sched_setaffinity(0, {core})  # the C++ path on one core

    def vk_rate(*a, **kw):
        os.sched_setaffinity(0, all_cores)
        try:
            return lavapipe_rate(*a, **kw)
        finally:
            os.sched_setaffinity(0, {core})

    lines = [f"{n} cosine-weighted pairs; C++ batched on 1 core (kernel {_core.model_simd_path()}, one-core FMA "
             f"peak {peak:.1f} GFLOP/s measured by hbrdf_fma_peak); GLSL under lavapipe, 64 invocations per "
             f"workgroup, {len(all_cores)} cores",
             f"SMAPE (mean over the campaign's materials, {models_dir_label(args.models_dir)}): "
             f"{campaign or 'no fitting campaign found (random weights timed)'}",
             f"{'model':22s} {'FLOP/eval':>9s} {'C++ M/s':>8s} {'GFLOP/s':>8s} {'% peak':>7s} {'lavapipe M/s':>13s} "
             f"{'SMAPE':>7s}"]
    rows = []
    with tempfile.TemporaryDirectory() as d:
        path, _ = model_for("hybrid", 32, 3, args.models_dir, d)
        any_model = hb.load_model(path)
        p = any_model.analytic_params(0)
        row = {"arch": "analytic", "name": "analytic (f_a)", "cpp": best_rate(lambda: hb.analytic_eval(wi, wo, p), n, 7),
               "vk": vk_rate(any_model, "hbrdf_eval_analytic", n, wi, wo, d) if use_vk else None,
               "smape": smapes.get((32, 3), (None,))[0], "flops": None}
        rows.append(row)
        for arch in ("hybrid", "neural"):
            for width, depth in SIZES:
                path, _ = model_for(arch, width, depth, args.models_dir, d)
                cpp = _core.Model(path)
                s = smapes.get((width, depth))
                rows.append({"arch": arch, "name": f"{arch} {width}x{depth}", "flops": cpp.flops_per_eval,
                             "cpp": best_rate(lambda: cpp.eval(wi, wo, 0), n, 7),
                             "vk": vk_rate(hb.load_model(path), "hbrdf_eval", n, wi, wo, d) if use_vk else None,
                             "smape": (s[1] if arch == "hybrid" else s[2]) if s else None})
        if use_vk:  # the other code forms of the hybrid 32x2
            path, _ = model_for("hybrid", 32, 2, args.models_dir, d)
            for name, options in (("32x2 fp16 unrolled", {"precision": "fp16"}),
                                  ("32x2 fp32 loops", {"mlp_form": "loops"}),
                                  ("32x2 fp16 loops", {"precision": "fp16", "mlp_form": "loops"})):
                rows.append({"arch": "form", "name": "hybrid " + name, "flops": None, "cpp": None,
                             "vk": vk_rate(hb.load_model(path), "hbrdf_eval", n, wi, wo, d, **options),
                             "smape": None})
    for r in rows:
        fl = f"{r['flops']:9.0f}" if r["flops"] else f"{'-':>9s}"
        cpp = f"{r['cpp'] / 1e6:8.2f}" if r["cpp"] else f"{'-':>8s}"
        gf = r["cpp"] * r["flops"] / 1e9 if r["flops"] and r["cpp"] else None
        gfs = f"{gf:8.1f} {100 * gf / peak:6.1f}%" if gf else f"{'-':>8s} {'-':>7s}"
        vk = f"{r['vk'] / 1e6:13.2f}" if r["vk"] else f"{'-':>13s}"
        sm = f"{r['smape']:7.4f}" if r["smape"] is not None else f"{'-':>7s}"
        lines.append(f"{r['name']:22s} {fl} {cpp} {gfs} {vk} {sm}")
    text = "\n".join(lines)
    print(text)
    if args.out:
        pathlib.Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        pathlib.Path(args.out + ".txt").write_text(text + "\n")
        plot(rows, args.out + ".png", lines[0][:110] + "\n" + lines[1][:160])
        print(f"wrote {args.out}.txt and {args.out}.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
