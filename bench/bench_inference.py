#!/usr/bin/env python3
"""What accuracy costs in time: evaluation throughput of the analytic model and of
hybrid and neural models at 16x2 .. 64x3, on the C++ batched path (one core) and
as generated GLSL under lavapipe (both cores), measured in one run.

Models here have random weights (throughput does not depend on the values);
pass --models to add SMAPE columns from fitted model files instead.

    python bench/bench_inference.py [--pairs 1048576] [--no-lavapipe]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python"))

import hybridbrdf as hb  # noqa: E402
from hybridbrdf import _core  # noqa: E402
from hybridbrdf.codegen import generate, material_constant  # noqa: E402
from test_model_file import make_model  # noqa: E402

RUNNER = ROOT / "build" / "hbrdf_vk_runner"
LVP = "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json"
SIZES = [(16, 2), (16, 3), (32, 2), (32, 3), (64, 2), (64, 3)]

WRAP = """#version 450
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer In { float data_in[]; };
layout(std430, binding = 1) writeonly buffer Out { float data_out[]; };
#include "model.glsl"
void main() {
    uint i = gl_GlobalInvocationID.x;
    vec3 wi = vec3(data_in[6 * i], data_in[6 * i + 1], data_in[6 * i + 2]);
    vec3 wo = vec3(data_in[6 * i + 3], data_in[6 * i + 4], data_in[6 * i + 5]);
    vec3 f = FN(wi, wo, MAT);
    data_out[3 * i] = f.x; data_out[3 * i + 1] = f.y; data_out[3 * i + 2] = f.z;
}
"""


def best_rate(fn, n, repeats=5):
    fn()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return n / best


def lavapipe_rate(model, fn, n, wi, wo, d):
    (pathlib.Path(d) / "model.glsl").write_text(generate(model, "glsl", [model.materials[0]]))
    src = pathlib.Path(d) / "w.comp"
    src.write_text(WRAP.replace("FN", fn).replace("MAT", material_constant(model.materials[0])))
    spv = pathlib.Path(d) / "w.spv"
    subprocess.run(["glslangValidator", "-V", "--target-env", "vulkan1.1", f"-I{d}", str(src), "-o", str(spv)],
                   check=True, capture_output=True)
    np.concatenate([wi, wo], axis=1).astype(np.float32).tofile(pathlib.Path(d) / "in.bin")
    r = subprocess.run([str(RUNNER), str(spv), f"{d}/in.bin", f"{d}/out.bin", str(n), "3", "--repeat", "5"],
                       check=True, capture_output=True, text=True, env=dict(os.environ, VK_DRIVER_FILES=LVP))
    ms = float([ln for ln in r.stdout.splitlines() if ln.startswith("best_ms")][0].split()[1])
    return n / (ms / 1000.0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=1 << 20)
    ap.add_argument("--no-lavapipe", action="store_true")
    args = ap.parse_args()
    n = args.pairs
    rng = np.random.default_rng(7)
    from hybridbrdf.metrics import cosine_hemisphere

    wi = cosine_hemisphere(rng, n).astype(np.float32)
    wo = cosine_hemisphere(rng, n).astype(np.float32)
    use_vk = not args.no_lavapipe and RUNNER.exists() and os.path.exists(LVP)
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})  # the C++ path on one core
    print(f"{n} cosine-weighted pairs; C++ batched on 1 core ({_core.simd_path()}); GLSL under lavapipe, "
          f"64 invocations per workgroup, all cores")
    print(f"{'model':22s} {'FLOP/eval':>9s} {'C++ M/s':>9s} {'GFLOP/s':>8s} {'lavapipe M/s':>13s}")
    with tempfile.TemporaryDirectory() as d:
        p = hb.AnalyticParams(kd=0.3, eta=1.5, alpha=(0.2, 0.3))
        rate = best_rate(lambda: hb.analytic_eval(wi, wo, p), n)
        _, any_model = make_model("hybrid", width=16, depth=2)
        any_model.save(f"{d}/a.safetensors")
        any_model = hb.load_model(f"{d}/a.safetensors")
        vk = ""
        if use_vk:
            os.sched_setaffinity(0, set(range(os.cpu_count())))
            vk = f"{lavapipe_rate(any_model, 'hbrdf_eval_analytic', n, wi, wo, d) / 1e6:13.2f}"
            os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
        print(f"{'analytic (f_a)':22s} {'-':>9s} {rate / 1e6:9.2f} {'-':>8s} {vk}")
        for arch in ("hybrid", "neural"):
            for width, depth in SIZES:
                _, model = make_model(arch, latent=12 if arch == "neural" else 4, width=width, depth=depth)
                path = f"{d}/{arch}{width}x{depth}.safetensors"
                model.save(path)
                cpp = _core.Model(path)
                rate = best_rate(lambda: cpp.eval(wi, wo, 0), n)
                flops = cpp.flops_per_eval
                vk = ""
                if use_vk:
                    os.sched_setaffinity(0, set(range(os.cpu_count())))
                    vk = f"{lavapipe_rate(hb.load_model(path), 'hbrdf_eval', n, wi, wo, d) / 1e6:13.2f}"
                    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
                print(f"{arch + f' {width}x{depth}':22s} {flops:9.0f} {rate / 1e6:9.2f} {rate * flops / 1e9:8.2f} {vk}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
