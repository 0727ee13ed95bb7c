#!/usr/bin/env python3
"""Speed guard: the kernels' speed ratios, measured in one run, against floors (CI runs it).

A noisy shared machine cannot fake a ratio of two kernels timed in the same interleaved
rounds of one pinned process, so the guard compares kernels with each other, never with a
figure from another day. It builds a small native driver (bench/speed_guard/) against the
build tree's libhybridbrdf and the generated C++ header of a shipped model, runs it on one
core, prints every ratio with its floor and exits 1 when one is below its floor, naming the
ratio, the figure and the floor.

Each floor is the lowest of ten runs on the machine that docs/BENCHMARKS.md ("The speed guard
(CI)") names (`python bench/speed_guard.py --runs 10` prints them) less a margin for
run-to-run spread and for machines of the same kind with other caches. A floor guards what
its reason says: losing a kernel's vectorisation halves the first ratios; a scalar network
in the batched path collapses the model ratios.

HBRDF_SIMD=baseline (the library's process-wide cap) makes every kernel the baseline one:
then the guard must fail, and tests/python/test_speed_guard.py proves it does.

    python bench/speed_guard.py [--pairs N] [--rounds R] [--runs K] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from typing import Callable, List

ROOT = pathlib.Path(__file__).resolve().parents[1]
BUILD = ROOT / "build"
LIBRARY = BUILD / "libhybridbrdf.a"
MODEL = ROOT / "results" / "rgl54_hybrid_32x2_fast58k_exp_refit005.safetensors"
MATERIAL = "cc_ibiza_sunset_rgb.rgl"

@dataclass(frozen=True)
class Ratio:
    name: str
    value: Callable[[dict], float]
    floor: float
    why: str


def _ratio(a, b):
    return lambda r: r["rates"][a] / r["rates"][b]


# The figures in each reason: lowest / median of 10 runs, 2026-11-25, AMD EPYC Zen 5 (AVX-512 on
# 512-bit pipes), unless another machine is named; docs/BENCHMARKS.md ("The speed guard (CI)") keeps the table.
RATIOS: List[Ratio] = [
    Ratio("f_a eval SoA: AVX2+FMA / baseline kernel", _ratio("fa_soa", "fa_soa_baseline"), 1.6,
          "vectorised f_a, 8 lanes against 4 (2.01 / 2.04); a loop that stops vectorising gives ~1.0"),
    Ratio("f_a eval AoS: AVX2+FMA / baseline kernel", _ratio("fa_aos", "fa_aos_baseline"), 1.7,
          "the same kernel behind two vectorised transposes (2.11 / 2.14)"),
    Ratio("f_a MIS sampling: AVX2+FMA / baseline kernel", _ratio("mis", "mis_baseline"), 1.6,
          "vectorised sampling, both warps per lane and a polynomial sincos (2.14 / 2.17, 2026-11-26); "
          "a loop that stops vectorising gives ~1.0"),
    Ratio("hybrid batched: best kernel / baseline kernel", _ratio("model_batch", "model_batch_baseline"), 2.8,
          "register-blocked layers, AVX-512 where the CPU has it (5.85 / 5.95 on Zen 5; Zen 4's AVX-512 "
          "runs on 256-bit pipes: ~3.8 there); a network that leaves the blocked kernels gives ~1"),
    Ratio("hybrid batched: AVX2+FMA kernel / baseline kernel", _ratio("model_batch_avx2", "model_batch_baseline"),
          2.8, "the register-blocked AVX2 layers (3.54 / 3.60)"),
    Ratio("hybrid: batched (best kernel) / scalar path", _ratio("model_batch", "model_scalar"), 10.0,
          "the scalar path is what one-pair calls get (26.6 / 27.1 with AVX-512; ~16 with AVX2 alone)"),
    Ratio("hybrid: generated C++ header / library scalar path", _ratio("header", "model_scalar"), 0.85,
          "the header's loops form at the library's flags, one pair per call like the scalar path (1.11 / 1.13)"),
    Ratio("f_a eval SoA: evaluations per 1,000 AVX2 peak flops",
          lambda r: 1e3 * r["rates"]["fa_soa"] / (r["fma_peak_gflops"]["avx2_fma"] * 1e9), 1.1,
          "a slowdown of every f_a kernel alike, which the ratios above cannot see (1.40 / 1.43; Zen 4 1.43)"),
    Ratio("hybrid 32x2 batched, AVX2 kernel: fraction of the AVX2 FMA peak",
          lambda r: r["rates"]["model_batch_avx2"] * r["flops_per_eval"] / (r["fma_peak_gflops"]["avx2_fma"] * 1e9),
          0.45, "the 32x2 on AVX2 reaches 0.59-0.60 on Zen 5, 0.55 on Zen 4 (docs/BENCHMARKS.md)"),
]


def library_flags() -> List[str]:
    """The Release flags CMake compiles libhybridbrdf with: -O3 -DNDEBUG plus the target's
    PRIVATE options, read from CMakeLists.txt so that the guard (and tests/python/test_vectorisation.py)
    follow a change of them."""
    text = (ROOT / "CMakeLists.txt").read_text()
    m = re.search(r"target_compile_options\(hybridbrdf PRIVATE ([^)]*)\)", text)
    if not m:
        raise SystemExit("speed guard: CMakeLists.txt: libhybridbrdf's compile options not found")
    return ["-O3", "-DNDEBUG", "-std=c++17"] + m.group(1).split()


def build_library() -> None:
    """Configures and builds build/ (Release) when its libhybridbrdf is missing or stale."""
    subprocess.run(["cmake", "-S", str(ROOT), "-B", str(BUILD), "-DCMAKE_BUILD_TYPE=Release"], check=True,
                   stdout=subprocess.DEVNULL)
    subprocess.run(["cmake", "--build", str(BUILD), "--target", "hybridbrdf", "-j", str(os.cpu_count() or 1)],
                   check=True, stdout=subprocess.DEVNULL)


def build_driver(work: pathlib.Path) -> pathlib.Path:
    """The driver linked against the build tree's library and the model's generated header."""
    from hybridbrdf.codegen import generate, material_constant
    from hybridbrdf.model_file import load_model

    model = load_model(str(MODEL))
    (work / "model.h").write_text(generate(model, "cpp", materials=[MATERIAL], model_path=str(MODEL)))
    flags = library_flags()
    header_obj = work / "header_kernel.o"
    subprocess.run(["g++", *flags, "-include", str(work / "model.h"),
                    f"-DHBRDF_GUARD_MATERIAL={material_constant(MATERIAL)}", "-c",
                    str(ROOT / "bench/speed_guard/header_kernel.cpp"), "-o", str(header_obj)], check=True)
    exe = work / "speed_guard_driver"
    subprocess.run(["g++", *flags, "-I", str(ROOT / "cpp/include"), str(ROOT / "bench/speed_guard/driver.cpp"),
                    str(header_obj), str(LIBRARY), "-o", str(exe)], check=True)
    return exe


def material_index() -> int:
    from hybridbrdf.model_file import load_model

    names = list(load_model(str(MODEL)).materials)
    return names.index(MATERIAL)


def run_driver(exe: pathlib.Path, pairs: int, rounds: int) -> dict:
    core = sorted(os.sched_getaffinity(0))[0]
    r = subprocess.run([str(exe), str(MODEL), str(material_index()), str(pairs), str(rounds)], check=True,
                       capture_output=True, text=True, preexec_fn=lambda: os.sched_setaffinity(0, {core}))
    return json.loads(r.stdout)


def evaluate(run: dict) -> List[dict]:
    return [{"name": q.name, "value": q.value(run), "floor": q.floor, "why": q.why} for q in RATIOS]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=1 << 18, help="direction pairs per timed call (default 2^18)")
    ap.add_argument("--rounds", type=int, default=9, help="interleaved timed rounds; each kernel's best is kept (default 9)")
    ap.add_argument("--runs", type=int, default=1,
                    help="driver processes; with more than one, prints each ratio's lowest and median (to set floors)")
    ap.add_argument("--json", help="also write the runs and ratios to this JSON file")
    args = ap.parse_args()
    if args.pairs < 1024 or args.rounds < 1 or args.runs < 1:
        ap.error("--pairs must be >= 1024, --rounds and --runs >= 1")

    if not LIBRARY.exists():
        build_library()
    else:  # cheap when up to date; rebuilds after a source change so that the guard times this tree
        subprocess.run(["cmake", "--build", str(BUILD), "--target", "hybridbrdf"], check=True, stdout=subprocess.DEVNULL)
    with tempfile.TemporaryDirectory(prefix="hbrdf_speed_guard_") as tmp:
        exe = build_driver(pathlib.Path(tmp))
        runs = [run_driver(exe, args.pairs, args.rounds) for _ in range(args.runs)]

    first = runs[0]
    print(f"speed guard: {first['pairs']} pairs, best of {first['rounds']} interleaved rounds, 1 pinned core; "
          f"kernels {first['simd']} (f_a) / {first['model_simd']} (model); model {MODEL.name} [{MATERIAL}]; "
          f"FMA peak avx2 {first['fma_peak_gflops']['avx2_fma']:.1f} / avx512 {first['fma_peak_gflops']['avx512']:.1f} GFLOP/s")
    print("rates (M/s): " + ", ".join(f"{k} {v / 1e6:.2f}" for k, v in first["rates"].items()))
    results = [evaluate(r) for r in runs]
    failures = []
    print(f"\n{'ratio':62s} {'value':>7s} {'floor':>6s}" + (f" {'lowest':>7s} {'median':>7s}" if len(runs) > 1 else ""))
    for i, q in enumerate(RATIOS):
        values = sorted(res[i]["value"] for res in results)
        low, med = values[0], values[len(values) // 2]
        ok = low >= q.floor
        extra = f" {low:7.3f} {med:7.3f}" if len(runs) > 1 else ""
        print(f"{q.name:62s} {results[0][i]['value']:7.3f} {q.floor:6.2f}{extra}  {'ok' if ok else 'BELOW FLOOR'}")
        if not ok:
            failures.append(f"{q.name} = {low:.3f}, below its floor {q.floor} ({q.why})")
    if args.json:
        pathlib.Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        pathlib.Path(args.json).write_text(json.dumps({"runs": runs, "ratios": results}, indent=2))
    for f in failures:
        print(f"speed guard: FAILED: {f}", file=sys.stderr)
    if not failures:
        print(f"\nspeed guard: all {len(RATIOS)} ratios at or above their floors")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
