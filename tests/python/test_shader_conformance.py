"""Generated GLSL and HLSL executed under lavapipe (Mesa's CPU Vulkan driver),
with the Vulkan validation layer on, against libhybridbrdf on the same inputs:
10^5 cosine-weighted pairs plus the hard cases, for several architectures.

Tolerance: 1e-4 relative where |f| > 1e-6 (lavapipe's exp is ~15 ULP, its
multiply-adds are fused, and the network's sums and exp() amplify both);
no NaN or Inf; zeros in the same places."""

import os
import pathlib
import subprocess

import numpy as np
import pytest

import hybridbrdf as hb
from hybridbrdf import _core
from hybridbrdf.codegen import eval_compute_shader, generate, material_constant

from conftest import cosine_directions, hard_pairs
from test_model_file import make_model

ROOT = pathlib.Path(__file__).resolve().parents[2]
RUNNER = pathlib.Path(os.environ.get("HBRDF_VK_RUNNER", ROOT / "build" / "hbrdf_vk_runner"))
LVP_ICD = "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json"
REQUIRED = os.environ.get("HBRDF_REQUIRE_VULKAN") == "1"

if not (RUNNER.exists() and os.path.exists(LVP_ICD)):
    if REQUIRED:
        raise RuntimeError(f"shader conformance needs {RUNNER} (cmake --build build) and lavapipe ({LVP_ICD})")
    pytest.skip("hbrdf_vk_runner or lavapipe not available", allow_module_level=True)

def run_shader(tmp_path, target, model, material, wi, wo, **generate_options):
    n = len(wi)
    (tmp_path / f"model.{target}").write_text(generate(model, target, [model.materials[material]],
                                                       **generate_options))
    const = material_constant(model.materials[material])
    src = tmp_path / ("wrap.comp" if target == "glsl" else "wrap.hlsl")
    src.write_text(eval_compute_shader("hbrdf_eval", const, f"model.{target}", target, n=n))
    spv = tmp_path / "shader.spv"
    args = ["-V"] if target == "glsl" else ["-D", "-V", "-e", "main", "-S", "comp"]
    r = subprocess.run(["glslangValidator", *args, "--target-env", "vulkan1.1", "-I" + str(tmp_path), str(src),
                        "-o", str(spv)], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[-2000:]
    assert subprocess.run(["spirv-val", str(spv)]).returncode == 0
    np.concatenate([wi, wo], axis=1).astype(np.float32).tofile(tmp_path / "in.bin")
    env = dict(os.environ, VK_DRIVER_FILES=LVP_ICD)
    r = subprocess.run([str(RUNNER), str(spv), str(tmp_path / "in.bin"), str(tmp_path / "out.bin"), str(n), "3",
                        "--validation"], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "llvmpipe" in r.stdout
    return np.fromfile(tmp_path / "out.bin", dtype=np.float32).reshape(n, 3)


CASES = [("hybrid", "hardgelu", 32, 3), ("hybrid", "relu", 16, 2), ("neural", "hardgelu", 16, 2),
         ("logmul", "hardgelu", 16, 2), ("analytic-input", "relu", 16, 2), ("additive", "hardgelu", 16, 2)]


# The network as straight-line code with literal weights (the shader default) and as loops over
# constant arrays (the C++ default, and the form fp16 uses), both against the library.
FORMS = [(case, target, "unrolled") for case in CASES for target in ("glsl", "hlsl")] + [
    (CASES[0], "glsl", "loops"), (CASES[2], "hlsl", "loops")]


@pytest.mark.parametrize("case,target,mlp_form", FORMS)
def test_shader_matches_the_library_under_lavapipe(tmp_path, case, target, mlp_form):
    arch, activation, width, depth = case
    _, model = make_model(arch, latent=12 if arch == "neural" else 4, width=width, depth=depth,
                          isotropic=[True, False, True])
    model.arch["activation"] = activation
    path = tmp_path / "m.safetensors"
    model.save(path)
    model = hb.load_model(path)
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
    from test_codegen import _half_rounded_copy

    _, model = make_model("hybrid", width=32, depth=2, isotropic=[True, False, True])
    model.save(tmp_path / "m.safetensors")
    half = _half_rounded_copy(model, tmp_path / "half.safetensors")
    rng = np.random.default_rng(12)
    wi = cosine_directions(rng, 50_000).astype(np.float32)
    wo = cosine_directions(rng, 50_000).astype(np.float32)
    got = run_shader(tmp_path, target, model, 1, wi, wo, precision="fp16", mlp_form=mlp_form)
    ref = _core.Model(str(tmp_path / "half.safetensors")).eval(wi, wo, 1)
    big = np.abs(ref) > 1e-6
    assert np.isfinite(got).all() and np.array_equal(got == 0, ref == 0)
    assert (np.abs(got[big] - ref[big]) / np.abs(ref[big])).max() < 1e-4
    assert half.materials == model.materials
