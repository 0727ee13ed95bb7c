#!/usr/bin/env python3
"""Lavapipe throughput of the generated code in each shader dialect, GLSL, HLSL, Slang and WGSL,
for the released architecture (a hybrid 32x2, one material) and for its analytic part alone
(``hbrdf_eval_analytic``), on the same direction pairs (docs/CODEGEN_MEASURED.md, "Shader dialects:
Slang and WGSL against GLSL").

Two harnesses, each compared with GLSL inside itself:

- ``hbrdf_vk_runner`` (the harness of bench/bench_inference.py's GLSL figure): GLSL and HLSL
  compiled by glslangValidator, Slang by slangc (slangtorch's, ``-O0``, OpSource patched:
  tests/python/slang_wgsl_tools.py), each the kernel of glsl/eval.comp.j2 in its dialect, 64
  invocations per workgroup, pairs *read from a storage buffer* (6 floats each), as
  bench_inference's "GLSL under lavapipe" column; the time of one submit + fence wait, best of 7
  after a warm-up (``lavapipe_rate``).
- wgpu (wgpu-native, naga): the WGSL kernel, and the GLSL one twice: glslang's SPIR-V (the
  runner's GLSL file) through naga's SPIR-V front end, the reference of this harness, and the
  source (the generated code inlined, since naga's GLSL front end has no ``#include``) through
  naga's GLSL front end, which refuses it with wgpu 0.32.0 (the material constant, a struct with a
  ``float z[4]`` member, is "an invalid constant expression" to naga; the run prints the reason
  and leaves that row out); same buffers, same pairs; the time of one submit +
  ``wgpuDevicePoll(wait)`` (wgpu 0.32.0's ``on_submitted_work_done`` fails: its callback type does
  not match wgpu-native's), compile, upload and encoding excluded, best of 7 after a warm-up. naga
  re-emits SPIR-V for every input, so "GLSL SPIR-V via wgpu" is not the runner's SPIR-V: WGSL / GLSL
  inside wgpu is the fair WGSL figure; wgpu's absolute rate against the runner's is a different
  harness.

Every measurement is one process (lavapipe's rate varies by up to +-20% from one process to the
next): each round runs every (dialect, function) once, in an order reversed every other round, on
the host's own SIMD path and AVX2 only (``GALLIUM_OVERRIDE_CPU_CAPS=avx``, bench_inference.VK_RUNS);
the table gives the best rate of the rounds, its ratio to the best rate of the GLSL row of the same
harness, and the median and range of the per-round ratios. Each kernel's output (first round) is
compared with the runner's GLSL output: the largest relative difference where |f| > 1e-6 is printed.

    python bench/dialect_speed.py [--model results/rgl54_hybrid_32x2_e09_120k_refit01.safetensors]
        [--material vch_golden_yellow_rgb.rgl] [--pairs 1048576] [--rounds 5]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
sys.path.insert(0, str(ROOT / "tests" / "python"))

BASELINE = "results/rgl54_hybrid_32x2_e09_120k_refit01.safetensors"
FUNCTIONS = {"hybrid": "hbrdf_eval", "f_a": "hbrdf_eval_analytic"}
# (row name, harness, what it runs); the first row of each harness is its GLSL reference.
ROWS = [("GLSL", "runner", "glslangValidator -V"),
        ("HLSL", "runner", "glslangValidator -D -V (HLSL front end)"),
        ("Slang", "runner", "slangc -lang slang -O0"),
        ("GLSL SPIR-V via wgpu", "wgpu", "glslang's GLSL SPIR-V, naga SPIR-V front end"),
        ("GLSL via wgpu", "wgpu", "naga GLSL front end"),
        ("WGSL", "wgpu", "naga WGSL front end")]
REFERENCE = {"runner": "GLSL", "wgpu": "GLSL SPIR-V via wgpu"}
REPEAT = 7


# ---- the wgpu worker: one shader, one process ------------------------------------------------


def wgpu_worker(shader: str, kind: str, n: int, d: str) -> None:
    """Times one kernel under wgpu on lavapipe (run as its own process) and prints best_ms."""
    from slang_wgsl_tools import wgpu_device
    import wgpu

    device = wgpu_device()
    path = pathlib.Path(shader)
    code = path.read_bytes() if kind == "spirv" else path.read_text()
    module = device.create_shader_module(label="kernel.comp", code=code)
    pipeline = device.create_compute_pipeline(layout="auto", compute={"module": module, "entry_point": "main"})
    data = np.fromfile(f"{d}/in.bin", dtype=np.float32)[:6 * n]
    buf_in = device.create_buffer_with_data(data=data, usage=wgpu.BufferUsage.STORAGE)
    buf_out = device.create_buffer(size=4 * 3 * n, usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC)
    bind = device.create_bind_group(layout=pipeline.get_bind_group_layout(0),
                                    entries=[{"binding": 0, "resource": {"buffer": buf_in}},
                                             {"binding": 1, "resource": {"buffer": buf_out}}])
    groups = (n + 63) // 64
    assert groups <= 65535, "more than 65535 * 64 pairs"
    best = float("inf")
    for r in range(REPEAT + 1):  # the first dispatch warms up, as in hbrdf_vk_runner
        encoder = device.create_command_encoder()
        compute = encoder.begin_compute_pass()
        compute.set_pipeline(pipeline)
        compute.set_bind_group(0, bind)
        compute.dispatch_workgroups(groups, 1, 1)
        compute.end()
        commands = encoder.finish()
        t0 = time.perf_counter()
        device.queue.submit([commands])
        device._poll_wait()  # wgpuDevicePoll(wait): until the submitted work is done
        ms = (time.perf_counter() - t0) * 1000.0
        if r > 0:
            best = min(best, ms)
    np.frombuffer(device.queue.read_buffer(buf_out), dtype=np.float32).tofile(f"{d}/out_wgpu.bin")
    print(f"best_ms {best:.4f}")


def wgpu_rate(shader, kind, n, d, env):
    from bench_inference import LVP

    r = subprocess.run([sys.executable, __file__, "--wgpu-worker", str(shader), kind, str(n), str(d)],
                       capture_output=True, text=True, env=dict(os.environ, VK_DRIVER_FILES=LVP, **env))
    if r.returncode != 0:
        raise RuntimeError(f"wgpu worker failed on {shader}: {r.stderr[-3000:]}")
    ms = float([ln for ln in r.stdout.splitlines() if ln.startswith("best_ms")][0].split()[1])
    return n / (ms / 1000.0)


# ---- building the kernels --------------------------------------------------------------------


def build(model, material, fn, d: pathlib.Path, tag: str):
    """{row: (kind, path)} of the kernel of ``fn`` in every dialect (kind: spirv for the runner,
    wgsl / glsl / spirv for wgpu); None where a compiler refuses it (reason printed)."""
    from bench_inference import compile_shader
    from hybridbrdf.codegen.main import generate
    from hybridbrdf.codegen.literals import material_constant
    from shader_kernels import eval_compute_shader
    from slang_wgsl_tools import compile_slang

    const = material_constant(material)
    out = {}
    glsl_spv = compile_shader(model, fn, d, material=material, tag=f"{tag}_glsl")  # the bench_inference kernel
    out["GLSL"] = ("spirv", glsl_spv)
    out["GLSL SPIR-V via wgpu"] = ("spirv", glsl_spv)
    for target in ("hlsl", "slang"):
        (d / f"{tag}_model.{target}").write_text(generate(model, target, [material]))
        src = d / f"{tag}_kernel.{target}"
        src.write_text(eval_compute_shader(fn, const, f"{tag}_model.{target}", target=target))
        spv = d / f"{tag}_{target}.spv"
        if target == "hlsl":
            subprocess.run(["glslangValidator", "-D", "-V", "-e", "main", "-S", "comp", "--target-env", "vulkan1.1",
                            f"-I{d}", str(src), "-o", str(spv)], check=True, capture_output=True)
            out["HLSL"] = ("spirv", spv)
        else:
            compile_slang(src, spv, include_dir=d)
            out["Slang"] = ("spirv", spv)
    wgsl = generate(model, "wgsl", [material])
    src = d / f"{tag}_kernel.wgsl"
    src.write_text(eval_compute_shader(fn, const, f"{tag}_model.wgsl", target="wgsl", model_code=wgsl))
    out["WGSL"] = ("wgsl", src)
    # The GLSL kernel for naga's GLSL front end: the generated file inlined in place of #include.
    kernel = (d / f"{tag}_glsl.comp").read_text()
    code = (d / f"{tag}_glsl.glsl").read_text()
    kernel = kernel.replace("#extension GL_GOOGLE_include_directive : require\n", "")
    kernel = re.sub(r'#include "[^"]+"', lambda _: code, kernel)
    src = d / f"{tag}_inline.comp"
    src.write_text(kernel)
    out["GLSL via wgpu"] = ("glsl", src)
    return out


def spirv_instructions(spv, d):
    from bench_inference import spirv_counts

    try:
        return spirv_counts(spv, d)[0]
    except subprocess.CalledProcessError:
        return None


# ---- the machine -----------------------------------------------------------------------------


def machine_line() -> str:
    info = pathlib.Path("/proc/cpuinfo").read_text() if os.path.exists("/proc/cpuinfo") else ""

    def field(name):
        m = re.search(rf"^{name}\s*:\s*(.*)$", info, re.M)
        return m.group(1).strip() if m else "?"

    flags = set(field("flags").split())
    simd = [f for f in ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512vl", "avx512bw", "avx512_bf16") if f in flags]
    return (f"CPU {field('model name')} (family {field('cpu family')}, model {field('model')}), "
            f"{len(os.sched_getaffinity(0))} cores usable, SIMD flags {' '.join(simd)}; {platform.platform()}")


def lavapipe_version() -> str:
    try:
        r = subprocess.run(["dpkg-query", "-W", "-f", "${Version}", "mesa-vulkan-drivers"], capture_output=True,
                           text=True)
        mesa = r.stdout.strip() or "?"
    except FileNotFoundError:
        mesa = "?"
    import wgpu
    import wgpu.backends.wgpu_native as native

    return f"mesa-vulkan-drivers {mesa} (lavapipe); wgpu {wgpu.__version__} (wgpu-native {native.__version__})"


def llvmpipe_name(d, env):
    """The device string the runner prints (llvmpipe, LLVM version, vector width)."""
    from bench_inference import LVP, RUNNER

    spv = next(pathlib.Path(d).glob("*_glsl.spv"))
    r = subprocess.run([str(RUNNER), str(spv), f"{d}/in.bin", f"{d}/out.bin", "64", "3"], capture_output=True,
                       text=True, env=dict(os.environ, VK_DRIVER_FILES=LVP, **env))
    return [ln for ln in r.stdout.splitlines() if ln.startswith("device")][0].split(" ", 1)[1]


# ---- main ------------------------------------------------------------------------------------


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--wgpu-worker":
        wgpu_worker(sys.argv[2], sys.argv[3], int(sys.argv[4]), sys.argv[5])
        return 0
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", default=BASELINE, help=f"the model (default {BASELINE}, the released architecture)")
    ap.add_argument("--material", default="vch_golden_yellow_rgb.rgl",
                    help="its material (default vch_golden_yellow_rgb.rgl)")
    ap.add_argument("--pairs", type=int, default=1 << 20, help="direction pairs per dispatch (default 2^20)")
    ap.add_argument("--rounds", type=int, default=5, help="interleaved rounds per SIMD path (default 5)")
    ap.add_argument("--simd", default="host,avx2", type=lambda v: v.split(","),
                    help="lavapipe SIMD paths: host and/or avx2 (GALLIUM_OVERRIDE_CPU_CAPS=avx); default both")
    args = ap.parse_args()

    import hybridbrdf as hb
    from bench_inference import LVP, RUNNER, VK_RUNS, lavapipe_rate
    from hybridbrdf.evaluate.directions import cosine_hemisphere

    if args.rounds < 1 or not 64 <= args.pairs <= 65535 * 64:
        raise SystemExit("--rounds must be >= 1 and 64 <= --pairs <= 65535 * 64")
    if any(s not in VK_RUNS for s in args.simd):
        raise SystemExit(f"--simd: a subset of {','.join(VK_RUNS)}")
    if not (RUNNER.exists() and os.path.exists(LVP)):
        raise SystemExit(f"needs {RUNNER} (cmake --build build) and lavapipe ({LVP})")
    model_path = ROOT / args.model if (ROOT / args.model).exists() else pathlib.Path(args.model)
    model = hb.load_model(str(model_path))
    if args.material not in model.materials:
        raise SystemExit(f"{args.model}: no material {args.material!r} (pass --material)")
    n = args.pairs
    rng = np.random.default_rng(7)
    wi, wo = (cosine_hemisphere(rng, n).astype(np.float32) for _ in range(2))
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        d = pathlib.Path(tmp)
        np.concatenate([wi, wo], axis=1).astype(np.float32).tofile(d / "in.bin")
        shaders = {f: build(model, args.material, fn, d, f) for f, fn in FUNCTIONS.items()}
        instr = {(row, f): spirv_instructions(shaders[f][row][1], d)
                 for f in FUNCTIONS for row, harness, _ in ROWS if harness == "runner"}
        devices = {s: llvmpipe_name(d, VK_RUNS[s]) for s in args.simd}
        # Each wgpu kernel once on 64 pairs: a kernel naga refuses leaves the table with its reason.
        refused = {}
        for f in FUNCTIONS:
            for row, harness, _ in ROWS:
                if harness == "wgpu" and row not in refused:
                    try:
                        wgpu_rate(shaders[f][row][1], shaders[f][row][0], 64, d, {})
                    except RuntimeError as e:
                        reason = [ln.strip() for ln in str(e).splitlines() if "error" in ln.lower()]
                        refused[row] = reason[-1] if reason else str(e).splitlines()[-1]
        rows = [r for r in ROWS if r[0] not in refused]

        def measure(row, f, env):
            kind, path = shaders[f][row]
            harness = dict((r, h) for r, h, _ in ROWS)[row]
            if harness == "runner":
                rate = lavapipe_rate(path, n, d, env)
                out = np.fromfile(d / "out.bin", dtype=np.float32)
            else:
                rate = wgpu_rate(path, kind, n, d, env)
                out = np.fromfile(d / "out_wgpu.bin", dtype=np.float32)
            return rate, out

        # rates[simd][(row, f)] = [per round]
        rates = {s: {(row, f): [] for row, _, _ in rows for f in FUNCTIONS} for s in args.simd}
        agreement, reference = {}, {}
        order = [(row, f) for f in FUNCTIONS for row, _, _ in rows]
        for s in args.simd:
            for k in range(args.rounds):
                for row, f in (order if k % 2 == 0 else order[::-1]):
                    rate, out = measure(row, f, VK_RUNS[s])
                    rates[s][(row, f)].append(rate)
                    if row == "GLSL" and f not in reference:
                        reference[f] = out
                    if (row, f) not in agreement and f in reference:
                        ref = reference[f]
                        big = np.abs(ref) > 1e-6
                        agreement[(row, f)] = float(np.max(np.abs(out[big] - ref[big]) / np.abs(ref[big])))
                print(f"  {s} round {k + 1}/{args.rounds}: " + ", ".join(
                    f"{row} {f} {rates[s][(row, f)][-1] / 1e6:.2f}" for row, f in order), file=sys.stderr, flush=True)
    wall = time.perf_counter() - t_start

    lines = [f"dialect throughput under lavapipe: {args.model}, material {args.material} "
             f"({model.arch['kind']} {model.arch['width']}x{model.arch['depth']}), hybrid = hbrdf_eval, "
             f"f_a = hbrdf_eval_analytic",
             f"machine: {machine_line()}",
             f"lavapipe: {lavapipe_version()}; " + "; ".join(f"{s}: {devices[s]}" for s in args.simd)
             + " (avx2 = GALLIUM_OVERRIDE_CPU_CAPS=avx)",
             f"{n} cosine-weighted pairs read from a storage buffer (glsl/eval.comp.j2 in each dialect, 64 invocations "
             f"per workgroup); {args.rounds} interleaved rounds per SIMD path, one process per measurement, each "
             f"the best of {REPEAT} dispatches after a warm-up; M/s = best round; ratio = best rate / the best "
             f"rate of the GLSL row of the same harness (median and range of the per-round ratios); "
             f"{wall:.0f} s in all",
             "SPIR-V instructions per evaluation (runner rows, spirv-opt -O): " + ", ".join(
                 f"{row} {instr[(row, 'hybrid')]} / {instr[(row, 'f_a')]}" for row, h, _ in ROWS if h == "runner"),
             "max relative difference to the runner's GLSL output (|f| > 1e-6), hybrid / f_a: " + ", ".join(
                 f"{row} {agreement.get((row, 'hybrid'), float('nan')):.1e} / {agreement.get((row, 'f_a'), float('nan')):.1e}"
                 for row, _, _ in rows if row != "GLSL")]
    lines += [f"refused: {row} ({what}): {reason}" for row, what, reason in
              ((r, w, refused[r]) for r, _, w in ROWS if r in refused)]
    for s in args.simd:
        lines.append("")
        lines.append(f"{s} SIMD path{' (GALLIUM_OVERRIDE_CPU_CAPS=avx)' if s == 'avx2' else ''}:")
        lines.append("| dialect | harness | hybrid M/s | f_a M/s | hybrid / GLSL | f_a / GLSL |")
        lines.append("|---|---|---|---|---|---|")
        for row, harness, what in rows:
            cells = []
            for f in FUNCTIONS:
                cells.append(f"{max(rates[s][(row, f)]) / 1e6:.2f}")
            ratios = []
            for f in FUNCTIONS:
                ref = rates[s][(REFERENCE[harness], f)]
                r = [a / b for a, b in zip(rates[s][(row, f)], ref)]
                ratios.append("1 (reference)" if row == REFERENCE[harness] else
                              f"{max(rates[s][(row, f)]) / max(ref):.2f}x (median {statistics.median(r):.2f}x, "
                              f"{min(r):.2f}-{max(r):.2f})")
            lines.append(f"| {row} | {harness}: {what} | {cells[0]} | {cells[1]} | {ratios[0]} | {ratios[1]} |")
        cross = [f"{f} {statistics.median([a / b for a, b in zip(rates[s][(REFERENCE['wgpu'], f)], rates[s][('GLSL', f)])]):.2f}x"
                 for f in FUNCTIONS]
        lines.append(f"{REFERENCE['wgpu']} / GLSL in the runner (different harnesses, median of rounds): {', '.join(cross)}")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
