#!/usr/bin/env python3
"""What texturing costs in the generated GLSL under lavapipe (issue 48; docs/SVBRDF.md): a texel's
hbrdf_eval_layers (its four layer materials selected per pair, layer 0's kd decoded from 8-bit
sRGB by hbrdf_decode_srgb, glsl/layers.comp.j2) against hbrdf_eval of the base material's constant
(glsl/eval.comp.j2) and against the same kernel on pure texels without the decode (the base
material chosen at run time), in one process, best of 7 dispatches per kernel after a warm-up
(hbrdf_vk_runner --repeat 7), on lavapipe's host SIMD path.

The texels are bench/svbrdf_mixture.py's 512x512 material (three layers of
`results/rgl54_fast.safetensors`): per pair the weights of a texel, looked up in Python (the layers kernel
reads them from its input buffer: 17 floats per pair against eval's 6); then glsl/textured.comp.j2,
which reads uv per pair and looks the weights map and an sRGB kd map of layer 0 up itself
(bilinear). Pairs on pure texels, on the whole texture (texture order) and on mixed texels.

    python bench/svbrdf_glsl_cost.py [--model results/rgl54_fast.safetensors] [--pairs 262144] [--anatomy]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
sys.path.insert(0, str(ROOT / "tests" / "python"))

import hybridbrdf as hb  # noqa: E402
from hybridbrdf.codegen.literals import material_constant  # noqa: E402
from hybridbrdf.codegen.main import generate  # noqa: E402
from hybridbrdf.evaluate.metrics import metric_directions  # noqa: E402
from hybridbrdf.fit.painting import composite  # noqa: E402
from hybridbrdf.svbrdf.asset import SVBRDF  # noqa: E402
from hybridbrdf.svbrdf.decode import encode, png_channel  # noqa: E402

from helpers import RUNNER, compile_spirv  # noqa: E402
from shader_kernels import eval_compute_shader, render_shader  # noqa: E402
from svbrdf_mixture import LAYERS, SIZE, masks  # noqa: E402

LVP = "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json"


def rate(spv, rows, out_floats, work):
    np.ascontiguousarray(rows, dtype=np.float32).tofile(work / "in.bin")
    r = subprocess.run([str(RUNNER), str(spv), str(work / "in.bin"), str(work / "out.bin"), str(len(rows)),
                        str(out_floats), "--repeat", "7"], check=True, capture_output=True, text=True,
                       env=dict(os.environ, VK_DRIVER_FILES=LVP))
    ms = float([ln for ln in r.stdout.splitlines() if ln.startswith("best_ms")][0].split()[1])
    return len(rows) / (ms / 1000.0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", default=str(ROOT / "results" / "rgl54_fast.safetensors"))
    ap.add_argument("--pairs", type=int, default=1 << 18)
    ap.add_argument("--anatomy", action="store_true",
                    help="also time the map-reading kernel with its lookup replaced: weights zero but unknown to the "
                         "compiler (the four guarded layer evaluations stay), and weights the constant (1, 0, 0, 0)")
    args = ap.parse_args()
    model = hb.load_model(args.model)
    names = [n for n, _ in LAYERS]
    idx = [model.materials.index(n) for n in names]
    work = pathlib.Path(tempfile.mkdtemp(prefix="svbrdf_glsl_"))
    # One generated file holding the three layer materials (their constants in model order).
    chosen = [model.materials[i] for i in sorted(idx)]
    (work / "model.glsl").write_text(generate(model, "glsl", chosen))
    consts = [material_constant(n) for n in chosen]
    layer_of = {n: float(chosen.index(n)) for n in names}
    n = args.pairs
    wi, wo = (a.astype(np.float32) for a in metric_directions(n, 3))
    w = composite(masks())
    weights = np.concatenate([w, np.zeros((SIZE, SIZE, 1))], axis=2).astype(np.float32)
    sv = SVBRDF(model, names, (SIZE, SIZE), weights)
    full = np.concatenate([1 - w.sum(axis=2, keepdims=True), w], axis=2).reshape(-1, 3)
    rng = np.random.default_rng(0)
    kd0 = model.tensors["materials.kd"][model.index(names[0])]
    stored_kd = encode(kd0, png_channel("kd"), bits=8).astype(np.float32) / 255.0

    def rows_for(texels):
        t = np.sort(rng.choice(texels, n))
        uv = np.stack([(t % SIZE + 0.5) / SIZE, (t // SIZE + 0.5) / SIZE], axis=1)
        wt = sv.texels(uv, "nearest")["weight"]
        w4 = np.concatenate([wt, np.zeros((n, 1), np.float32)], axis=1)
        mats = np.tile([layer_of[names[0]], layer_of[names[1]], layer_of[names[2]], layer_of[names[0]]], (n, 1))
        return np.concatenate([wi, wo, w4, mats, np.tile(stored_kd, (n, 1))], axis=1).astype(np.float32), wt

    sets = {"pure texels": np.nonzero(full[:, 0] == 1)[0], "whole texture": np.arange(SIZE * SIZE),
            "mixed texels": np.nonzero(full.max(axis=1) < 0.99)[0]}
    src = work / "wrap.comp"
    src.write_text(eval_compute_shader("hbrdf_eval", material_constant(names[0]), "model.glsl", "glsl", n=n))
    uniform_spv = work / "uniform.spv"
    compile_spirv(src, uniform_spv, "glsl", include_dir=work)
    src.write_text(render_shader("layers.comp.glsl", include="model.glsl", materials=consts, n=n))
    layers_spv = work / "layers.spv"
    compile_spirv(src, layers_spv, "glsl", include_dir=work)
    src.write_text(render_shader("layers.comp.glsl", include="model.glsl", materials=consts, n=n, decode_kd=False))
    runtime_spv = work / "runtime.spv"
    compile_spirv(src, runtime_spv, "glsl", include_dir=work)
    pairs = np.concatenate([wi, wo], axis=1)
    base_rate = rate(uniform_spv, pairs, 3, work)
    print(f"lavapipe (host SIMD), {n} pairs, best of 7 dispatches; model {args.model}")
    print(f"uniform material ({names[0]}), hbrdf_eval of its constant: {base_rate / 1e6:.2f} M evaluations/s")
    pure_rows, _ = rows_for(sets["pure texels"])
    runtime_rate = r = rate(runtime_spv, pure_rows, 4, work)
    print(f"  the same material chosen at run time (the layers kernel, pure texels, no decode): {r / 1e6:.2f} M/s = "
          f"{base_rate / r:.2f}x")
    for label, texels in sets.items():
        rows, wt = rows_for(texels)
        r = rate(layers_spv, rows, 4, work)
        print(f"  hbrdf_eval_layers + kd decode, {label:13s} {r / 1e6:6.2f} M/s = {base_rate / r:.2f}x the uniform "
              f"material ({float(((wt > 0).sum(axis=1)).mean()):.2f} layers per pair)")
    # The kernel that reads the maps itself (glsl/textured.comp.j2): per pair uv, a bilinear lookup
    # of the weights map and of layer 0's sRGB kd map (an albedo texture: the material's kd x 0.8-1.0).
    kd_map = np.clip(stored_kd * rng.uniform(0.8, 1.0, (SIZE, SIZE, 1)), 0, 1).astype(np.float32)
    maps = np.concatenate([weights.ravel(), kd_map.ravel()]).astype(np.float32)
    maps = np.concatenate([maps, np.zeros(-len(maps) % 8, np.float32)]).reshape(-1, 8)
    layer_consts = [material_constant(n) for n in names] + [material_constant(names[0])]
    for kd0 in (False, True):
        src.write_text(render_shader("textured.comp.glsl", include="model.glsl", materials=layer_consts, n=n,
                                     width=SIZE, height=SIZE, kd0=kd0))
        textured_spv = work / "textured.spv"
        compile_spirv(src, textured_spv, "glsl", include_dir=work)
        for label, texels in sets.items():
            t = np.sort(rng.choice(texels, n))
            uv = np.stack([(t % SIZE + 0.5) / SIZE, (t // SIZE + 0.5) / SIZE], axis=1).astype(np.float32)
            r = rate(textured_spv, np.concatenate([np.concatenate([uv, wi, wo], axis=1), maps]), 4, work)
            print(f"  textured kernel reading the maps ({'weights + kd' if kd0 else 'weights     '}), {label:13s} "
                  f"{r / 1e6:6.2f} M/s = {base_rate / r:.2f}x the uniform constant, {r / runtime_rate:.2f}x the "
                  f"throughput of the uniform chosen at run time")
    if args.anatomy:  # where the map-reading kernel's time goes
        kernel = render_shader("textured.comp.glsl", include="model.glsl", materials=layer_consts, n=n, width=SIZE,
                               height=SIZE, kd0=False)
        lookup = "vec3 w = a00 * map_texel"
        variants = {"no lookup, weights 0 at run time (the layers' branches kept)":
                    kernel.replace(lookup, "vec3 w = vec3(min(data_in[8u * N], 0.0)); vec3 unused = a00 * map_texel"),
                    "no lookup, weights constant (1, 0, 0, 0): one evaluation in the code":
                    kernel.replace(lookup, "vec3 w = vec3(0.0); vec3 unused = a00 * map_texel")}
        uv = np.stack([(np.arange(n) % SIZE + 0.5) / SIZE, (np.arange(n) // SIZE % SIZE + 0.5) / SIZE], axis=1)
        rows = np.concatenate([np.concatenate([uv.astype(np.float32), wi, wo], axis=1), maps])
        for label, code in variants.items():
            src.write_text(code)
            compile_spirv(src, textured_spv, "glsl", include_dir=work)
            r = rate(textured_spv, rows, 4, work)
            print(f"  anatomy: {label:68s} {r / 1e6:6.2f} M/s = {base_rate / r:.2f}x the uniform constant")
    return 0


if __name__ == "__main__":
    sys.exit(main())
