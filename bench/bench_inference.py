#!/usr/bin/env python3
"""What accuracy costs in time and memory: evaluation throughput of the analytic model,
hybrid and neural models at 16x2 .. 64x3 and the fitted RGL models, on the C++ batched
path (one core, AVX2 kernel and, where the CPU has it, AVX-512) and as generated GLSL
under lavapipe (both cores; the host's own SIMD path and an AVX2-only run), measured in
one run, next to each model's SMAPE, its SPIR-V instruction count per evaluation and
its bytes per material and per collection; writes a table and a PNG plot (error against
cost).

- FLOPs per evaluation count the network's multiply-adds (2 per weight); the achieved
  GFLOP/s is set against one core's FMA peak *of the kernel's instruction set*, measured in
  the same run on the same pinned core by ``_core.fma_peak_gflops`` (the hbrdf_fma_peak
  loops, inside the Python module so that an installed package measures it too). On Zen 4
  the AVX2 and AVX-512 peaks are equal (AVX-512 runs on 256-bit pipes); on Zen 5 the
  AVX-512 peak is twice the AVX2 one.
- Lavapipe runs the generated shader (default form: unrolled network with literal
  weights) as a compute shader over ``--pairs`` pairs, 64 invocations per workgroup,
  once as the host allows and once with ``GALLIUM_OVERRIDE_CPU_CAPS=avx`` (Mesa's switch
  that hides AVX-512, so LLVM emits AVX2+FMA code: the figure a machine without AVX-512
  gets); the network as loops (``--mlp-form loops``) on a sixteenth of the pairs (it ran at a
  few hundredths of a million evaluations per second before the loops form's unroll hints,
  issue 56; with them, about the unrolled form's rate, docs/CODEGEN.md). Lavapipe is a proxy for a GPU, so each
  shader's SPIR-V instruction count per
  evaluation is printed too (after ``spirv-opt -O``, which inlines everything into
  straight-line code; "fma" counts the fused multiply-adds spirv-opt forms).
- Bytes: what the model holds per material (analytic parameters and latent code, float32)
  and the shared network once; "per collection" is for the 54 RGL materials.
- SMAPE of the size sweep comes from a fitting campaign (``bench/compare_models.py``
  with all six sizes; ``--models-dir``, default ``out/cost`` and, without it, the tables
  kept in ``results/compare_rgl5_synthetic_<mlp>.txt``): the mean over its materials of
  the hybrid (latent 4), the neural baseline (latent 12) and, for the analytic row, the
  analytic part of the hybrid 32x3. Fitted models of the campaign are timed when present,
  otherwise models with random weights (throughput does not depend on the values). The
  RGL rows (``--rgl-models``) are fitted models, with their mean SMAPE / cMAE over the
  five raw RGL rows of docs/BENCHMARKS.md.

    python bench/bench_inference.py [--pairs 1048576] [--models-dir out/cost] [--no-lavapipe]
        [--rgl-models results/rgl54_hybrid_32x2_e09_120k_refit01.safetensors,results/rgl54_fast.safetensors]
        [--out docs/figures/cost_accuracy]
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
sys.path.insert(0, str(ROOT / "tests" / "python"))  # shader_kernels

import hybridbrdf as hb  # noqa: E402
from hybridbrdf import _core  # noqa: E402
from hybridbrdf.codegen.main import generate
from hybridbrdf.codegen.literals import material_constant
from hybridbrdf.model.random import random_model  # noqa: E402
from bench_analytic import best_rate  # noqa: E402
from shader_kernels import eval_compute_shader  # noqa: E402

RUNNER = ROOT / "build" / "hbrdf_vk_runner"
LVP = "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json"
SIZES = [(16, 2), (16, 3), (32, 2), (32, 3), (64, 2), (64, 3)]
RGL_MODELS = ("results/rgl54_hybrid_32x2_e09_120k_refit01.safetensors,results/rgl54_hybrid_16x2_e09_100k_refit01.safetensors,"
              "results/rgl54_fast.safetensors")
# Lavapipe runs: the host's own SIMD path, and AVX2+FMA only (Mesa hides AVX-512 from LLVM).
VK_RUNS = {"host": {}, "avx2": {"GALLIUM_OVERRIDE_CPU_CAPS": "avx"}}
FLOAT = 4  # bytes


def compile_shader(model, fn, d, material=None, tag="w", directions="buffer", **generate_options):
    """SPIR-V of the eval kernel running the generated GLSL ``fn`` for ``material`` (default:
    the model's first), written as d/TAG.spv (TAG keeps several shaders apart in one folder);
    ``directions``: the kernel reads its pairs ("buffer") or makes them ("synthetic", see
    tests/python/shader_kernels.py, eval_compute_shader)."""
    material = model.materials[0] if material is None else material
    (pathlib.Path(d) / f"{tag}.glsl").write_text(generate(model, "glsl", [material], **generate_options))
    src = pathlib.Path(d) / f"{tag}.comp"
    src.write_text(eval_compute_shader(fn, material_constant(material), f"{tag}.glsl", directions=directions))
    spv = pathlib.Path(d) / f"{tag}.spv"
    subprocess.run(["glslangValidator", "-V", "--target-env", "vulkan1.1", f"-I{d}", str(src), "-o", str(spv)],
                   check=True, capture_output=True)
    return spv


def spirv_counts(spv, d):
    """(instructions, fused multiply-adds) in the function bodies after spirv-opt -O: the
    unrolled shaders become one straight-line function, so this is the count per evaluation."""
    opt = pathlib.Path(d) / "o.spv"
    subprocess.run(["spirv-opt", "-O", str(spv), "-o", str(opt)], check=True, capture_output=True)
    dis = subprocess.run(["spirv-dis", "--raw-id", str(opt)], check=True, capture_output=True, text=True).stdout
    ops, inside = collections.Counter(), False
    for line in dis.splitlines():
        words = line.split("=")[-1].split()
        if not words:
            continue
        if words[0] == "OpFunction":
            inside = True
        elif words[0] == "OpFunctionEnd":
            inside = False
        elif inside:
            ops["Fma" if words[0] == "OpExtInst" and "Fma" in words else words[0]] += 1
    return sum(ops.values()), ops["Fma"]


def lavapipe_rate(spv, n, d, env):
    """Evaluations per second of one lavapipe process with the extra environment ``env``
    (best of its 3 x 7 timed dispatches; inputs already in d/in.bin)."""
    r = subprocess.run([str(RUNNER), str(spv), f"{d}/in.bin", f"{d}/out.bin", str(n), "3", "--repeat", "7"],
                       check=True, capture_output=True, text=True, env=dict(os.environ, VK_DRIVER_FILES=LVP, **env))
    ms = float([ln for ln in r.stdout.splitlines() if ln.startswith("best_ms")][0].split()[1])
    return n / (ms / 1000.0)


def lavapipe_rates(spv, n, d):
    """Evaluations per second under lavapipe for each of VK_RUNS."""
    return {run: lavapipe_rate(spv, n, d, env) for run, env in VK_RUNS.items()}


def fma_peak_gflops(core: int) -> dict:
    """One core's FMA peak in GFLOP/s per kernel name ("avx2+fma", "avx512"), measured on
    ``core`` by the Python module itself (``_core.fma_peak_gflops``: the hbrdf_fma_peak
    loops), so that an installed package measures it too; nan where the probe is missing."""
    previous = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {core})
    try:
        p = _core.fma_peak_gflops(2.0)
    finally:
        os.sched_setaffinity(0, previous)
    return {k: (p[key] if p[key] > 0 else float("nan")) for k, key in (("avx2+fma", "avx2_fma"), ("avx512", "avx512"))}


def campaign_smape(models_dir):
    """{mlp: (analytic, hybrid, neural)} mean SMAPE from compare_<mlp>.txt files (or the copies
    kept as results/compare_rgl5_synthetic_<mlp>.txt), plus the header line and where it came from."""
    out, header, where = {}, "", ""
    for w, d in SIZES:
        for p in (pathlib.Path(models_dir or "-") / f"compare_{w}x{d}.txt",
                  ROOT / "results" / f"compare_rgl5_synthetic_{w}x{d}.txt"):
            if p.exists():
                break
        else:
            continue
        lines = p.read_text().splitlines()
        header, where = header or lines[0].split(": ", 1)[-1], where or str(p.parent)  # drop the "# WxD: " prefix
        mean = [ln for ln in lines if ln.startswith("mean ")][0].split()
        out[(w, d)] = (float(mean[1]), float(mean[2]), float(mean[3]))
    return out, header, where


def model_for(arch, width, depth, models_dir, d):
    latent = 12 if arch == "neural" else 4
    fitted = pathlib.Path(models_dir or "-") / f"{arch}_{width}x{depth}_l{latent}.safetensors"
    if fitted.exists():
        return str(fitted), True
    _, model = random_model(arch, latent=latent, width=width, depth=depth)
    path = f"{d}/{arch}{width}x{depth}.safetensors"
    model.save(path)
    return path, False


def network_bytes(model) -> int:
    """float32 bytes of the shared network (every tensor but the per-material ones)."""
    return FLOAT * sum(int(np.asarray(v).size) for k, v in model.tensors.items() if not k.startswith("materials."))


def material_bytes(model) -> int:
    """float32 bytes one material holds: analytic parameters (kd, eta, alpha), latent code and, with
    material output layers, its head (6 x width + 6)."""
    return FLOAT * sum(int(np.asarray(v)[0].size) for k, v in model.tensors.items() if k.startswith("materials."))


def rgl_accuracy(path):
    """Mean SMAPE and cMAE over the five raw RGL rows (CONVENTIONS protocol), hybrid and f_a."""
    from hybridbrdf.evaluate.evaluation import evaluate

    model = hb.load_model(path)
    sources = [hb.open_source(str(p)) for p in sorted((ROOT.parent / "shared" / "data" / "rgl").glob("*.bsdf"))]
    rows = evaluate(model, sources)
    return {k: float(np.mean([r[k] for r in rows])) for k in ("smape", "cmae", "smape_analytic", "cmae_analytic")}


RGL_NAMES = ("cc_ibiza_sunset_rgb", "cg_sunflower_rgb", "colodur_napoli_4f_rgb", "paper_white_rgb",
             "vch_golden_yellow_rgb")


def alternatives(n_pairs=1_000_000, seed=7):
    """The representations a user would pick instead, for each of the five raw RGL
    measurements: the measurement tabulated in the MERL layout (nearest-cell lookup,
    _core.MerlTable) and its published NBRDF network (_core.NbrdfNetwork). Returns
    {name: (C++ object, mean SMAPE, mean cMAE)} over the five, scored like the models
    (CONVENTIONS protocol), and the objects of the first material for timing."""
    from hybridbrdf.evaluate.metrics import cmae, metric_directions, smape
    from hybridbrdf.sources.merl import MERL_DIMS, MERL_SCALES, MERLSource, _evaluate_at_nodes
    from hybridbrdf.sources.nbrdf import open_nbrdf

    wi, wo = metric_directions(n_pairs, seed)
    wi32, wo32 = wi.astype(np.float32), wo.astype(np.float32)
    scores = {"MERL-layout table": [], "NBRDF network": []}
    first = {}
    data = ROOT.parent / "shared" / "data"
    for name in RGL_NAMES:
        src = hb.open_source(str(data / "rgl" / f"{name}.bsdf"))
        ref = src.eval(wi, wo)
        # Tabulated at the MERL nodes; nodes below the horizon are missing and filled from
        # their nearest measured neighbours, as the MERL reader does.
        values, measurable = _evaluate_at_nodes(src.eval)
        raw = np.where(measurable[:, None], values / MERL_SCALES, -1.0).T.reshape(3, *MERL_DIMS)
        table = _core.MerlTable(MERLSource(raw, interpolation="nearest")._table.astype(np.float32))
        net = open_nbrdf(data / "nbrdf" / "rgl" / f"{name}.h5")
        network = _core.NbrdfNetwork([(k.T.astype(np.float32), b.astype(np.float32)) for _, k, b, _ in net.layers])
        for key, obj in (("MERL-layout table", table), ("NBRDF network", network)):
            f = obj.eval(wi32, wo32).astype(np.float64)
            scores[key].append((smape(ref, f), cmae(ref, f, wi[:, 2])))
            first.setdefault(key, obj)
    return {k: (first[k], float(np.mean([s[0] for s in v])), float(np.mean([s[1] for s in v])))
            for k, v in scores.items()}


def plot(rows, path_png, title, released_cmae=None):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(16, 4.4))
    for ax, key, label in ((axes[0], ("cpp", "avx2+fma"), "C++ batched, 1 core, AVX2"),
                           (axes[1], ("vk", "avx2"), "GLSL under lavapipe, 2 cores, AVX2")):
        for arch, marker in (("analytic", "s"), ("hybrid", "o"), ("neural", "^")):
            pts = [(1e9 / r[key[0]][key[1]], r["smape"], r["name"]) for r in rows
                   if r["arch"] == arch and r.get(key[0], {}).get(key[1]) and r.get("smape") is not None]
            if not pts:
                continue
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker=marker, linestyle="-" if arch != "analytic" else "",
                    label=arch)
            for x, y, name in pts:
                ax.annotate(name.split()[-1] if arch != "analytic" else "f_a", (x, y), textcoords="offset points",
                            xytext=(4, 4), fontsize=7)
        ax.set_xscale("log")
        ax.set_xlabel("ns per evaluation (" + label + ")")
        ax.set_ylabel("mean SMAPE (size sweep)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    # The five raw RGL rows: the fitted models against the alternatives, bytes per material noted.
    ax = axes[2]
    for r in rows:
        if "rgl" not in r or not r["cpp"].get("avx2+fma"):
            continue
        x, y = 1e9 / r["cpp"]["avx2+fma"], r["rgl"]["cmae"]
        ax.plot([x], [y], marker="o" if r["arch"] == "rgl" else "D", linestyle="")
        per_material = r["mat_bytes"] + r["net_bytes"] // r["materials"]
        ax.annotate(f"{r['name'].split(' (')[0][:24]}\n{per_material:,} B/material", (x, y), textcoords="offset points",
                    xytext=(4, 4), fontsize=7)
    if released_cmae is not None:
        ax.axhline(released_cmae, color="grey", linestyle="--", linewidth=1)
        ax.annotate("released model", (ax.get_xlim()[0], released_cmae), textcoords="offset points", xytext=(4, 3),
                    fontsize=7, color="grey")
    ax.set_xscale("log")
    ax.set_xlabel("ns per evaluation (C++, 1 core, AVX2)")
    ax.set_ylabel("mean cMAE, five raw RGL rows")
    ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path_png, dpi=120)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=1 << 20, help="direction pairs per measurement (default 2^20)")
    ap.add_argument("--models-dir", default="out/cost",
                    help="fitting campaign with compare_<mlp>.txt tables and fitted models (default out/cost; "
                         "without it the tables in results/ and random weights)")
    ap.add_argument("--rgl-models", default=RGL_MODELS,
                    help="comma-separated fitted RGL models to time and score on the five raw RGL rows "
                         f"(default {RGL_MODELS}; missing files are skipped)")
    ap.add_argument("--no-lavapipe", action="store_true", help="skip the GLSL-under-lavapipe columns")
    ap.add_argument("--out", default="", help="write OUT.txt (the table), OUT.json (its rows) and OUT.png (the plot)")
    args = ap.parse_args()
    n = args.pairs
    rng = np.random.default_rng(7)
    from hybridbrdf.evaluate.directions import cosine_hemisphere

    wi = cosine_hemisphere(rng, n).astype(np.float32)
    wo = cosine_hemisphere(rng, n).astype(np.float32)
    use_vk = not args.no_lavapipe and RUNNER.exists() and os.path.exists(LVP)
    all_cores = os.sched_getaffinity(0)
    core = sorted(all_cores)[0]
    smapes, campaign, where = campaign_smape(args.models_dir)
    peak = fma_peak_gflops(core)
    kernels = ["avx2+fma"] + (["avx512"] if _core.model_simd_path() == "avx512" else [])
    os.sched_setaffinity(0, {core})  # the C++ path on one core

    def cpp_rates(evaluate):
        rates = {}
        try:
            for k in kernels:
                _core.limit_model_simd(k)
                rates[k] = best_rate(evaluate, n, 7)
        finally:
            _core.limit_model_simd("avx512")
        return rates

    def shader_figures(model, fn, d, **options):
        spv = compile_shader(model, fn, d, **options)
        instr, fma = spirv_counts(spv, d)
        os.sched_setaffinity(0, all_cores)
        try:
            # The loops form: a sixteenth of the pairs (a few hundredths of a million per second before
            # its unroll hints, issue 56; the row stays comparable with the earlier tables).
            return lavapipe_rates(spv, n // 16 if options.get("mlp_form") == "loops" else n, d), instr, fma
        finally:
            os.sched_setaffinity(0, {core})

    rows = []
    with tempfile.TemporaryDirectory() as d:
        np.concatenate([wi, wo], axis=1).astype(np.float32).tofile(pathlib.Path(d) / "in.bin")

        def add(name, arch, model_path, fn="hbrdf_eval", smape=None, **options):
            model = hb.load_model(model_path)
            cpp = _core.Model(model_path)
            row = {"arch": arch, "name": name, "smape": smape, "flops": None, "vk": {}, "spirv": None,
                   "net_bytes": network_bytes(model), "mat_bytes": material_bytes(model)}
            if fn == "hbrdf_eval_analytic":
                p = model.analytic_params(0)
                row["cpp"] = {"avx2+fma": best_rate(lambda: hb.analytic_eval(wi, wo, p), n, 7)}
                row["net_bytes"], row["mat_bytes"] = 0, 8 * FLOAT  # kd, eta (RGB), alpha (2)
            elif not options:
                row["flops"] = cpp.flops_per_eval
                row["cpp"] = cpp_rates(lambda: cpp.eval(wi, wo, 0))
            else:
                row["cpp"] = {}
            if use_vk:
                row["vk"], instr, fma = shader_figures(model, fn, d, **options)
                row["spirv"] = None if options.get("mlp_form") == "loops" else (instr, fma)
            rows.append(row)
            return row

        path, _ = model_for("hybrid", 32, 3, args.models_dir, d)
        add("analytic (f_a)", "analytic", path, "hbrdf_eval_analytic", smapes.get((32, 3), (None,))[0])
        for arch in ("hybrid", "neural"):
            for width, depth in SIZES:
                path, _ = model_for(arch, width, depth, args.models_dir, d)
                s = smapes.get((width, depth))
                add(f"{arch} {width}x{depth}", arch, path, smape=(s[1] if arch == "hybrid" else s[2]) if s else None)
        if use_vk:  # the other code forms of the hybrid 32x2
            path, _ = model_for("hybrid", 32, 2, args.models_dir, d)
            for name, options in (("32x2 fp16 unrolled", {"precision": "fp16"}),
                                  ("32x2 fp32 loops", {"mlp_form": "loops"})):
                add("hybrid " + name, "form", path, **options)
        for p in [p for p in args.rgl_models.split(",") if p]:
            if not (ROOT / p).exists() and not pathlib.Path(p).exists():
                print(f"skipped {p}: no such file", file=sys.stderr)
                continue
            full = str(ROOT / p) if (ROOT / p).exists() else p
            m = hb.load_model(full)
            row = add(f"RGL {m.arch['width']}x{m.arch['depth']} {pathlib.Path(p).stem}", "rgl", full)
            row["rgl"] = rgl_accuracy(full)
            row["materials"] = len(m.materials)
        if (ROOT.parent / "shared" / "data" / "rgl").exists():
            for name, (obj, sm, cm) in alternatives().items():
                rows.append({"arch": "alternative", "name": name + " (one per material)", "smape": None, "flops": None,
                             "vk": {}, "spirv": None, "net_bytes": 0, "mat_bytes": obj.memory_bytes,
                             "cpp": {"avx2+fma": best_rate(lambda: obj.eval(wi, wo), n, 7)},
                             "rgl": {"smape": sm, "cmae": cm, "smape_analytic": float("nan"),
                                     "cmae_analytic": float("nan")}, "materials": 1})

    kernel_cols = " ".join(f"{'C++ ' + k[:6]:>11s} {'%peak':>6s}" for k in kernels)
    vk_cols = " ".join(f"{'vk ' + r:>9s}" for r in VK_RUNS)
    lines = [f"{n} cosine-weighted pairs; C++ batched on 1 core (kernels {', '.join(kernels)}; one-core FMA peak "
             f"{', '.join(f'{k} {peak[k]:.1f}' for k in kernels)} GFLOP/s measured by _core.fma_peak_gflops); GLSL under lavapipe, 64 invocations per workgroup, "
             f"{len(all_cores)} cores, host SIMD path and AVX2 only (GALLIUM_OVERRIDE_CPU_CAPS=avx)",
             f"SMAPE of the size sweep (mean over the campaign's materials, {where or 'none'}): "
             f"{campaign or 'no fitting campaign found'}",
             "M/s: million evaluations per second; SPIR-V: instructions per evaluation after spirv-opt -O (fma: fused "
             "multiply-adds among them); bytes: network (shared) + per material; collection: 54 materials",
             f"{'model':44s} {'FLOP/ev':>7s} {kernel_cols} {vk_cols} {'SPIR-V':>6s} {'fma':>5s} "
             f"{'net B':>7s} {'B/mat':>5s} {'54 mat B':>8s} {'SMAPE':>7s}"]
    for r in rows:
        fl = f"{r['flops']:7.0f}" if r["flops"] else f"{'-':>7s}"
        cols = []
        for k in kernels:
            rate = r["cpp"].get(k)
            pct = 100 * rate * r["flops"] / 1e9 / peak[k] if rate and r["flops"] else None
            cols.append((f"{rate / 1e6:11.2f}" if rate else f"{'-':>11s}") + " " +
                        (f"{pct:5.1f}%" if pct else f"{'-':>6s}"))
        vk = " ".join(f"{r['vk'][run] / 1e6:9.2f}" if r["vk"].get(run) else f"{'-':>9s}" for run in VK_RUNS)
        sp = f"{r['spirv'][0]:6d} {r['spirv'][1]:5d}" if r["spirv"] else f"{'-':>6s} {'-':>5s}"
        coll = r["net_bytes"] + 54 * r["mat_bytes"]
        sm = f"{r['smape']:7.4f}" if r["smape"] is not None else f"{'-':>7s}"
        lines.append(f"{r['name'][:44]:44s} {fl} {' '.join(cols)} {vk} {sp} {r['net_bytes']:7d} {r['mat_bytes']:5d} "
                     f"{coll:8d} {sm}")
    rgl = [r for r in rows if "rgl" in r]
    if rgl:
        from rgl_paper_comparison import PAPER

        ref = np.mean(list(PAPER.values()), axis=0)  # SMAPE, SMAPE f_a, cMAE, cMAE f_a of the released model
        lines.append(f"RGL models: mean over the five raw RGL rows, hybrid (f_a part); the released model: SMAPE "
                     f"{ref[0]:.4f} ({ref[1]:.4f}), cMAE {ref[2]:.5f} ({ref[3]:.5f})")
        for r in rgl:
            a = r["rgl"]
            fa = (f" ({a['smape_analytic']:.4f})", f" ({a['cmae_analytic']:.5f})") if r["arch"] == "rgl" else ("", "")
            lines.append(f"  {r['name']}: SMAPE {a['smape']:.4f}{fa[0]}, cMAE {a['cmae']:.5f}{fa[1]}; "
                         f"{r['mat_bytes'] + r['net_bytes'] // r['materials']:,} bytes per material")
        models = [r for r in rgl if r["arch"] == "rgl"]
        if len(models) == 2 and use_vk:
            lines.append(f"  lavapipe speed-up {models[1]['name']} / {models[0]['name']}: " + ", ".join(
                f"{run} {models[1]['vk'][run] / models[0]['vk'][run]:.2f}x" for run in VK_RUNS))
    text = "\n".join(lines)
    print(text)
    if args.out:
        pathlib.Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        pathlib.Path(args.out + ".txt").write_text(text + "\n")
        json_rows = [{k: v for k, v in r.items()} for r in rows]
        pathlib.Path(args.out + ".json").write_text(json.dumps({"title": lines[:2], "rows": json_rows}, indent=1) + "\n")
        from rgl_paper_comparison import PAPER

        plot(rows, args.out + ".png", lines[0][:160] + "\n" + lines[1][:160],
             float(np.mean([v[2] for v in PAPER.values()])))
        print(f"wrote {args.out}.txt, {args.out}.json and {args.out}.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
