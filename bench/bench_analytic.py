#!/usr/bin/env python3
"""Single-core throughput of the analytic BRDF f_a: evaluation and MIS sampling.

Paths, all measured in this one run on 2^20 cosine-weighted direction pairs:
  * C++ batched, native (cpp/tools/bench.cpp, built here if missing): SoA and
    AoS evaluation, MIS sampling; AVX2+FMA and the baseline kernels
  * C++ through the Python bindings (what a Python user gets)
  * PyTorch float32 (hybridbrdf.brdf.torch_brdf), one thread
  * NumPy float64 (the textbook transcription tests/python/textbook_reference.py)

The process is pinned to one core. Prints a table and the ratio of each path
to NumPy; --json writes the figures. Usage:

    python bench/bench_analytic.py [--pairs N] [--repeats R] [--json out/bench_analytic.json]
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import subprocess
import sys
import time

import numpy as np
import torch

import hybridbrdf as hb
from hybridbrdf import _core
from hybridbrdf.brdf import torch_brdf

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python"))  # the float64 textbook oracle the tests check against
from textbook_reference import sample_mis as numpy_sample_mis  # noqa: E402
from textbook_reference import textbook_fa as numpy_fa  # noqa: E402

TARGET_EVALS_PER_S = 50e6


def cpu_name() -> str:
    """The CPU's model name with its family and model numbers (a bare "AMD EPYC" names Zen 4
    and Zen 5 alike, whose AVX-512 throughput differs twofold)."""
    info = {}
    try:
        for line in open("/proc/cpuinfo"):
            key, _, value = line.partition(":")
            info.setdefault(key.strip(), value.strip())
            if not line.strip():
                break
    except OSError:
        pass
    name = info.get("model name") or platform.processor() or "unknown"
    if "cpu family" in info and "model" in info:
        name += f" (family {info['cpu family']}, model {info['model']})"
    return name


def best_rate(fn, n: int, repeats: int) -> float:
    fn()  # warm-up (allocations, lazy init)
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return n / best


def native_bench(n: int, repeats: int) -> dict:
    exe = ROOT / "build" / "hbrdf_bench"
    if not exe.exists():
        subprocess.run(["cmake", "-S", str(ROOT), "-B", str(ROOT / "build"), "-DCMAKE_BUILD_TYPE=Release"],
                       check=True, stdout=subprocess.DEVNULL)
        subprocess.run(["cmake", "--build", str(ROOT / "build"), "--target", "hbrdf_bench"], check=True,
                       stdout=subprocess.DEVNULL)
    out = subprocess.run([str(exe), str(n), str(repeats)], check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=1 << 20, help="direction pairs per timed call (default 2^20)")
    ap.add_argument("--repeats", type=int, default=7, help="timed repetitions; the best is kept (default 7)")
    ap.add_argument("--json", help="also write the figures to this JSON file")
    args = ap.parse_args()

    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    torch.set_num_threads(1)
    n, reps = args.pairs, args.repeats

    rng = np.random.default_rng(7)

    def cos_dirs(k):
        u = rng.random((k, 2))
        r, phi = np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
        return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u[:, 0])], axis=1)

    wi64, wo64, u64 = cos_dirs(n), cos_dirs(n), rng.random((n, 2))
    wi32, wo32, u32 = (a.astype(np.float32) for a in (wi64, wo64, u64))
    wi_soa, wo_soa = np.ascontiguousarray(wi32.T), np.ascontiguousarray(wo32.T)
    params = hb.AnalyticParams(kd=[0.3, 0.2, 0.1], eta=[1.5, 1.6, 1.7], alpha=(0.2, 0.4))
    core_p = params.to_core()
    t = {k: torch.tensor(v) for k, v in (("wi", wi32), ("wo", wo32), ("u", u32))}
    tp = [torch.tensor(v, dtype=torch.float32) for v in (params.kd, params.eta, params.alpha)]

    native = native_bench(n, reps)
    rates = {
        "eval": {
            "C++ SoA, native (" + native["simd"] + ")": native["eval_soa"],
            "C++ AoS, native (" + native["simd"] + ")": native["eval_aos"],
            "C++ SoA, native (baseline SSE2)": native["eval_soa_baseline"],
            "C++ SoA via bindings": best_rate(lambda: _core.eval_analytic_soa(wi_soa, wo_soa, core_p), n, reps),
            "C++ AoS via bindings": best_rate(lambda: _core.eval_analytic(wi32, wo32, core_p), n, reps),
        },
        "sample_mis": {
            "C++ AoS, native (" + native["simd"] + ")": native["sample_mis"],
            "C++ AoS, native (baseline SSE2)": native["sample_mis_baseline"],
            "C++ AoS via bindings": best_rate(lambda: _core.sample(wo32, u32, core_p, "mis"), n, reps),
        },
    }
    with torch.no_grad():
        rates["eval"]["PyTorch float32 (1 thread)"] = best_rate(
            lambda: torch_brdf.eval_analytic(t["wi"], t["wo"], *tp), n, reps)
        rates["sample_mis"]["PyTorch float32 (1 thread)"] = best_rate(
            lambda: torch_brdf.sample(t["wo"], t["u"], *tp, "mis"), n, reps)
    small = max(n // 8, 1)  # NumPy is slow; time a slice
    rates["eval"]["NumPy float64"] = best_rate(
        lambda: numpy_fa(wi64[:small], wo64[:small], params.kd, params.eta, params.alpha), small, max(reps // 2, 2))
    rates["sample_mis"]["NumPy float64"] = best_rate(
        lambda: numpy_sample_mis(wo64[:small], u64[:small], params.kd, params.eta, params.alpha), small,
        max(reps // 2, 2))

    print(f"machine: {cpu_name()}, 1 core pinned; simd path {native['simd']}; {n} cosine-weighted pairs, "
          f"best of {reps}; torch {torch.__version__}, numpy {np.__version__}")
    for op, table in rates.items():
        ref = table["NumPy float64"]
        print(f"\n{op:32s} {'M/s':>10s} {'x NumPy':>9s}")
        for name, r in sorted(table.items(), key=lambda kv: -kv[1]):
            print(f"{name:32s} {r / 1e6:10.2f} {r / ref:9.1f}")
    soa = native["eval_soa"]
    verdict = "meets" if soa >= TARGET_EVALS_PER_S else "MISSES"
    print(f"\nC++ batched SoA evaluation: {soa / 1e6:.1f} M evaluations/s on one core, {verdict} the "
          f"{TARGET_EVALS_PER_S / 1e6:.0f} M/s target; {soa / rates['eval']['NumPy float64']:.0f}x NumPy float64, "
          f"{soa / native['eval_soa_baseline']:.2f}x the baseline kernel")
    mis = native["sample_mis"]
    print(f"C++ batched MIS sampling (AoS): {mis / 1e6:.1f} M samples/s on one core, "
          f"{mis / native['sample_mis_baseline']:.2f}x the baseline kernel")
    if args.json:
        pathlib.Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        with open(args.json, "w") as fh:
            json.dump({"machine": cpu_name(), "pairs": n, "rates_per_s": rates, "native": native}, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
