#!/usr/bin/env python3
"""How the generated network's code form changes its speed under lavapipe: the same
model's hbrdf_eval with the MLP written in other forms, timed in one run (AVX2-only
lavapipe by default, as a machine without AVX-512 runs it), each checked against the
default form's output. Also probes whether lavapipe fuses multiply-adds.

Forms (all exact to the model within float rounding):
- unrolled: the generator's default, one expression per neuron, ``b + w0*x0 + w1*x1 ...``;
- fma: the same chain as nested ``fma(w, x, acc)`` calls;
- tree: each neuron's terms summed as a balanced tree (short dependency chains);
- acc4: each neuron's terms in 4 interleaved partial sums;
- rows4: blocks of 4 neurons accumulated input by input (k outer);
- mat4: layers as mat4 * vec4 products of literal matrices (16x fewer SPIR-V operations);
- pairs4: 4 direction pairs per invocation, the MLP on vec4 lanes (one literal per weight
  serves 4 evaluations).

    python bench/shader_forms.py [MODEL] [--pairs 1048576] [--host-simd] [--rounds 3]
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
sys.path.insert(0, str(ROOT / "tests" / "python"))  # shader_kernels

import hybridbrdf as hb  # noqa: E402
import hybridbrdf.codegen.network as cg  # noqa: E402
from hybridbrdf.codegen.literals import float_literal as lit, material_constant
from hybridbrdf.codegen.main import generate
from hybridbrdf.evaluate.directions import cosine_hemisphere
from shader_kernels import eval_compute_shader  # noqa: E402

RUNNER = ROOT / "build" / "hbrdf_vk_runner"
LVP = "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json"
DEFAULT_MODEL = "results/rgl54_hybrid_32x2_e09_120k_refit01.safetensors"
ACT4 = "vec4 hbrdf_act4(vec4 x) { return x * clamp((x + 1.5f) * 0.333333343f, 0.0f, 1.0f); }\n"


def _inputs(index, n_in):
    return [f"x[{k}]" for k in range(n_in)] if index == 0 else [f"h{index - 1}_{k}" for k in range(n_in)]


def _weights(layer):
    return (np.asarray(layer["weight"], dtype=np.float32).reshape(layer["n_out"], layer["n_in"]),
            np.asarray(layer["bias"], dtype=np.float32))


def _neuron(index, j, last, expr):
    return f"o[{j}] = {expr};" if last else f"float h{index}_{j} = hbrdf_activation({expr});"


def _tree(terms):
    while len(terms) > 1:
        terms = [f"({terms[i]} + {terms[i + 1]})" if i + 1 < len(terms) else terms[i] for i in range(0, len(terms), 2)]
    return terms[0]


# Each form stands in for codegen_network.unrolled_layer and takes its arguments; ``let`` (the
# dialect's declaration) is unused: these forms are GLSL only and declare ``float h..`` themselves.
def form_fma(layer, index, last, fp16=False, let=None):
    w, b = _weights(layer)
    out = []
    for j in range(w.shape[0]):
        e = lit(b[j])
        for k, x in enumerate(_inputs(index, w.shape[1])):
            e = f"fma({lit(w[j, k])}, {x}, {e})"
        out.append(_neuron(index, j, last, e))
    return out


def form_tree(layer, index, last, fp16=False, let=None, parts=None):
    w, b = _weights(layer)
    out = []
    for j in range(w.shape[0]):
        terms = [lit(b[j])] + [f"{lit(w[j, k])} * {x}" for k, x in enumerate(_inputs(index, w.shape[1]))]
        if parts:
            terms = [f"({' + '.join(terms[a::parts])})" for a in range(parts) if terms[a::parts]]
        out.append(_neuron(index, j, last, _tree(terms)))
    return out


def form_rows4(layer, index, last, fp16=False, let=None):
    w, b = _weights(layer)
    x, out = _inputs(index, w.shape[1]), []
    for j0 in range(0, w.shape[0], 4):
        js = range(j0, min(w.shape[0], j0 + 4))
        out += [f"float a{index}_{j} = {lit(b[j])};" for j in js]
        out += [f"a{index}_{j} += {lit(w[j, k])} * {x[k]};" for k in range(w.shape[1]) for j in js]
        out += [_neuron(index, j, last, f"a{index}_{j}") for j in js]
    return out


def form_mat4(layer, index, last, fp16=False, let=None):
    w, b = _weights(layer)
    n_out, n_in = w.shape
    out = []
    if index == 0:
        for kb in range(0, n_in, 4):
            out.append(f"vec4 v0_{kb // 4} = vec4({', '.join(f'x[{k}]' if k < n_in else '0.0f' for k in range(kb, kb + 4))});")
        src = [f"v0_{kb // 4}" for kb in range(0, n_in, 4)]
    else:
        src = [f"g{index - 1}_{kb // 4}" for kb in range(0, n_in, 4)]
    at = lambda a, j, k: lit(a[j, k]) if j < n_out and k < n_in else "0.0f"  # noqa: E731
    for jb in range(0, n_out, 4):
        terms = [f"vec4({', '.join(lit(b[j]) if j < n_out else '0.0f' for j in range(jb, jb + 4))})"]
        for kb, s in zip(range(0, n_in, 4), src):  # mat4 is column-major: column = input k
            terms.append(f"mat4({', '.join(at(w, j, k) for k in range(kb, kb + 4) for j in range(jb, jb + 4))}) * {s}")
        if last:
            out.append(f"vec4 ov_{jb // 4} = {' + '.join(terms)};")
            out += [f"o[{j}] = ov_{jb // 4}[{j - jb}];" for j in range(jb, min(jb + 4, n_out))]
        else:
            out.append(f"vec4 g{index}_{jb // 4} = hbrdf_act4({' + '.join(terms)});")
    return out


# ---- packed half precision (GL_EXT_shader_explicit_arithmetic_types_float16) -------------------
#
# Precision notes (Filament-style: say where half is enough and where it is not):
# - binary16 has an 11-bit significand (relative step 2^-11 = 4.9e-4) and a range of +-65504.
# - Hidden layers: weights are O(0.01 .. 6), inputs (unit directions, latent codes) and hardGeLU
#   activations O(1 .. 30): well inside the range; the cost is rounding. Two neurons share one
#   f16vec2, so one fma() over f16vec2 is one packed HFMA2 on NVIDIA (two multiply-adds per
#   instruction, where the FP32 path issues one FFMA each).
# - The inputs x[] arrive in float32 (normalised directions, the material's latent code) and are
#   rounded to half once, at the first layer.
# - The output layer stays float32: its outputs feed exp(o) with o up to HBRDF_PRE_EXP_MAX = 16
#   (exp(16) = 8.9e6 is beyond half's range), and an absolute error e in o is a relative error e
#   in exp(o): half's step at |o| = 8..16 is 2^-7..2^-6, i.e. 0.8-1.6% in f_c, too coarse.
#   Its 32 inputs are widened from half (exact). f_a and the combine (exp, sigmoid) are untouched
#   float32 code.
# - Accumulation: a 32-term dot product summed in half rounds after every term; the pre-activations
#   of this model reach |a| of 10-30 where the half step is 2^-6..2^-5, so the summed rounding can
#   reach ~0.05 absolute, which the float32 output layer (weights up to ~4) turns into a few percent
#   of f. Hence two forms, measured side by side: ``half2`` (products and sums in half) and
#   ``half2acc8`` (half products summed in half over blocks of 8 inputs, the blocks summed in
#   float32, the activation in float32): per-term float32 accumulation would convert every product
#   (a conversion and an FADD per term cost more than the FFMA they replace), blocks of 8 keep 7 of
#   8 operations packed.
HALF_EXT = "#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require\n"
ACT_H2 = ("f16vec2 hbrdf_act_h2(f16vec2 x) {\n"
          "    return x * clamp((x + f16vec2(1.5hf)) * f16vec2(0.333333343hf), f16vec2(0.0hf), f16vec2(1.0hf));\n}\n"
          "vec2 hbrdf_act2(vec2 x) { return x * clamp((x + 1.5f) * 0.333333343f, 0.0f, 1.0f); }\n")
_UNROLLED = cg.unrolled_layer  # the generator's own form: the float32 output layer of the half forms


def half_lit(v) -> str:
    """``v`` rounded to binary16, as a GLSL half literal (shortest digits that round-trip)."""
    h = np.float16(v)
    if not np.isfinite(h):
        raise ValueError(f"weight {float(v)!r} is beyond the half-precision range (65504)")
    return f"{np.format_float_positional(h, unique=True, trim='0')}hf"


def _half_inputs(index, n_in):
    """The layer's inputs as f16vec2 broadcasts: x[k] rounded once (layer 0), else the previous
    layer's packed activations ``p<index-1>_<k/2>`` swizzled (.xx / .yy: free operand selects)."""
    if index == 0:
        return [f"f16vec2(float16_t(x[{k}]))" for k in range(n_in)]
    return [f"p{index - 1}_{k // 2}.{'xx' if k % 2 == 0 else 'yy'}" for k in range(n_in)]


