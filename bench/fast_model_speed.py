#!/usr/bin/env python3
"""Lavapipe speed of a candidate model's generated GLSL against a baseline's, in one run
(the question: is a model as accurate as the released 32x2 also at least twice as fast in
GLSL as the project's 32x2? docs/BENCHMARKS.md, "Evaluation cost").

Lavapipe's throughput of one shader varies from one process to the next (docs/BENCHMARKS.md,
"Evaluation cost") by more than a single pair of runs can settle a 2x threshold with. So the
two shaders run alternately, ``--rounds`` lavapipe processes each, once on the host's own SIMD
path and once AVX2 only (``GALLIUM_OVERRIDE_CPU_CAPS=avx``); every round prints both rates and
their ratio, and the summary gives the median ratio and the ratio of the best rates. Each
shader is the default generated form (unrolled network, literal weights) for one material,
compiled by glslang and run by ``hbrdf_vk_runner`` over ``--pairs`` pairs; the SPIR-V
instruction count per evaluation (after ``spirv-opt -O``) is printed next to it, since lavapipe
is only a proxy for a GPU.

Two kernels (``--harness``): ``synthetic`` makes each pair in the shader from a hash of the
invocation index, as a renderer hands the BRDF directions it already holds in registers;
``buffer`` reads 6 floats per pair from a storage buffer (the same cosine-weighted pairs for
both shaders), the kernel of the conformance tests. Lavapipe turns those reads into per-lane,
bounds-checked scalar loads, a fixed cost (a sizeable share of the 32x2's time;
docs/BENCHMARKS.md, "Evaluation cost") that a GPU does not have and that shrinks every ratio;
each summary line gives the rate of the kernel without the BRDF (``hbrdf_harness_only``) so
that cost stays visible.
Accuracy is not measured here: ``bench/rgl_paper_comparison.py MODEL`` gives the five rows.

    python bench/fast_model_speed.py CANDIDATE [--baseline results/rgl54_hybrid_32x2_e09_120k_refit01.safetensors]
        [--material vch_golden_yellow_rgb.rgl] [--rounds 9] [--pairs 1048576] [--harness synthetic,buffer]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import statistics
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))

import hybridbrdf as hb  # noqa: E402
from bench_inference import LVP, RUNNER, VK_RUNS, compile_shader, lavapipe_rate, spirv_counts  # noqa: E402
from hybridbrdf.evaluate.directions import cosine_hemisphere

BASELINE = "results/rgl54_hybrid_32x2_e09_120k_refit01.safetensors"
HARNESSES = {"synthetic": "made in the shader from a hash of the invocation index (glsl/eval_synthetic.comp.j2)",
             "buffer": "read from a storage buffer, 6 floats each (glsl/eval.comp.j2)"}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("candidate", help="the model to time (.safetensors)")
    ap.add_argument("--baseline", default=BASELINE, help=f"the model it is compared with (default {BASELINE})")
    ap.add_argument("--material", default="vch_golden_yellow_rgb.rgl",
                    help="material both shaders are generated for (default vch_golden_yellow_rgb.rgl, the raw measurement)")
    ap.add_argument("--rounds", type=int, default=9, help="lavapipe processes per shader and SIMD path (default 9)")
    ap.add_argument("--pairs", type=int, default=1 << 20, help="direction pairs per dispatch (default 2^20)")
    ap.add_argument("--harness", default="synthetic,buffer", type=lambda v: v.split(","),
                    help="comma-separated kernels to time with: synthetic (pairs made in the shader) and/or buffer "
                         "(pairs read from a storage buffer); default synthetic,buffer")
    args = ap.parse_args()
    if args.rounds < 1 or args.pairs < 64:
        raise SystemExit("--rounds must be >= 1 and --pairs >= 64")
    if not args.harness or any(h not in HARNESSES for h in args.harness):
        raise SystemExit(f"--harness: expected a comma-separated subset of {', '.join(HARNESSES)}, got {','.join(args.harness)}")
    if not (RUNNER.exists() and os.path.exists(LVP)):
        raise SystemExit(f"needs {RUNNER} (cmake --build build) and lavapipe ({LVP})")
    rng = np.random.default_rng(7)
    wi, wo = (cosine_hemisphere(rng, args.pairs).astype(np.float32) for _ in range(2))
    with tempfile.TemporaryDirectory() as tmp:
        d = pathlib.Path(tmp)
        np.concatenate([wi, wo], axis=1).astype(np.float32).tofile(d / "in.bin")
        models = {tag: hb.load_model(path) for tag, path in (("baseline", args.baseline), ("candidate", args.candidate))}
        for tag, m in models.items():
            if args.material not in m.materials:
                raise SystemExit(f"{getattr(args, tag)}: no material {args.material!r} (pass --material)")
        for harness in args.harness:
            spv = {tag: compile_shader(m, "hbrdf_eval", d, material=args.material, tag=f"{tag}_{harness}",
                                       directions=harness) for tag, m in models.items()}
            bare = compile_shader(models["baseline"], "hbrdf_harness_only", d, material=args.material,
                                  tag=f"bare_{harness}", directions=harness)
            print(f"== pairs {HARNESSES[harness]}")
            for tag, m in models.items():
                instr, fma = spirv_counts(spv[tag], d)
                path = getattr(args, tag)
                print(f"{tag}: {path} ({m.arch['kind']} {m.arch['width']}x{m.arch['depth']}, latent {m.arch['latent']}); "
                      f"SPIR-V {instr} instructions per evaluation, {fma} fma")
            print(f"material {args.material}, {args.pairs} pairs, {args.rounds} alternating rounds; "
                  "M/s = million evaluations per second")
            for run, env in VK_RUNS.items():
                rates = {"baseline": [], "candidate": []}
                for k in range(args.rounds):
                    for tag in ("baseline", "candidate") if k % 2 == 0 else ("candidate", "baseline"):
                        rates[tag].append(lavapipe_rate(spv[tag], args.pairs, d, env))
                    b, c = rates["baseline"][-1], rates["candidate"][-1]
                    print(f"  {run:5s} round {k + 1}: baseline {b / 1e6:7.2f} M/s, candidate {c / 1e6:7.2f} M/s, "
                          f"ratio {c / b:.2f}x")
                ratios = [c / b for b, c in zip(rates["baseline"], rates["candidate"])]
                print(f"{harness} {run}: median ratio {statistics.median(ratios):.2f}x (min {min(ratios):.2f}x, max "
                      f"{max(ratios):.2f}x); best rates {max(rates['candidate']) / 1e6:.2f} / "
                      f"{max(rates['baseline']) / 1e6:.2f} M/s = {max(rates['candidate']) / max(rates['baseline']):.2f}x; "
                      f"the kernel without the BRDF {lavapipe_rate(bare, args.pairs, d, env) / 1e6:.1f} M/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
