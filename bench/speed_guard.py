#!/usr/bin/env python3
"""Speed guard: the kernels' instructions per evaluation, counted under callgrind, against floors (CI runs it).

A guard must judge the code, not the CPU. The ratio of an 8-lane kernel's speed to a 4-lane
one's is a property of the core as much as of the code (2.0-2.2 on AMD Zen 5, 1.4-1.7 on an
Intel Xeon with AVX-512 for the same build), so timed floors set on one vendor fail on the other.
Instructions retired per evaluation are not: they depend on the compiled code and on the
instruction set the library dispatches to, and callgrind (valgrind) counts them exactly and
reports the same CPU features (AVX2+FMA, no AVX-512) on every x86-64 host. A kernel that stops
vectorising executes several times the instructions of its vector form; a kernel that becomes
slower everywhere alike executes more instructions per evaluation. The guard builds a small
native driver (bench/speed_guard/) against a build tree's libhybridbrdf and the generated C++
header of a shipped model, counts each kernel on N and 2N pairs (the difference over N is the
steady-state cost; set-up and loop remainders cancel), prints every ratio with its floor and
exits 1 when one is below its floor, naming the ratio, the figure and the floor.

Each floor is the figure on the reference build (GCC 12.2, Debian 12; the same on every CPU)
less a margin for compiler and library updates, and well above what the regression it exists
for gives: tests/python/test_speed_guard.py rebuilds the library with the struct-return
regression that once stopped f_a's loop vectorising, and runs the guard with HBRDF_SIMD=baseline
(the library's process-wide cap: every kernel the baseline one); both must fail.

    python bench/speed_guard.py [--pairs N] [--source DIR] [--build DIR | --library FILE] [--json out.json]
    python bench/speed_guard.py --timed [--runs K]     # the timed ratios: benchmark figures, no floors
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from typing import Callable, Dict, List

ROOT = pathlib.Path(__file__).resolve().parents[1]
MODEL = ROOT / "results" / "rgl54_hybrid_32x2_fast58k_exp_refit005.safetensors"
MATERIAL = "cc_ibiza_sunset_rgb.rgl"


@dataclass(frozen=True)
class Ratio:
    name: str
    value: Callable[[dict], float]
    floor: float
    why: str


def _fewer(kernel, reference):
    """How many times fewer instructions per evaluation ``kernel`` executes than ``reference``."""
    return lambda r: r["instructions"][reference] / r["instructions"][kernel]


# Reference figures (instructions per evaluation, callgrind 3.19, GCC 12.2, Debian 12), the same
# on Intel Xeon (AVX-512) and AMD EPYC Zen 5 hosts; docs/BENCHMARKS.md ("The speed guard (CI)")
# keeps the table with the regressions' figures.
RATIOS: List[Ratio] = [
    Ratio("f_a eval SoA: baseline / AVX2+FMA kernel instructions", _fewer("fa_soa", "fa_soa_baseline"), 2.5,
          "8 vectorised lanes with FMA against 4 without (3.70); with the struct-return regression that "
          "stopped the loop vectorising 1.38, with HBRDF_SIMD=baseline 1.0"),
    Ratio("f_a eval AoS: baseline / AVX2+FMA kernel instructions", _fewer("fa_aos", "fa_aos_baseline"), 2.3,
          "the same kernel behind two vectorised transposes (3.25; struct-return regression 1.43)"),
    Ratio("f_a MIS sampling: baseline / AVX2+FMA kernel instructions", _fewer("mis", "mis_baseline"), 2.5,
          "vectorised sampling, both warps per lane and a polynomial sincos (3.73; struct-return regression 1.33); a loop "
          "that stops vectorising gives ~1"),
    Ratio("hybrid batched: baseline / AVX2+FMA kernel instructions", _fewer("model_batch_avx2", "model_batch_baseline"),
          3.2, "register-blocked AVX2 layers (4.34); a network that leaves the blocked kernels gives ~1"),
    Ratio("hybrid: scalar path / batched kernel instructions", _fewer("model_batch", "model_scalar"), 11.0,
          "the scalar path is what one-pair calls get (16.3; 3.8 with baseline kernels); callgrind's CPU has "
          "no AVX-512, so the batched kernel is the AVX2 one here"),
    Ratio("hybrid: library scalar path / generated C++ header instructions", _fewer("header", "model_scalar"), 1.15,
          "the header's loops form at the library's flags, one pair per call like the scalar path (1.49)"),
    Ratio("f_a eval SoA, AVX2+FMA kernel: evaluations per 1,000 instructions",
          lambda r: 1e3 / r["instructions"]["fa_soa"], 29.0,
          "a slowdown of every f_a kernel alike, which the ratios above cannot see (38.2; struct-return "
          "regression 5.4)"),
    Ratio("hybrid 32x2 batched, AVX2+FMA kernel: flops per instruction",
          lambda r: r["flops_per_eval"] / r["instructions"]["model_batch_avx2"], 4.2,
          "the register-blocked layers keep the instruction stream mostly 8-wide FMAs (5.28; struct-return "
          "regression 4.03, whose f_a rows stop vectorising; baseline 1.22); a slowdown of every model "
          "kernel alike lowers it"),
    Ratio("textured, pure texels: uniform / textured batched instructions", _fewer("svbrdf_pure", "model_batch"), 0.7,
          "pure texels of a plain layer run the uniform kernel in place, the lookup one byte per pair (0.83); "
          "the sorted per-lane path that preceded it (b06c4a7) 0.445"),
    Ratio("textured, two layers at every pair: 2 x uniform / textured batched instructions",
          lambda r: 2 * r["instructions"]["model_batch"] / r["instructions"]["svbrdf_mixed"], 0.55,
          "each layer through its material's uniform kernel on its gathered pairs (0.70); the sorted per-lane "
          "path it replaced (b06c4a7) 0.442"),
]


def library_flags(source: pathlib.Path = ROOT) -> List[str]:
    """The Release flags CMake compiles libhybridbrdf with: -O3 -DNDEBUG plus the target's
    PRIVATE options, read from CMakeLists.txt so that the guard (and tests/python/test_vectorisation.py)
    follow a change of them."""
    text = (source / "CMakeLists.txt").read_text()
    m = re.search(r"target_compile_options\(hybridbrdf PRIVATE ([^)]*)\)", text)
    if not m:
        raise SystemExit(f"speed guard: {source / 'CMakeLists.txt'}: libhybridbrdf's compile options not found")
    return ["-O3", "-DNDEBUG", "-std=c++17"] + m.group(1).split()


def build_library(source: pathlib.Path, build: pathlib.Path) -> pathlib.Path:
    """Configures (when needed) and builds ``build`` (Release) from ``source``; returns its libhybridbrdf.a.
    Cheap when up to date; rebuilds after a source change so that the guard measures this tree."""
    if not (build / "CMakeCache.txt").exists():
        # A folder of the guard's own (another tree's, a test's) builds the library alone; this
        # checkout's build/ keeps the project's defaults, since scripts/test.sh's ctest reuses it.
        lean = [] if build == ROOT / "build" else [
            "-DHBRDF_BUILD_TESTS=OFF", "-DHBRDF_BUILD_PYTHON=OFF", "-DHBRDF_BUILD_RENDERER=OFF"]
        subprocess.run(["cmake", "-S", str(source), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release", *lean],
                       check=True, stdout=subprocess.DEVNULL)
    subprocess.run(["cmake", "--build", str(build), "--target", "hybridbrdf", "-j", str(os.cpu_count() or 1)],
                   check=True, stdout=subprocess.DEVNULL)
    return build / "libhybridbrdf.a"


def build_driver(work: pathlib.Path, source: pathlib.Path = ROOT, library: pathlib.Path | None = None) -> pathlib.Path:
    """The driver linked against ``library`` (default: ``source``/build's) and the model's generated header."""
    from hybridbrdf.codegen.main import generate
    from hybridbrdf.codegen.literals import material_constant
    from hybridbrdf.model.file import load_model

    library = library or source / "build" / "libhybridbrdf.a"
    model = load_model(str(MODEL))
    (work / "model.h").write_text(generate(model, "cpp", materials=[MATERIAL], model_path=str(MODEL)))
    flags = library_flags(source)
    header_obj = work / "header_kernel.o"
    subprocess.run(["g++", *flags, "-include", str(work / "model.h"),
                    f"-DHBRDF_GUARD_MATERIAL={material_constant(MATERIAL)}", "-c",
                    str(ROOT / "bench/speed_guard/header_kernel.cpp"), "-o", str(header_obj)], check=True)
    exe = work / "speed_guard_driver"
    subprocess.run(["g++", *flags, "-I", str(source / "cpp/include"), str(ROOT / "bench/speed_guard/driver.cpp"),
                    str(header_obj), str(library), "-o", str(exe)], check=True)
    return exe


def material_index() -> int:
    from hybridbrdf.model.file import load_model

    return list(load_model(str(MODEL)).materials).index(MATERIAL)


def count_instructions(exe: pathlib.Path, pairs: int, work: pathlib.Path) -> dict:
    """Runs the driver's count mode under callgrind; returns its JSON with
    ``instructions`` = {kernel: instructions per evaluation (or sample)}."""
    if shutil.which("valgrind") is None:
        raise SystemExit("speed guard: valgrind is not installed (scripts/setup.sh installs it)")
    out = work / "callgrind.out"
    r = subprocess.run(["valgrind", "--tool=callgrind", "--instr-atstart=no", f"--callgrind-out-file={out}",
                        str(exe), str(MODEL), str(material_index()), str(pairs), "0", "count"],
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"speed guard: the driver failed under callgrind (exit {r.returncode}):\n{r.stderr[-3000:]}")
    totals: Dict[str, Dict[int, int]] = {}
    for dump in work.glob("callgrind.out.*"):
        text = dump.read_text()
        label = re.search(r"^desc: Trigger: Client Request: (\w+)@(\d+)$", text, re.M)
        total = re.search(r"^totals: (\d+)$", text, re.M)
        if label and total:
            totals.setdefault(label.group(1), {})[int(label.group(2))] = int(total.group(1))
    result = json.loads(r.stdout)
    result["instructions"] = {}
    for kernel, counts in totals.items():
        if set(counts) != {pairs, 2 * pairs}:
            raise SystemExit(f"speed guard: callgrind dumps of {kernel} incomplete: {sorted(counts)}")
        result["instructions"][kernel] = (counts[2 * pairs] - counts[pairs]) / pairs
    return result


def run_timed(exe: pathlib.Path, pairs: int, rounds: int) -> dict:
    core = sorted(os.sched_getaffinity(0))[0]
    r = subprocess.run([str(exe), str(MODEL), str(material_index()), str(pairs), str(rounds), "time"], check=True,
                       capture_output=True, text=True, preexec_fn=lambda: os.sched_setaffinity(0, {core}))
    return json.loads(r.stdout)


def cpu_name() -> str:
    try:
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


# The timed ratios: what the kernels' instruction counts buy on this core. Benchmark figures,
# printed for docs/BENCHMARKS.md, never judged: they follow the core's SIMD scaling.
TIMED = [
    ("f_a eval SoA: AVX2+FMA / baseline kernel", lambda r: r["rates"]["fa_soa"] / r["rates"]["fa_soa_baseline"]),
    ("f_a eval AoS: AVX2+FMA / baseline kernel", lambda r: r["rates"]["fa_aos"] / r["rates"]["fa_aos_baseline"]),
    ("f_a MIS sampling: AVX2+FMA / baseline kernel", lambda r: r["rates"]["mis"] / r["rates"]["mis_baseline"]),
    ("hybrid batched: best kernel / baseline kernel",
     lambda r: r["rates"]["model_batch"] / r["rates"]["model_batch_baseline"]),
    ("hybrid batched: AVX2+FMA kernel / baseline kernel",
     lambda r: r["rates"]["model_batch_avx2"] / r["rates"]["model_batch_baseline"]),
    ("hybrid: batched (best kernel) / scalar path", lambda r: r["rates"]["model_batch"] / r["rates"]["model_scalar"]),
    ("hybrid: generated C++ header / library scalar path", lambda r: r["rates"]["header"] / r["rates"]["model_scalar"]),
    ("f_a eval SoA: evaluations per 1,000 AVX2 peak flops",
     lambda r: 1e3 * r["rates"]["fa_soa"] / (r["fma_peak_gflops"]["avx2_fma"] * 1e9)),
    ("hybrid 32x2 batched, AVX2 kernel: fraction of the AVX2 FMA peak",
     lambda r: r["rates"]["model_batch_avx2"] * r["flops_per_eval"] / (r["fma_peak_gflops"]["avx2_fma"] * 1e9)),
]


def timed_main(exe: pathlib.Path, pairs: int, rounds: int, runs: int, json_path) -> int:
    results = [run_timed(exe, pairs, rounds) for _ in range(runs)]
    first = results[0]
    print(f"timed kernel ratios on {cpu_name()}: {first['pairs']} pairs, best of {first['rounds']} interleaved "
          f"rounds, 1 pinned core; kernels {first['simd']} (f_a) / {first['model_simd']} (model); FMA peak avx2 "
          f"{first['fma_peak_gflops']['avx2_fma']:.1f} / avx512 {first['fma_peak_gflops']['avx512']:.1f} GFLOP/s")
    print("rates (M/s): " + ", ".join(f"{k} {v / 1e6:.2f}" for k, v in first["rates"].items()))
    print(f"\n{'ratio (benchmark figure, not judged)':66s} {'lowest':>7s} {'median':>7s}")
    for name, value in TIMED:
        values = sorted(value(r) for r in results)
        print(f"{name:66s} {values[0]:7.3f} {values[len(values) // 2]:7.3f}")
    if json_path:
        pathlib.Path(json_path).parent.mkdir(parents=True, exist_ok=True)
        pathlib.Path(json_path).write_text(json.dumps({"cpu": cpu_name(), "runs": results}, indent=2))
    return 0


def guard_main(exe: pathlib.Path, pairs: int, work: pathlib.Path, json_path) -> int:
    run = count_instructions(exe, pairs, work)
    print(f"speed guard: instructions per evaluation under callgrind, {pairs} and {2 * pairs} pairs; kernels "
          f"{run['simd']} (f_a) / {run['model_simd']} (model); model {MODEL.name} [{MATERIAL}]")
    print("instructions per evaluation: " + ", ".join(f"{k} {v:.1f}" for k, v in run["instructions"].items()))
    failures = []
    print(f"\n{'ratio':66s} {'value':>7s} {'floor':>6s}")
    for q in RATIOS:
        value = q.value(run)
        ok = value >= q.floor
        print(f"{q.name:66s} {value:7.3f} {q.floor:6.2f}  {'ok' if ok else 'BELOW FLOOR'}")
        if not ok:
            failures.append(f"{q.name} = {value:.3f}, below its floor {q.floor} ({q.why})")
    if json_path:
        pathlib.Path(json_path).parent.mkdir(parents=True, exist_ok=True)
        pathlib.Path(json_path).write_text(json.dumps(
            {"run": run, "ratios": {q.name: q.value(run) for q in RATIOS}}, indent=2))
    for f in failures:
        print(f"speed guard: FAILED: {f}", file=sys.stderr)
    if not failures:
        print(f"\nspeed guard: all {len(RATIOS)} ratios at or above their floors")
    return 1 if failures else 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int,
                    help="direction pairs per counted call (default 4096; the counts run N and 2N) or per timed "
                         "call with --timed (default 2^18)")
    ap.add_argument("--source", type=pathlib.Path, default=ROOT,
                    help="the C++ source tree (CMakeLists.txt, cpp/) to build and measure (default: this checkout)")
    ap.add_argument("--build", type=pathlib.Path, help="its Release build folder (default: SOURCE/build)")
    ap.add_argument("--library", type=pathlib.Path,
                    help="measure this prebuilt libhybridbrdf.a (compiled from SOURCE's headers) instead of "
                         "building one; tests/python/test_speed_guard.py passes a copy of build/'s with the "
                         "kernels' translation units recompiled from a patched SOURCE")
    ap.add_argument("--timed", action="store_true",
                    help="time the kernels on one pinned core instead and print the timed ratios (benchmark "
                         "figures of this CPU; no floors)")
    ap.add_argument("--rounds", type=int, default=9, help="with --timed: interleaved rounds, each kernel's best kept")
    ap.add_argument("--runs", type=int, default=1, help="with --timed: driver processes (lowest and median printed)")
    ap.add_argument("--json", help="also write the measurements and ratios to this JSON file")
    args = ap.parse_args()
    pairs = args.pairs or (1 << 18 if args.timed else 4096)
    if pairs < 1024 or args.rounds < 1 or args.runs < 1:
        ap.error("--pairs must be >= 1024, --rounds and --runs >= 1")
    if args.library and args.build:
        ap.error("--library replaces --build: give one of them")
    if args.library and not args.library.is_file():
        ap.error(f"--library {args.library}: no such file")
    source = args.source.resolve()
    library = args.library.resolve() if args.library else build_library(source, (args.build or source / "build").resolve())
    with tempfile.TemporaryDirectory(prefix="hbrdf_speed_guard_") as tmp:
        exe = build_driver(pathlib.Path(tmp), source, library)
        if args.timed:
            return timed_main(exe, pairs, args.rounds, args.runs, args.json)
        return guard_main(exe, pairs, pathlib.Path(tmp), args.json)


if __name__ == "__main__":
    sys.exit(main())
