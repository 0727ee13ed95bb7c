"""Generated GLSL and HLSL executed under lavapipe (Mesa's CPU Vulkan driver),
with the Vulkan validation layer on, against libhybridbrdf on the same inputs:
10^5 cosine-weighted pairs plus the hard cases, for several architectures.

Tolerance: 1e-4 relative where |f| > 1e-6 (lavapipe's exp is ~15 ULP, its
multiply-adds are fused, and the network's sums and exp() amplify both);
no NaN or Inf; zeros in the same places."""

import numpy as np
import pytest

from hybridbrdf import _core
from hybridbrdf.codegen import eval_compute_shader, generate, material_constant
from hybridbrdf.directions import cosine_directions
from hybridbrdf.random_model import random_model

from helpers import compile_spirv, half_rounded_copy, hard_pairs, run_on_lavapipe, saved_random_model
from helpers import skip_without_vulkan

skip_without_vulkan(allow_module_level=True)


def run_shader(tmp_path, target, model, material, wi, wo, **generate_options):
    """hbrdf_eval of one material, generated for ``target`` and run by glsl/eval.comp.<target>."""
    (tmp_path / f"model.{target}").write_text(generate(model, target, [model.materials[material]],
                                                       **generate_options))
    const = material_constant(model.materials[material])
    src = tmp_path / ("wrap.comp" if target == "glsl" else "wrap.hlsl")
    src.write_text(eval_compute_shader("hbrdf_eval", const, f"model.{target}", target, n=len(wi)))
    spv = tmp_path / "shader.spv"
    compile_spirv(src, spv, target, include_dir=tmp_path)
    return run_on_lavapipe(spv, np.concatenate([wi, wo], axis=1))


CASES = [("hybrid", "hardgelu", 32, 3), ("hybrid", "relu", 16, 2), ("neural", "hardgelu", 16, 2),
         ("logmul", "hardgelu", 16, 2), ("analytic-input", "relu", 16, 2), ("additive", "hardgelu", 16, 2), ("hybrid-half", "hardgelu", 16, 2)]


# The network as straight-line code with literal weights (the shader default) and as loops over
# constant arrays (the C++ default, and the form fp16 uses), both against the library.
FORMS = [(case, target, "unrolled") for case in CASES for target in ("glsl", "hlsl")] + [
    (CASES[0], "glsl", "loops"), (CASES[2], "hlsl", "loops")]


@pytest.mark.parametrize("case,target,mlp_form", FORMS)
def test_shader_matches_the_library_under_lavapipe(tmp_path, case, target, mlp_form):
    arch, activation, width, depth = case
    path, model = saved_random_model(tmp_path, arch, activation, width, depth)
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
    if arch == "additive":  # max(f_a + o, 0) cancels: bound the error by the size of its terms
        assert np.abs(got - ref).max() < 1e-4 * np.abs(ref).max()
    else:
        assert rel.max() < 1e-4, f"max relative error {rel.max():.3g}"


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
