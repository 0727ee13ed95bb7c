"""Generated code: the C++ header compiles with -Wall -Wextra -Werror and
computes what libhybridbrdf computes (1e-6 relative); GLSL and HLSL compile
with glslangValidator and pass spirv-val. (Running the shaders under lavapipe
is the conformance suite of the code-generation issue.)"""

import shutil
import subprocess

import numpy as np
import pytest

import hybridbrdf as hb
from hybridbrdf import _core
from hybridbrdf.codegen import float_literal, generate, main as codegen_main, material_constant
from hybridbrdf.directions import cosine_directions
from hybridbrdf.random_model import random_model
from hybridbrdf.shaders import render_shader

from helpers import compile_spirv, half_rounded_copy, hard_pairs, saved_random_model

ARCHS = [("hybrid", "hardgelu"), ("hybrid", "relu"), ("neural", "hardgelu"), ("additive", "relu"),
         ("logmul", "hardgelu"), ("analytic-input", "hardgelu")]

DRIVER = r"""
#include <cstdio>
#include <vector>
#include "model.h"
int main() {
    const hbrdf::HbrdfMaterial mats[] = {MATS};
    unsigned n = 0;
    if (std::fread(&n, 4, 1, stdin) != 1) return 2;
    std::vector<float> in(8 * n);
    if (std::fread(in.data(), 4, in.size(), stdin) != in.size()) return 3;
    for (const auto& m : mats)
        for (unsigned i = 0; i < n; ++i) {
            const float* p = &in[8 * i];
            hbrdf::float3 wi(p[0], p[1], p[2]), wo(p[3], p[4], p[5]);
            hbrdf::float3 f = hbrdf::hbrdf_eval(wi, wo, m);
            hbrdf::float3 fa = hbrdf::hbrdf_eval_analytic(wi, wo, m);
            float pdf_s = 0.f;
            hbrdf::float3 s = hbrdf::hbrdf_sample(wo, hbrdf::float2(p[6], p[7]), m, pdf_s);
            float out[11] = {f.x, f.y, f.z, fa.x, fa.y, fa.z, hbrdf::hbrdf_pdf(wi, wo, m), s.x, s.y, s.z, pdf_s};
            std::fwrite(out, 4, 11, stdout);
        }
    return 0;
}
"""