def form_half2(layer, index, last, fp16=False, let=None, block=None):
    """Hidden layers in packed half: two neurons per f16vec2, ``fma`` over f16vec2 (HFMA2).
    ``block``: sum half products in half over blocks of ``block`` inputs, the blocks in float32
    (None: every sum in half). The output layer: float32, its inputs widened."""
    w, b = _weights(layer)
    n_out, n_in = w.shape
    if last:
        widen = [f"float h{index - 1}_{k} = float(p{index - 1}_{k // 2}.{'x' if k % 2 == 0 else 'y'});"
                 for k in range(n_in)]
        return widen + _UNROLLED(layer, index, last)
    if n_out % 2:  # a zero neuron pads the last pair (never read)
        w, b = np.vstack([w, np.zeros((1, n_in), np.float32)]), np.append(b, np.float32(0))
    xs, out = _half_inputs(index, n_in), []
    for p in range(w.shape[0] // 2):
        j = 2 * p
        wk = [f"f16vec2({half_lit(w[j, k])}, {half_lit(w[j + 1, k])})" for k in range(n_in)]
        if block is None:
            e = f"f16vec2({half_lit(b[j])}, {half_lit(b[j + 1])})"
            for k in range(n_in):
                e = f"fma({wk[k]}, {xs[k]}, {e})"
            out.append(f"f16vec2 p{index}_{p} = hbrdf_act_h2({e});")
        else:
            sums = [f"vec2({lit(b[j])}, {lit(b[j + 1])})"]
            for k0 in range(0, n_in, block):
                e = f"{wk[k0]} * {xs[k0]}"
                for k in range(k0 + 1, min(n_in, k0 + block)):
                    e = f"fma({wk[k]}, {xs[k]}, {e})"
                sums.append(f"vec2({e})")
            out.append(f"f16vec2 p{index}_{p} = f16vec2(hbrdf_act2({' + '.join(sums)}));")
    return out


#: The forms besides the generator's own ``unrolled`` (one-pair-per-invocation forms: the network
#: written differently, the rest of the shader unchanged).
FORMS = {"fma": form_fma, "tree": form_tree, "acc4": lambda *a, **k: form_tree(*a, **k, parts=4),
         "rows4": form_rows4, "mat4": form_mat4}
#: Packed half-precision forms (GPU only in effect: lavapipe computes half in float32 lanes and
#: rounds, so there they measure accuracy, not speed).
HALF_FORMS = {"half2": form_half2, "half2acc8": lambda *a, **k: form_half2(*a, **k, block=8)}


def form_glsl(model, material, name):
    """``model``'s GLSL for ``material`` with its network in the form ``name`` (``unrolled`` or a
    key of :data:`FORMS`)."""
    if name == "unrolled":
        return generate(model, "glsl", [material])
    default = cg.unrolled_layer
    cg.unrolled_layer = {**FORMS, **HALF_FORMS}[name]
    try:
        glsl = generate(model, "glsl", [material])
    finally:
        cg.unrolled_layer = default
    # mat4 and the half forms call activations the generated code does not define
    if name == "mat4":
        return glsl.replace("void hbrdf_mlp(", ACT4 + "void hbrdf_mlp(", 1)
    if name in HALF_FORMS:  # the extension before any declaration: glslang wants it first in the file
        return HALF_EXT + glsl.replace("void hbrdf_mlp(", ACT_H2 + "void hbrdf_mlp(", 1)
    return glsl


def pairs4_shader(glsl, material):
    """The generated file with a vec4-lane copy of hbrdf_mlp, and a kernel evaluating 4 pairs
    per invocation (hybrid models: f = exp(o) + sigmoid(g) f_a)."""
    s = glsl.index("void hbrdf_mlp(")
    e = glsl.index("\n}\n", s) + 3
    body = glsl[s:e].replace("void hbrdf_mlp(const float x[", "void hbrdf_mlp4(const vec4 x[")
    body = body.replace("out float o[", "out vec4 o[").replace("float h", "vec4 h").replace("hbrdf_activation(", "hbrdf_act4(")
    model = glsl[:e] + ACT4 + body + glsl[e:]
    kernel = f"""#version 450
#extension GL_GOOGLE_include_directive : require
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer In {{ float data_in[]; }};
layout(std430, binding = 1) writeonly buffer Out {{ float data_out[]; }};
#include "model.glsl"
void main() {{
    uint base = 4u * gl_GlobalInvocationID.x;
    vec4 x[10]; vec3 fa[4]; bool ok[4];
    for (int s = 0; s < 4; ++s) {{
        uint i = base + uint(s);
        vec3 wi = vec3(data_in[6 * i], data_in[6 * i + 1], data_in[6 * i + 2]);
        vec3 wo = vec3(data_in[6 * i + 3], data_in[6 * i + 4], data_in[6 * i + 5]);
        wi *= hbrdf_inverse_length(wi); wo *= hbrdf_inverse_length(wo);
        ok[s] = wi.z > 0.0f && wo.z > 0.0f;
        fa[s] = hbrdf_eval_analytic(wi, wo, {material});
        x[0][s] = wi.x; x[1][s] = wi.y; x[2][s] = wi.z; x[3][s] = wo.x; x[4][s] = wo.y; x[5][s] = wo.z;
        for (int k = 0; k < 4; ++k) x[6 + k][s] = {material}.z[k];
    }}
    vec4 o[6];
    hbrdf_mlp4(x, o);
    for (int s = 0; s < 4; ++s) {{
        uint i = base + uint(s);
        vec3 f = vec3(hbrdf_exp_clamped(o[0][s]) + fa[s].x / (1.0f + exp(-o[3][s])),
                      hbrdf_exp_clamped(o[1][s]) + fa[s].y / (1.0f + exp(-o[4][s])),
                      hbrdf_exp_clamped(o[2][s]) + fa[s].z / (1.0f + exp(-o[5][s])));
        if (!ok[s]) f = vec3(0.0f);
        data_out[3 * i] = f.x; data_out[3 * i + 1] = f.y; data_out[3 * i + 2] = f.z;
    }}
}}
"""
    return model, kernel


def run(d, model_glsl, kernel, items, floats_per_item, env):
    d = pathlib.Path(d)
    (d / "model.glsl").write_text(model_glsl)
    (d / "w.comp").write_text(kernel)
    subprocess.run(["glslangValidator", "-V", "--target-env", "vulkan1.1", f"-I{d}", str(d / "w.comp"), "-o",
                    str(d / "w.spv")], check=True, capture_output=True)
    r = subprocess.run([str(RUNNER), str(d / "w.spv"), str(d / "in.bin"), str(d / "out.bin"), str(items),
                        str(floats_per_item), "--repeat", "7"], check=True, capture_output=True, text=True,
                       env=dict(os.environ, VK_DRIVER_FILES=LVP, **env))
    ms = float([ln for ln in r.stdout.splitlines() if ln.startswith("best_ms")][0].split()[1])
    return ms, np.fromfile(d / "out.bin", dtype=np.float32).reshape(-1, 3)


def fusion_probe(d, env):
    """fma(a, b, c) for a = b = 1 + 2^-23, c = -(1 + 2^-22): 2^-46 fused, 0 unfused."""
    a = np.float32(1 + 2 ** -23)
    np.array([a, a, -(1 + 2 ** -22)] * 64, dtype=np.float32).tofile(pathlib.Path(d) / "in.bin")
    kernel = """#version 450
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer In { float data_in[]; };
layout(std430, binding = 1) writeonly buffer Out { float data_out[]; };
void main() {
    uint i = gl_GlobalInvocationID.x;
    data_out[3 * i] = fma(data_in[3 * i], data_in[3 * i + 1], data_in[3 * i + 2]);
    data_out[3 * i + 1] = 0.0f; data_out[3 * i + 2] = 0.0f;
}
"""
    _, out = run(d, "", kernel, 64, 3, env)
    return float(out[0, 0])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model", nargs="?", default=DEFAULT_MODEL, help=f"a hybrid model (default {DEFAULT_MODEL})")
    ap.add_argument("--pairs", type=int, default=1 << 20)
    ap.add_argument("--host-simd", action="store_true", help="let lavapipe use AVX-512 where the CPU has it")
    ap.add_argument("--rounds", type=int, default=3, help="interleaved rounds over the forms (default 3)")
    args = ap.parse_args()
    env = {} if args.host_simd else {"GALLIUM_OVERRIDE_CPU_CAPS": "avx"}
    model = hb.load_model(args.model if pathlib.Path(args.model).exists() else ROOT / args.model)
    mat = model.materials[0]
    mc = material_constant(mat)
    n = args.pairs
    rng = np.random.default_rng(7)
    pairs = np.concatenate([cosine_hemisphere(rng, n), cosine_hemisphere(rng, n)], axis=1).astype(np.float32)
    with tempfile.TemporaryDirectory() as d:
        fused = fusion_probe(d, env)
        pairs.tofile(pathlib.Path(d) / "in.bin")
        shaders = {name: (form_glsl(model, mat, name), eval_compute_shader("hbrdf_eval", mc, "model.glsl"), n, 3)
                   for name in ("unrolled", *FORMS)}
        shaders["pairs4"] = (*pairs4_shader(generate(model, "glsl", [mat]), mc), n // 4, 12)
        # Interleaved rounds, best time per form: a slow first process or a busy moment
        # elsewhere on the machine then cannot favour one form.
        results = {}
        for _ in range(args.rounds):
            for name, shader in shaders.items():
                ms, out = run(d, *shader, env)
                results[name] = (min(ms, results.get(name, (ms,))[0]), out)
    ref = results["unrolled"][1]
    print(f"{model.kind} {model.arch['width']}x{model.arch['depth']} ({pathlib.Path(args.model).name}, {mat}), {n} pairs, "
          f"lavapipe {'host SIMD' if args.host_simd else 'AVX2 only (GALLIUM_OVERRIDE_CPU_CAPS=avx)'}, 2 cores")
    print(f"fma(1 + 2^-23, 1 + 2^-23, -(1 + 2^-22)) = {fused:.3g} under lavapipe "
          f"({'fused' if fused != 0 else 'not fused: every multiply-add is a multiply and an add'})")
    print(f"{'form':10s} {'M/s':>7s} {'vs unrolled':>11s} {'max rel diff':>12s}")
    for name, (ms, out) in results.items():
        rel = np.max(np.abs(out - ref) / np.maximum(np.abs(ref), 1e-6))
        print(f"{name:10s} {n / ms / 1e3:7.2f} {results['unrolled'][0] / ms:10.2f}x {rel:12.2e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
