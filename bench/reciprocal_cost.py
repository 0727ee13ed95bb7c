#!/usr/bin/env python3
"""What reciprocity costs in evaluation time (issue 60, step 4): a ``hybrid`` model against a
``hybrid-reciprocal`` one of the same architecture (width, depth, latent, output layer, energy
tables), in one run, interleaved.

The reciprocal network's first layer reads 9 inputs (s = wi + wo and the six products of
d = wi - wo, model format 2) instead of 6 (wi, wo), plus 3 adds, 3 subtractions and 6 products
per evaluation; everything after the first layer is the same. Timed here:

- libhybridbrdf's batched ``Model.eval`` (one thread, the calling process pinned to one core),
  for each kernel the host has (``_core.limit_model_simd``: avx512, avx2+fma, baseline), and the
  scalar path (``Model.eval_scalar``, the tracer's, one pair at a time, on an eighth of the pairs);
  best of ``--repeats`` calls over ``--pairs`` pairs per round, in the thread's CPU time (the
  core is shared: CPU time leaves out the time the thread was preempted);
- the generated GLSL (default form) under lavapipe, the buffer kernel of the conformance tests
  (pairs read from a storage buffer), the host's SIMD path and AVX2 only
  (bench_inference.VK_RUNS), one lavapipe process per shader per round over ``--vk-pairs`` pairs
  (wall time: the runner's best of 8 dispatches; and CPU time: all the runner's threads with 16
  extra dispatches minus with none, which leaves out start, compile and preemption), with
  each shader's SPIR-V instruction count per evaluation (load-independent).

Each round times the plain model then the reciprocal one, the next round the other way round;
the summary gives the median of the per-round ratios (reciprocal time / plain time, > 1 is
slower) with their min and max. Rates: million evaluations per second. Costs do not depend on the
weights' values, so short fits serve (docs/RECIPROCITY.md).

    python bench/reciprocal_cost.py PLAIN RECIPROCAL [PLAIN RECIPROCAL ...] [--rounds 5]
        [--pairs 65536] [--vk-pairs 65536] [--repeats 15] [--no-lavapipe]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import resource
import subprocess
import statistics
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
sys.path.insert(0, str(ROOT / "tests" / "python"))  # shader_kernels, for bench_inference

import hybridbrdf as hb  # noqa: E402
from hybridbrdf import _core  # noqa: E402
from bench_inference import LVP, RUNNER, VK_RUNS, compile_shader, lavapipe_rate, spirv_counts  # noqa: E402
from hybridbrdf.evaluate.directions import cosine_hemisphere  # noqa: E402


def arch_key(model) -> tuple:
    """What must match between the two models for the comparison to be at equal architecture."""
    a = model.arch
    return tuple(a.get(k) for k in ("width", "depth", "latent", "output_layer", "activation", "energy_bound", "n_out"))


def summarise(label: str, pairs: list) -> str:
    """One line: per-round ratios of reciprocal to plain time, and the best rates."""
    ratios = [p / r for p, r in pairs]  # rate_plain / rate_reciprocal = time ratio
    plain, rec = max(p for p, _ in pairs), max(r for _, r in pairs)
    return (f"{label}: time ratio reciprocal/plain median {statistics.median(ratios):.3f} "
            f"(min {min(ratios):.3f}, max {max(ratios):.3f}, {len(ratios)} rounds); best rates plain "
            f"{plain / 1e6:.2f}, reciprocal {rec / 1e6:.2f} M/s")


def best_cpu_rate(fn, n: int, repeats: int) -> float:
    """Evaluations per CPU second of ``fn`` (best of ``repeats`` calls after a warm-up): on a core
    other processes share, the calling thread's CPU time excludes the time it was preempted."""
    fn()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.thread_time()
        fn()
        best = min(best, time.thread_time() - t0)
    return n / best


def cpp_rounds(paths, wi, wo, args, kernels):
    """Per kernel, the (plain, reciprocal) rate of every round."""
    models = [_core.Model(str(p)) for p in paths]
    out = {k: [] for k in kernels}
    try:
        for k_round in range(args.rounds):
            for k in kernels:
                _core.limit_model_simd("avx512" if k == "scalar" else k)
                order = (0, 1) if k_round % 2 == 0 else (1, 0)
                rate = {}
                for i in order:
                    if k == "scalar":  # the tracer's one-pair-at-a-time path, on an eighth of the pairs
                        m = len(wi) // 8
                        rate[i] = best_cpu_rate(lambda: models[i].eval_scalar(wi[:m], wo[:m], 0), m, args.repeats)
                    else:
                        rate[i] = best_cpu_rate(lambda: models[i].eval(wi, wo, 0), len(wi), args.repeats)
                out[k].append((rate[0], rate[1]))
    finally:
        _core.limit_model_simd("avx512")
    return out