def _build_driver(tmp_path, text, names):
    (tmp_path / "model.h").write_text(text)
    mats = ", ".join("hbrdf::" + material_constant(n) for n in names)
    (tmp_path / "driver.cpp").write_text(DRIVER.replace("MATS", mats))
    exe = tmp_path / "driver"
    r = subprocess.run(["g++", "-std=c++17", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror",
                        "-I", str(tmp_path), str(tmp_path / "driver.cpp"), "-o", str(exe)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[:3000]
    return exe


def _run_driver(exe, wi, wo, u, n_mats):
    """The driver's 11 outputs per pair (f, f_a, pdf, sampled wi, its pdf) for each material."""
    payload = np.uint32(len(wi)).tobytes() + np.concatenate([wi, wo, u], axis=1).astype(np.float32).tobytes()
    r = subprocess.run([str(exe)], input=payload, capture_output=True)
    assert r.returncode == 0
    return np.frombuffer(r.stdout, dtype=np.float32).reshape(n_mats, len(wi), 11)


def _rel(a, b):
    return np.abs(a - b) / np.maximum(np.abs(b), 1e-30)


@pytest.mark.parametrize("arch,activation,mlp_form", [(a, act, "auto") for a, act in ARCHS] + [
    ("hybrid", "hardgelu", "unrolled"), ("neural", "relu", "unrolled")])
def test_generated_cpp_matches_the_library(tmp_path, arch, activation, mlp_form):
    path, model = saved_random_model(tmp_path, arch, activation)
    exe = _build_driver(tmp_path, generate(model, "cpp", mlp_form=mlp_form), model.materials)
    rng = np.random.default_rng(8)
    n = 20000
    wi = cosine_directions(rng, n).astype(np.float32)
    wo = cosine_directions(rng, n).astype(np.float32)
    hwi, hwo = hard_pairs()
    wi = np.concatenate([wi, hwi.astype(np.float32)])
    wo = np.concatenate([wo, hwo.astype(np.float32)])
    u = rng.random((len(wi), 2)).astype(np.float32)
    out = _run_driver(exe, wi, wo, u, len(model.materials))
    cpp = _core.Model(str(path))
    for m in range(len(model.materials)):
        got = out[m]
        assert np.isfinite(got).all() and (got[:, :3] >= 0).all() and (got[:, 6] >= 0).all()
        ref = cpp.eval_scalar(wi, wo, m)  # the library's scalar path, the header's twin
        zero = ref == 0
        assert np.array_equal(got[:, :3] == 0, zero)  # zeros in the same places
        floor = 1e-6 * np.abs(ref).max() if arch == "additive" else 0.0  # max(f_a + o, 0) cancels
        assert np.all(np.abs(got[:, :3] - ref) <= 1e-6 * np.abs(ref) + floor), _rel(got[:, :3], ref).max()
        if arch == "neural":
            continue
        p = model.analytic_params(m)
        # The library's AVX2 kernels contract multiply-adds; compare with its baseline
        # kernels, which round like the header compiled with -ffp-contract=off.
        _core.force_baseline_simd(True)
        try:
            fa, pdf = hb.analytic_eval(wi, wo, p), hb.pdf(wi, wo, p, "mis")
            s_wi, s_pdf, _ = hb.sample(wo, u, p, "mis")
        finally:
            _core.force_baseline_simd(False)
        assert np.allclose(got[:, 3:6], fa, rtol=1e-6, atol=0)
        assert np.allclose(got[:, 6], pdf, rtol=1e-6, atol=0)
        assert np.allclose(got[:, 7:10], s_wi, rtol=0, atol=2e-6)
        assert np.allclose(got[:, 10], s_pdf, rtol=1e-5, atol=0)


def every_function_shader(tmp_path, target, model_code, material):
    """glsl/every_function.comp.<target> around the generated ``model_code``: compiling it
    compiles every generated function."""
    (tmp_path / f"model.{target}").write_text(model_code)
    src = tmp_path / ("wrap.comp" if target == "glsl" else "wrap.hlsl")
    src.write_text(render_shader(f"every_function.comp.{target}", include=f"model.{target}",
                                 material=material_constant(material)))
    return src


@pytest.mark.skipif(shutil.which("glslangValidator") is None, reason="glslang-tools not installed")
@pytest.mark.parametrize("arch,activation", ARCHS)
def test_generated_glsl_and_hlsl_compile_and_validate(tmp_path, arch, activation):
    _, model = random_model(arch, latent=12 if arch == "neural" else 4, width=16, depth=2)
    model.arch["activation"] = activation
    for target in ("glsl", "hlsl"):
        src = every_function_shader(tmp_path, target, generate(model, target), model.materials[1])
        compile_spirv(src, tmp_path / f"{target}.spv", target, include_dir=tmp_path)


def test_material_constant_names():
    assert material_constant("cc_ibiza-sunset.rgl") == "HBRDF_MATERIAL_CC_IBIZA_SUNSET_RGL"
    assert material_constant("gold") == "HBRDF_MATERIAL_GOLD"


def test_codegen_cli(tmp_path, capsys):
    _, model = random_model()
    path = tmp_path / "m.safetensors"
    model.save(path)
    out = tmp_path / "x.glsl"
    assert codegen_main([str(path), "--target", "glsl", "--materials", "mat-2", "-o", str(out)]) == 0
    text = out.read_text()
    assert "HBRDF_MATERIAL_MAT_2" in text and "HBRDF_MATERIAL_MAT_0" not in text
    assert codegen_main([str(path), "--target", "glsl", "--materials", "nope", "-o", str(tmp_path / "y")]) == 1
    assert "no material 'nope'" in capsys.readouterr().err
    bad = tmp_path / "bad.safetensors"
    bad.write_bytes(b"123")
    assert codegen_main([str(bad), "--target", "cpp", "-o", str(tmp_path / "z.h")]) == 1
    assert not (tmp_path / "y").exists() and not (tmp_path / "z.h").exists()


def test_mlp_forms(tmp_path):
    """Unrolled code holds the weights as literals and no weight arrays; loops the reverse;
    unrolled fp16 prints the half-rounded weights."""
    _, model = random_model("neural", latent=12, width=16, depth=2)
    path = tmp_path / "m.safetensors"
    model.save(path)
    w = model.tensors["mlp.hidden.1.weight"]
    for target in ("glsl", "hlsl", "cpp"):
        unrolled = generate(model, target, mlp_form="unrolled")
        loops = generate(model, target, mlp_form="loops")
        assert "HBRDF_W0" not in unrolled and "HBRDF_FRAMES_W" not in unrolled and "h1_15" in unrolled
        assert "HBRDF_W0" in loops and "HBRDF_FRAMES_W" in loops and "h1_15" not in loops
        assert float_literal(abs(w[3, 5])) in unrolled
    assert "HBRDF_W0" not in generate(model, "glsl") and "HBRDF_W0" in generate(model, "cpp")
    out = tmp_path / "x.glsl"
    with pytest.raises(SystemExit):  # argparse rejects an unknown form
        codegen_main([str(path), "--target", "glsl", "--mlp-form", "sideways", "-o", str(out)])
    assert not out.exists()
    half = generate(model, "glsl", precision="fp16")  # unrolled: half-rounded weights as literals
    assert "HBRDF_W0" not in half and float_literal(np.float16(w[3, 5]).astype(np.float32).__abs__()) in half
    assert codegen_main([str(path), "--target", "glsl", "--mlp-form", "loops", "-o", str(out)]) == 0
    assert "--mlp-form loops" in out.read_text()


@pytest.mark.parametrize("arch", ["hybrid", "neural", "analytic-input"])
def test_scene_specialisation_keeps_the_values(tmp_path, arch):
    """Folding one material's latent into the first layer and isotropic-only GGX change
    nothing but rounding; an analytic-only scene evaluates f_a exactly."""
    path, model = saved_random_model(tmp_path, arch)
    rng = np.random.default_rng(5)
    wi = cosine_directions(rng, 5000).astype(np.float32)
    wo = cosine_directions(rng, 5000).astype(np.float32)
    u = rng.random((5000, 2)).astype(np.float32)
    cpp = _core.Model(str(path))
    scene = {"name": "one.json", "materials": [{"name": "mat-2", "evaluate": "full"}]}
    text = generate(model, "cpp", scene=scene)
    assert "folded into the first layer" in text and ("isotropic-only" in text) == (arch != "neural")
    got = _run_driver(_build_driver(tmp_path, text, ["mat-2"]), wi, wo, u, 1)[0]
    ref = cpp.eval_scalar(wi, wo, 2)
    assert np.allclose(got[:, :3], ref, rtol=1e-5, atol=1e-9)
    if arch != "neural":
        scene = {"name": "flat.json", "materials": [{"name": "mat-0", "evaluate": "analytic"},
                                                     {"name": "mat-1", "evaluate": "analytic"}]}
        text = generate(model, "cpp", scene=scene)
        assert "HBRDF_W0" not in text and "isotropic-only" not in text  # mat-1 is anisotropic
        got = _run_driver(_build_driver(tmp_path, text, ["mat-0", "mat-1"]), wi, wo, u, 2)
        _core.force_baseline_simd(True)  # the non-FMA kernels round like the -ffp-contract=off header
        try:
            for k in range(2):
                assert np.allclose(got[k, :, :3], cpp.eval_analytic(wi, wo, k), rtol=1e-6, atol=1e-12)
        finally:
            _core.force_baseline_simd(False)


@pytest.mark.parametrize("target", ["cpp", "glsl", "hlsl"])
def test_mixed_scene_skips_the_network_per_material(tmp_path, target):
    """A scene with one full and one analytic-only material keeps the network, and the
    analytic-only material's hbrdf_eval is exactly its hbrdf_eval_analytic."""
    path, model = saved_random_model(tmp_path, "hybrid")
    scene = {"name": "mixed.json", "materials": [{"name": "mat-0", "evaluate": "analytic"},
                                                  {"name": "mat-1", "evaluate": "full"}]}
    text = generate(model, target, scene=scene)
    assert "analytic_only" in text and "hbrdf_mlp" in text
    if target != "cpp":  # compiles and validates (the values are the C++ case's, same template)
        src = every_function_shader(tmp_path, target, text, "mat-0")
        compile_spirv(src, tmp_path / "m.spv", target, include_dir=tmp_path)
        return
    rng = np.random.default_rng(6)
    wi = cosine_directions(rng, 3000).astype(np.float32)
    wo = cosine_directions(rng, 3000).astype(np.float32)
    u = rng.random((3000, 2)).astype(np.float32)
    got = _run_driver(_build_driver(tmp_path, text, ["mat-0", "mat-1"]), wi, wo, u, 2)
    assert np.array_equal(got[0, :, :3], got[0, :, 3:6])  # f == f_a for the analytic-only material
    assert not np.allclose(got[1, :, :3], got[1, :, 3:6])
    assert np.allclose(got[1, :, :3], _core.Model(str(path)).eval_scalar(wi, wo, 1), rtol=1e-5, atol=1e-9)
    _, neural = random_model("neural", latent=12, width=16, depth=2)
    with pytest.raises(ValueError, match="neural baseline"):
        generate(neural, "cpp", scene=scene)


@pytest.mark.skipif(shutil.which("glslangValidator") is None, reason="glslang-tools not installed")
def test_specialisation_shrinks_spirv(tmp_path):
    from hybridbrdf.codegen import spirv_size

    _, model = random_model("hybrid", width=32, depth=3)
    generic = spirv_size(generate(model, "glsl"), material_constant("mat-0"), tmp_path)
    folded = spirv_size(generate(model, "glsl", scene={"name": "s", "materials": [{"name": "mat-0",
                                                                                    "evaluate": "full"}]}),
                        material_constant("mat-0"), tmp_path)
    flat = spirv_size(generate(model, "glsl", scene={"name": "s", "materials": [{"name": "mat-0",
                                                                                  "evaluate": "analytic"}]}),
                      material_constant("mat-0"), tmp_path)
    assert flat < folded < generic, (generic, folded, flat)


@pytest.mark.parametrize("arch", ["hybrid", "neural"])
def test_fp16_header_stores_half_weights_exactly(tmp_path, arch):
    _, model = random_model(arch, latent=12 if arch == "neural" else 4, width=16, depth=2)
    model.save(tmp_path / "m.safetensors")
    half = half_rounded_copy(model, tmp_path / "half.safetensors")
    text = generate(model, "cpp", precision="fp16")
    assert "half precision" in text
    rng = np.random.default_rng(6)
    wi, wo = cosine_directions(rng, 5000).astype(np.float32), cosine_directions(rng, 5000).astype(np.float32)
    u = rng.random((5000, 2)).astype(np.float32)
    got = _run_driver(_build_driver(tmp_path, text, model.materials), wi, wo, u, 3)
    cpp_half = _core.Model(str(tmp_path / "half.safetensors"))
    cpp_full = _core.Model(str(tmp_path / "m.safetensors"))
    for m in range(3):
        ref = cpp_half.eval_scalar(wi, wo, m)
        assert np.allclose(got[m, :, :3], ref, rtol=1e-6, atol=1e-12)
        # and the rounding is visible against the float32 model (the test can fail)
        assert not np.allclose(got[m, :, :3], cpp_full.eval(wi, wo, m), rtol=1e-6, atol=1e-12)
