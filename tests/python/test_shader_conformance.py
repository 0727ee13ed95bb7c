"""Generated GLSL and HLSL executed under lavapipe (Mesa's CPU Vulkan driver),
with the Vulkan validation layer on, against libhybridbrdf on the same inputs:
10^5 cosine-weighted pairs plus the hard cases, for several architectures.

Tolerance: 1e-4 relative where |f| > 1e-6 (lavapipe's exp is ~15 ULP, its
multiply-adds are fused, and the network's sums and exp() amplify both);
no NaN or Inf; zeros in the same places."""

import subprocess

import numpy as np
import pytest

from hybridbrdf import _core, spec
from hybridbrdf.codegen.main import generate
from hybridbrdf.codegen.literals import material_constant
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.model.random import random_model

from helpers import compile_spirv, half_rounded_copy, hard_pairs, run_on_lavapipe, saved_random_model
from helpers import skip_without_vulkan
from shader_kernels import eval_compute_shader

skip_without_vulkan(allow_module_level=True)


def run_shader(tmp_path, target, model, material, wi, wo, **generate_options):
    """hbrdf_eval of one material, generated for ``target`` and run by glsl/eval.comp.j2."""
    (tmp_path / f"model.{target}").write_text(generate(model, target, [model.materials[material]],
                                                       **generate_options))
    const = material_constant(model.materials[material])
    src = tmp_path / ("wrap.comp" if target == "glsl" else "wrap.hlsl")
    src.write_text(eval_compute_shader("hbrdf_eval", const, f"model.{target}", target, n=len(wi)))
    spv = tmp_path / "shader.spv"
    compile_spirv(src, spv, target, include_dir=tmp_path)
    return run_on_lavapipe(spv, np.concatenate([wi, wo], axis=1))


# The paper's 32x3, every architecture of the spec at 16x2 (the activations taken in turn),
# material output layers (the head in HbrdfMaterial, read with constant indices), and energy-bound
# tables (spec/model.json energy_bounds: the table in HbrdfMaterial, read in a loop) on the
# reciprocal form with heads and on the neural baseline.
PAPER = ("hybrid", "hardgelu", 32, 3)
HEADS = ("hybrid", "hardgelu", 32, 2, "material")
CASES = ([PAPER] + [(arch, list(spec.ACTIVATIONS)[i % len(spec.ACTIVATIONS)], 16, 2) for i, arch in enumerate(spec.ARCHS)]
         + [HEADS, ("hybrid-half", "relu", 16, 2, "material"), ("hybrid-reciprocal", "hardgelu", 16, 2, "material", "energy"),
            ("neural", "relu", 16, 2, "shared", "energy")])
NEURAL = next(c for c in CASES if not spec.ARCHS[c[0]]["analytic"])


# The network as straight-line code with literal weights (the shader default) and as loops over
# constant arrays (the C++ default, and the form fp16 uses), both against the library.
# The loops form runs the paper's depth and activation and material output layers at width 12
# (issue 56). Before the loops carried unroll hints, lavapipe's compile time of constant arrays
# indexed in loops grew with the square of their size (Slang's all_outputs kernel of a 3-deep
# hybrid, 2026-11-28: width 8 2 s, 12 10 s, 16 21 s, 32 81 s); with them (docs/CODEGEN.md) the
# 32x3 takes about 8 s and width 12 under 2 s. Width 12 stays because the loops' code paths are the
# same at any width: it is above the hybrid's 10 inputs, as the paper's 32 is (the first layer
# 10 -> 12 is not square, so a transposed or mis-strided index reads other weights), and NEURAL's
# 30 inputs above its width cover the other side. A transposed weight index in the loops form
# fails these cases.
LOOPS_PAPER = ("hybrid", "hardgelu", 12, 3)
LOOPS_HEADS = ("hybrid", "hardgelu", 12, 2, "material")
FORMS = [(case, target, "unrolled") for case in CASES for target in ("glsl", "hlsl")] + [
    (LOOPS_PAPER, "glsl", "loops"), (NEURAL, "hlsl", "loops"), (LOOPS_HEADS, "glsl", "loops"),
    (LOOPS_HEADS, "hlsl", "loops")]