def lavapipe_cpu_rate(spv, n: int, d, env, repeat: int = 16) -> float:
    """Evaluations per CPU second of lavapipe on ``spv``: the runner's CPU time (all its threads,
    getrusage of the children) with ``repeat`` extra dispatches of ``n`` pairs minus that with
    none, so process start, shader compile and transfers cancel and preemption does not count."""
    def cpu(r):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        subprocess.run([str(RUNNER), str(spv), f"{d}/in.bin", f"{d}/out.bin", str(n), "3", "--repeat", str(r)],
                       check=True, capture_output=True, env=dict(os.environ, VK_DRIVER_FILES=LVP, **env))
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        return (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    return repeat * n / max(cpu(repeat) - cpu(0), 1e-9)


def lavapipe_rounds(paths, args, d):
    """Per lavapipe run (VK_RUNS), the (plain, reciprocal) rate of every round."""
    spv = [compile_shader(hb.load_model(str(p)), "hbrdf_eval", d, tag=f"m{i}", directions="buffer")
           for i, p in enumerate(paths)]
    for p, f in zip(paths, spv):
        instr, fma = spirv_counts(f, d)
        print(f"  SPIR-V after spirv-opt -O: {instr} instructions per evaluation, {fma} fma ({p})")
    out = {run: [] for run in VK_RUNS}
    for k_round in range(args.rounds):
        for run, env in VK_RUNS.items():
            order = (0, 1) if k_round % 2 == 0 else (1, 0)
            rate = {i: lavapipe_rate(spv[i], args.vk_pairs, d, env) for i in order}
            out[run].append((rate[0], rate[1]))
            cpu = {i: lavapipe_cpu_rate(spv[i], args.vk_pairs, d, env) for i in order}
            out.setdefault(f"{run}, CPU time", []).append((cpu[0], cpu[1]))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("models", nargs="+", help="pairs of model files: PLAIN (hybrid) then RECIPROCAL (hybrid-reciprocal)")
    ap.add_argument("--rounds", type=int, default=5, help="interleaved rounds (default 5)")
    ap.add_argument("--pairs", type=int, default=1 << 16, help="direction pairs per C++ call (default 2^16)")
    ap.add_argument("--vk-pairs", type=int, default=1 << 16, help="direction pairs per lavapipe dispatch (default 2^16)")
    ap.add_argument("--repeats", type=int, default=15, help="C++ calls per round, the best kept (default 15)")
    ap.add_argument("--no-lavapipe", action="store_true", help="time the C++ batched path only")
    args = ap.parse_args()
    if len(args.models) % 2 or args.rounds < 1 or args.pairs < 64 or args.repeats < 1:
        raise SystemExit("expected pairs of models (PLAIN RECIPROCAL ...), --rounds >= 1, --pairs >= 64, --repeats >= 1")
    for plain, rec in zip(args.models[::2], args.models[1::2]):
        mp, mr = hb.load_model(plain), hb.load_model(rec)
        if mp.arch["kind"] != "hybrid" or mr.arch["kind"] != "hybrid-reciprocal":
            raise SystemExit(f"{plain}, {rec}: expected a hybrid then a hybrid-reciprocal model")
        if arch_key(mp) != arch_key(mr):
            raise SystemExit(f"{plain}, {rec}: architectures differ ({arch_key(mp)} vs {arch_key(mr)})")
    use_vk = not args.no_lavapipe
    if use_vk and not (RUNNER.exists() and os.path.exists(LVP)):
        raise SystemExit(f"needs {RUNNER} (cmake --build build) and lavapipe ({LVP}), or --no-lavapipe")
    kernels = (["avx512"] if _core.model_simd_path() == "avx512" else []) + ["avx2+fma", "baseline", "scalar"]
    rng = np.random.default_rng(7)
    wi, wo = (cosine_hemisphere(rng, max(args.pairs, args.vk_pairs)).astype(np.float32) for _ in range(2))
    cpus = sorted(os.sched_getaffinity(0))
    print(f"simd_path {hb.simd_path()}, model kernel {_core.model_simd_path()}; cores {cpus}; "
          f"load average {os.getloadavg()[0]:.1f}; {args.pairs} pairs, {args.rounds} interleaved rounds")
    with tempfile.TemporaryDirectory() as tmp:
        d = pathlib.Path(tmp)
        np.concatenate([wi, wo], axis=1)[:args.vk_pairs].astype(np.float32).tofile(d / "in.bin")
        for plain, rec in zip(args.models[::2], args.models[1::2]):
            a = hb.load_model(plain).arch
            name = f"{a['width']}x{a['depth']} latent {a['latent']} {a.get('output_layer', 'shared')} output layer"
            print(f"== {name}: {plain} vs {rec}")
            flops = [_core.Model(p).flops_per_eval for p in (plain, rec)]
            print(f"  network FLOPs per evaluation (2 per multiply-add): plain {flops[0]}, reciprocal {flops[1]}")
            for k, rows in cpp_rounds((plain, rec), wi[:args.pairs], wo[:args.pairs], args, kernels).items():
                print("  " + summarise(f"C++ {k}" if k == "scalar" else f"C++ batched {k}", rows))
            if use_vk:
                for run, rows in lavapipe_rounds((plain, rec), args, d).items():
                    print("  " + summarise(f"GLSL lavapipe {run}", rows))
            print(f"  load average now {os.getloadavg()[0]:.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