@pytest.mark.parametrize("case,target,mlp_form", FORMS)
def test_shader_matches_the_library_under_lavapipe(tmp_path, case, target, mlp_form):
    arch, activation, width, depth, output_layer = (tuple(case) + ("shared",))[:5]
    path, model = saved_random_model(tmp_path, arch, activation, width, depth, output_layer,
                                     energy_bound="energy" in case)
    rng = np.random.default_rng(11)
    hwi, hwo = hard_pairs()
    wi = np.concatenate([cosine_directions(rng, 100_000), hwi]).astype(np.float32)
    wo = np.concatenate([cosine_directions(rng, 100_000), hwo]).astype(np.float32)
    material = 1  # the anisotropic one
    got = run_shader(tmp_path, target, model, material, wi, wo, mlp_form=mlp_form)
    ref = _core.Model(str(path)).eval(wi, wo, material)
    assert np.isfinite(got).all()
    assert np.array_equal(got == 0, ref == 0)
    big = np.abs(ref) > 1e-6
    rel = np.abs(got[big] - ref[big]) / np.abs(ref[big])
    if spec.ARCHS[arch]["combine"] == "additive":  # max(f_a + o, 0) cancels: bound the error by the size of its terms
        assert np.abs(got - ref).max() < 1e-4 * np.abs(ref).max()
    else:
        assert rel.max() < 1e-4, f"max relative error {rel.max():.3g}"


def test_loops_form_carries_unroll_hints(tmp_path):
    """The loops form's loops reach SPIR-V with LoopControl Unroll: GLSL through
    GL_EXT_control_flow_attributes (the HBRDF_UNROLL macro), HLSL through [unroll]. Lavapipe follows
    the hint and folds the constant weights; without it, it compiles and runs a copy of each weight
    array per use (the neural 16x2's hlsl loops case above: 20 s instead of about 1 s; a minute in
    Slang; docs/CODEGEN.md). A GLSL shader that defines HBRDF_UNROLL empty before the file gets no hint."""
    _, model = saved_random_model(tmp_path, "neural", "relu", 8, 1)
    name = model.materials[1]
    for target, opt_out in (("glsl", False), ("glsl", True), ("hlsl", False)):
        (tmp_path / f"model.{target}").write_text(generate(model, target, [name], mlp_form="loops"))
        kernel = eval_compute_shader("hbrdf_eval", material_constant(name), f"model.{target}", target, n=64)
        if opt_out:
            kernel = kernel.replace('#include "model.glsl"', '#define HBRDF_UNROLL\n#include "model.glsl"')
        src = tmp_path / ("wrap.comp" if target == "glsl" else "wrap.hlsl")
        src.write_text(kernel)
        compile_spirv(src, tmp_path / "s.spv", target, include_dir=tmp_path)
        dis = subprocess.run(["spirv-dis", str(tmp_path / "s.spv")], capture_output=True, text=True, check=True).stdout
        controls = sorted(line.split()[-1] for line in dis.splitlines() if "OpLoopMerge" in line)
        # 9 hinted: the copy of the inputs, each layer's neurons and inputs (2 x 2), the copy between
        # the layers, the frames' three; the latent's copy into the inputs has none.
        assert controls == (["None"] * 10 if opt_out else ["None"] + ["Unroll"] * 9), (target, opt_out, controls)


@pytest.mark.parametrize("target,mlp_form", [("glsl", "unrolled"), ("hlsl", "unrolled"), ("glsl", "loops"),
                                             ("hlsl", "loops")])
def test_fp16_shaders_match_the_half_rounded_model(tmp_path, target, mlp_form):
    _, model = random_model("hybrid", width=32, depth=2, isotropic=[True, False, True])
    model.save(tmp_path / "m.safetensors")
    half = half_rounded_copy(model, tmp_path / "half.safetensors")
    rng = np.random.default_rng(12)
    wi = cosine_directions(rng, 50_000).astype(np.float32)
    wo = cosine_directions(rng, 50_000).astype(np.float32)
    got = run_shader(tmp_path, target, model, 1, wi, wo, precision="fp16", mlp_form=mlp_form)
    ref = _core.Model(str(tmp_path / "half.safetensors")).eval(wi, wo, 1)
    big = np.abs(ref) > 1e-6
    assert np.isfinite(got).all() and np.array_equal(got == 0, ref == 0)
    assert (np.abs(got[big] - ref[big]) / np.abs(ref[big])).max() < 1e-4
    assert half.materials == model.materials


def _synthetic_pairs(n):
    """The pairs glsl/eval_synthetic.comp.j2 makes, rebuilt in NumPy: the PCG hash (Jarzynski &
    Olano 2020) of 2i and 2i + 1, 10/10/12 bits each to x, y in [-1, 1] and z in [0.02, 1.02]."""
    def pcg(v):
        state = v * np.uint32(747796405) + np.uint32(2891336453)
        word = ((state >> ((state >> np.uint32(28)) + np.uint32(4))) ^ state) * np.uint32(277803737)
        return (word >> np.uint32(22)) ^ word

    def direction(bits):
        f = np.float32
        u = np.stack([(bits & 1023).astype(f) * f(1.0 / 1023.0), ((bits >> 10) & 1023).astype(f) * f(1.0 / 1023.0),
                      (bits >> 20).astype(f) * f(1.0 / 4095.0)], axis=1)
        return np.stack([f(2) * u[:, 0] - f(1), f(2) * u[:, 1] - f(1), u[:, 2] + f(0.02)], axis=1)

    i = np.arange(n, dtype=np.uint32)
    with np.errstate(over="ignore"):
        return direction(pcg(np.uint32(2) * i)), direction(pcg(np.uint32(2) * i + np.uint32(1)))


def test_synthetic_direction_kernel_makes_the_pairs_it_documents(tmp_path):
    """The speed benchmark's kernel (pairs made in the shader, bench/fast_model_speed.py) evaluates
    what it says: its kernel-only output wi * wo + kd equals the NumPy rebuild of its pairs, and its
    hbrdf_eval equals the library's on those pairs."""
    path, model = saved_random_model(tmp_path, "hybrid-half", width=16, depth=2)
    name = model.materials[1]
    (tmp_path / "model.glsl").write_text(generate(model, "glsl", [name]))
    n = 64 * 256
    wi, wo = _synthetic_pairs(n)
    out = {}
    for fn in ("hbrdf_harness_only", "hbrdf_eval"):
        src = tmp_path / f"{fn}.comp"
        src.write_text(eval_compute_shader(fn, material_constant(name), "model.glsl", directions="synthetic"))
        spv = tmp_path / f"{fn}.spv"
        compile_spirv(src, spv, include_dir=tmp_path)
        out[fn] = run_on_lavapipe(spv, np.zeros((n, 6), np.float32))
    kd = np.asarray(model.tensors["materials.kd"][1], np.float32)
    assert np.allclose(out["hbrdf_harness_only"], wi * wo + kd, rtol=1e-6, atol=1e-7)
    ref = _core.Model(str(path)).eval(wi.astype(np.float64), wo.astype(np.float64), 1)
    assert np.isfinite(out["hbrdf_eval"]).all() and (ref > 0).all()
    rel = np.abs(out["hbrdf_eval"] - ref) / ref
    assert np.quantile(rel, 0.999) < 1e-4 and rel.max() < 1e-2, (np.quantile(rel, 0.999), rel.max())
