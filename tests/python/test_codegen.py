"""Generated code: the C++ header compiles with -Wall -Wextra -Werror and
computes what libhybridbrdf computes (1e-6 relative); GLSL and HLSL compile
with glslangValidator and pass spirv-val. (Running the shaders under lavapipe
is the conformance suite of the code-generation issue.)"""

import json
import pathlib
import shutil
import subprocess

import numpy as np
import pytest

import hybridbrdf as hb
from hybridbrdf import _core, spec
from hybridbrdf.codegen.literals import float_literal, material_constant
from hybridbrdf.codegen.main import generate, main as codegen_main
from hybridbrdf.codegen.scene import load_scene
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.model.random import random_model

from helpers import compile_spirv, half_rounded_copy, hard_pairs, saved_random_model
from shader_kernels import every_function_shader, spirv_size

ROOT = pathlib.Path(__file__).resolve().parents[2]
MODEL = ROOT / "results" / "rgl54_hybrid_32x2.safetensors"

# Every architecture of the spec, the activations taken in turn, and the paper's model with each.
ACTS = list(spec.ACTIVATIONS)
ARCHS = [(arch, ACTS[(i + 1) % len(ACTS)]) for i, arch in enumerate(spec.ARCHS)] + [("hybrid", ACTS[0])]

CPP_DRIVER = r"""
#include <cstdio>
#include <cstdlib>
#include "model.h"
int main() {
    const hbrdf::HbrdfMaterial mats[] = {MATS};
    unsigned n = 0;
    if (std::fread(&n, 4, 1, stdin) != 1) return 2;
    const std::size_t count = std::size_t(FLOATS) * n;
    float* const in = static_cast<float*>(std::calloc(count + 1, 4));  // not <vector>: 0.13 s less g++ a compile
    if (in == nullptr || std::fread(in, 4, count, stdin) != count) return 3;
    for (const auto& m : mats)
LOOP
    return 0;
}
"""

# The driver's 11 outputs per pair and material: f, f_a, pdf, sampled wi, its pdf.
EVAL_LOOP = r"""
        for (unsigned i = 0; i < n; ++i) {
            const float* p = &in[8 * i];
            hbrdf::float3 wi(p[0], p[1], p[2]), wo(p[3], p[4], p[5]);
            hbrdf::float3 f = hbrdf::hbrdf_eval(wi, wo, m);
            hbrdf::float3 fa = hbrdf::hbrdf_eval_analytic(wi, wo, m);
            float pdf_s = 0.f;
            hbrdf::float3 s = hbrdf::hbrdf_sample(wo, hbrdf::float2(p[6], p[7]), m, pdf_s);
            float out[11] = {f.x, f.y, f.z, fa.x, fa.y, fa.z, hbrdf::hbrdf_pdf(wi, wo, m), s.x, s.y, s.z, pdf_s};
            std::fwrite(out, 4, 11, stdout);
        }"""

# hbrdf_eval_depth at depths 0, 1, 2: 3 outputs per pair, depth and material.
DEPTH_LOOP = r"""
        for (int depth = 0; depth < 3; ++depth)
            for (unsigned i = 0; i < n; ++i) {
                const float* p = &in[6 * i];
                const hbrdf::float3 f = hbrdf::hbrdf_eval_depth(hbrdf::float3(p[0], p[1], p[2]),
                                                                hbrdf::float3(p[3], p[4], p[5]), m, depth);
                const float out[3] = {f.x, f.y, f.z};
                std::fwrite(out, 4, 3, stdout);
            }"""


def _build_cpp_driver(tmp_path, text, names, floats_per_pair, loop, stem="driver"):
    """The generated C++ ``text`` (as tmp_path/model.h) compiled with a driver that reads a
    pair count and ``floats_per_pair`` floats per pair from stdin and runs ``loop`` for each
    material of ``names`` (``m``), with -Wall -Wextra -Werror and no contracted multiply-adds."""
    (tmp_path / "model.h").write_text(text)
    mats = ", ".join("hbrdf::" + material_constant(n) for n in names)
    src = tmp_path / f"{stem}.cpp"
    src.write_text(CPP_DRIVER.replace("MATS", mats).replace("FLOATS", str(floats_per_pair)).replace("LOOP", loop[1:]))
    exe = tmp_path / stem
    r = subprocess.run(["g++", "-std=c++17", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror",
                        "-I", str(tmp_path), str(src), "-o", str(exe)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[:3000]
    return exe


def _run_cpp_driver(exe, *columns):
    """The driver's float32 outputs for the pairs whose floats are ``columns`` side by side."""
    payload = np.uint32(len(columns[0])).tobytes() + np.concatenate(columns, axis=1).astype(np.float32).tobytes()
    r = subprocess.run([str(exe)], input=payload, capture_output=True)
    assert r.returncode == 0
    return np.frombuffer(r.stdout, dtype=np.float32)


def _build_driver(tmp_path, text, names):
    return _build_cpp_driver(tmp_path, text, names, 8, EVAL_LOOP)


def _run_driver(exe, wi, wo, u, n_mats):
    """The driver's 11 outputs per pair (f, f_a, pdf, sampled wi, its pdf) for each material."""
    return _run_cpp_driver(exe, wi, wo, u).reshape(n_mats, len(wi), 11)


def _rel(a, b):
    return np.abs(a - b) / np.maximum(np.abs(b), 1e-30)


def tracer_scene(model_path, materials, extra_materials=None, **settings):
    """A path-tracer scene (docs/RENDERING.md), one sphere per material: ``materials`` maps the
    scene's names to a model material of ``model_path``, or to (material, "analytic")."""
    mats = {}
    for key, spec in materials.items():
        name, evaluate = spec if isinstance(spec, tuple) else (spec, None)
        mats[key] = {"type": "model", "file": str(model_path), "material": name}
        if evaluate:
            mats[key]["evaluate"] = evaluate
    mats.update(extra_materials or {})
    return {"camera": {"position": [0, 0, 4], "look_at": [0, 0, 0]}, "materials": mats,
            "objects": [{"type": "sphere", "center": [2 * i, 0, 0], "radius": 0.5, "material": k}
                        for i, k in enumerate(mats)], **settings}


@pytest.mark.parametrize("arch,activation,mlp_form,output_layer", [(a, act, "auto", "shared") for a, act in ARCHS] + [
    ("hybrid", "hardgelu", "unrolled", "shared"), ("neural", "relu", "unrolled", "shared"),
    ("hybrid", "hardgelu", "auto", "material"), ("hybrid", "relu", "unrolled", "material"),
    ("hybrid-half", "hardgelu", "auto", "material"), ("additive", "hardgelu", "unrolled", "material")])
def test_generated_cpp_matches_the_library(tmp_path, arch, activation, mlp_form, output_layer):
    path, model = saved_random_model(tmp_path, arch, activation, output_layer=output_layer)
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
        floor = 1e-6 * np.abs(ref).max() if spec.ARCHS[arch]["combine"] == "additive" else 0.0  # max(f_a + o, 0) cancels
        assert np.all(np.abs(got[:, :3] - ref) <= 1e-6 * np.abs(ref) + floor), _rel(got[:, :3], ref).max()
        if not spec.ARCHS[arch]["analytic"]:
            continue
        p = model.analytic_params(m)
        # The library's AVX2 kernels contract multiply-adds; compare with its baseline
        # kernels, which round like the header compiled with -ffp-contract=off. Sampling: the
        # library's scalar sampler (libm sin/cos, as the header), not its batched kernel (a
        # polynomial sincos, within 1e-3 in direction: tests/cpp/test_sampling.cpp).
        _core.force_baseline_simd(True)
        try:
            fa, pdf = hb.analytic_eval(wi, wo, p), hb.pdf(wi, wo, p, "mis")
        finally:
            _core.force_baseline_simd(False)
        s_wi, s_pdf, _ = _core.sample_scalar(wo, u, p.to_core(), "mis")
        assert np.allclose(got[:, 3:6], fa, rtol=1e-6, atol=0)
        assert np.allclose(got[:, 6], pdf, rtol=1e-6, atol=0)
        assert np.allclose(got[:, 7:10], s_wi, rtol=0, atol=2e-6)
        assert np.allclose(got[:, 10], s_pdf, rtol=1e-5, atol=0)


@pytest.mark.skipif(shutil.which("glslangValidator") is None, reason="glslang-tools not installed")
@pytest.mark.parametrize("arch,activation", ARCHS)
def test_generated_glsl_and_hlsl_compile_and_validate(tmp_path, arch, activation):
    _, model = random_model(arch, latent=4 if spec.ARCHS[arch]["analytic"] else 12, width=16, depth=2)
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
    """Unrolled code holds the weights as literals and no weight arrays; loops the reverse, with the
    dialect's unroll hint on its loops (none in C++ and WGSL); unrolled fp16 prints the
    half-rounded weights."""
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
        # the loops form's unroll hint (docs/CODEGEN.md): GLSL's macro, HLSL's [unroll], none in C++
        hints = [h for h in ("HBRDF_UNROLL for (", "[unroll] for (") if h in loops or h in unrolled]
        assert hints == {"glsl": ["HBRDF_UNROLL for ("], "hlsl": ["[unroll] for ("], "cpp": []}[target]
        assert not any(h in unrolled for h in hints)
    assert "HBRDF_W0" not in generate(model, "glsl") and "HBRDF_W0" in generate(model, "cpp")
    assert "[unroll] for (" in generate(model, "slang", mlp_form="loops")
    wgsl = generate(model, "wgsl", mlp_form="loops")  # WGSL has no loop attribute
    assert "HBRDF_UNROLL" not in wgsl and "unroll]" not in wgsl
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
    scene = load_scene(tracer_scene(path, {"two": "mat-2"}), model)
    text = generate(model, "cpp", scene=scene)
    assert "folded into the first layer" in text and ("isotropic-only" in text) == spec.ARCHS[arch]["analytic"]
    got = _run_driver(_build_driver(tmp_path, text, ["mat-2"]), wi, wo, u, 1)[0]
    ref = cpp.eval_scalar(wi, wo, 2)
    assert np.allclose(got[:, :3], ref, rtol=1e-5, atol=1e-9)
    if spec.ARCHS[arch]["analytic"]:
        scene = load_scene(tracer_scene(path, {"a": ("mat-0", "analytic"), "b": ("mat-1", "analytic")}), model)
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
    analytic-only material's hbrdf_eval is exactly its hbrdf_eval_analytic, which is the library's f_a."""
    path, model = saved_random_model(tmp_path, "hybrid")
    scene = load_scene(tracer_scene(path, {"flat": ("mat-0", "analytic"), "full": "mat-1"}), model)
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
    _core.force_baseline_simd(True)  # the non-FMA kernels round like the -ffp-contract=off header
    try:
        fa = _core.Model(str(path)).eval_analytic(wi, wo, 0)
    finally:
        _core.force_baseline_simd(False)
    assert np.allclose(got[0, :, :3], fa, rtol=1e-6, atol=1e-12)
    (tmp_path / "n").mkdir()
    neural_path, neural = saved_random_model(tmp_path / "n", "neural")
    with pytest.raises(ValueError, match=r"materials\.flat\.evaluate: \"analytic\" is not possible: the neural baseline"):
        load_scene(tracer_scene(neural_path, {"flat": ("mat-0", "analytic"), "full": "mat-1"}), neural)


@pytest.mark.skipif(shutil.which("glslangValidator") is None, reason="glslang-tools not installed")
def test_specialisation_shrinks_spirv(tmp_path):

    _, model = random_model("hybrid", width=32, depth=3)
    model.save(tmp_path / "m.safetensors")
    generic = spirv_size(generate(model, "glsl"), material_constant("mat-0"), tmp_path)
    folded = spirv_size(generate(model, "glsl", scene=load_scene(tracer_scene(model.path, {"a": "mat-0"}), model)),
                        material_constant("mat-0"), tmp_path)
    flat = spirv_size(generate(model, "glsl", scene=load_scene(tracer_scene(model.path, {"a": ("mat-0", "analytic")}),
                                                               model)),
                      material_constant("mat-0"), tmp_path)
    assert flat < folded < generic, (generic, folded, flat)


@pytest.mark.parametrize("arch", ["hybrid", "neural"])
def test_fp16_header_stores_half_weights_exactly(tmp_path, arch):
    _, model = random_model(arch, latent=4 if spec.ARCHS[arch]["analytic"] else 12, width=16, depth=2)
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


# ---- scenes: the path tracer's schema (docs/RENDERING.md, docs/CODEGEN.md) --------------------

def _eval_depth(tmp_path, text, names, wi, wo):
    """hbrdf_eval_depth of the generated C++ at depths 0, 1, 2: (material, depth, pair, rgb)."""
    exe = _build_cpp_driver(tmp_path, text, names, 6, DEPTH_LOOP, stem="depth")
    return _run_cpp_driver(exe, wi, wo).reshape(len(names), 3, len(wi), 3)


def _library_fa(path, wi, wo, k):
    _core.force_baseline_simd(True)  # the non-FMA kernels round like the -ffp-contract=off header
    try:
        return _core.Model(str(path)).eval_analytic(wi, wo, k)
    finally:
        _core.force_baseline_simd(False)


def test_scene_neural_max_depth_is_the_tracers_rule(tmp_path):
    """With neural_max_depth = 1, hbrdf_eval_depth is the library's full model at depth 0 and its
    f_a at depths 1 and 2 (the tracer's rule 1); -1 means max_depth; 0 leaves no network at all."""
    path, model = saved_random_model(tmp_path, "hybrid")
    scene_path = tmp_path / "s.json"
    # "file" relative to the scene's folder, as the tracer resolves it.
    scene_path.write_text(json.dumps(tracer_scene("m.safetensors", {"a": "mat-0", "b": "mat-1"},
                                                  neural_max_depth=1, max_depth=5)))
    plan = load_scene(scene_path, model)
    assert plan["neural_max_depth"] == 1 and [m["name"] for m in plan["materials"]] == ["mat-0", "mat-1"]
    text = generate(model, "cpp", scene=plan)
    assert "inline constexpr int HBRDF_NEURAL_MAX_DEPTH = 1;" in text
    rng = np.random.default_rng(11)
    wi = cosine_directions(rng, 4000).astype(np.float32)
    wo = cosine_directions(rng, 4000).astype(np.float32)
    got = _eval_depth(tmp_path, text, ["mat-0", "mat-1"], wi, wo)
    cpp = _core.Model(str(path))
    for k in range(2):
        full, fa = cpp.eval_scalar(wi, wo, k), _library_fa(path, wi, wo, k)
        assert np.allclose(got[k, 0], full, rtol=1e-6, atol=1e-12)
        assert not np.allclose(full, fa, rtol=1e-3)  # the rule is visible
        for depth in (1, 2):
            assert np.allclose(got[k, depth], fa, rtol=1e-6, atol=1e-12)

    scene_path.write_text(json.dumps(tracer_scene("m.safetensors", {"a": "mat-0"}, max_depth=3)))
    assert "HBRDF_NEURAL_MAX_DEPTH = 3;" in generate(model, "cpp", scene=load_scene(scene_path, model))

    scene_path.write_text(json.dumps(tracer_scene("m.safetensors", {"a": "mat-0", "b": "mat-1"}, neural_max_depth=0)))
    text = generate(model, "cpp", scene=load_scene(scene_path, model))
    assert "analytic only (no network)" in text and "hbrdf_mlp" not in text and "HBRDF_W0" not in text
    got = _eval_depth(tmp_path, text, ["mat-0", "mat-1"], wi, wo)
    for k in range(2):
        assert np.allclose(got[k, 0], _library_fa(path, wi, wo, k), rtol=1e-6, atol=1e-12)


def test_scene_emits_only_its_materials_of_this_model(tmp_path, capsys):
    path, model = saved_random_model(tmp_path, "hybrid")
    others = {"floor": {"type": "analytic", "kd": 0.4},
              "gold": {"type": "measured", "source": "synthetic:gold"},
              "elsewhere": {"type": "model", "file": "other.safetensors", "material": "mat-0"}}
    scene = tracer_scene(path, {"a": "mat-1", "b": "mat-1"}, extra_materials=others)
    scene["objects"].append({"type": "sphere", "center": [0, 3, 0], "radius": 0.5,
                             "material": {"type": "model", "file": str(path), "material": "mat-2"}})
    scene_path = tmp_path / "s.json"
    scene_path.write_text(json.dumps(scene))
    out = tmp_path / "x.h"
    assert codegen_main([str(path), "--target", "cpp", "--scene", str(scene_path), "-o", str(out)]) == 0
    text = out.read_text()
    assert "HBRDF_MATERIAL_MAT_1 " in text and "HBRDF_MATERIAL_MAT_2 " in text  # the inline one too
    assert "HBRDF_MATERIAL_MAT_0 " not in text  # mat-0 is only used from another file
    assert text.count("inline constexpr HbrdfMaterial HBRDF_MATERIAL_MAT_1 ") == 1  # used twice, emitted once
    assert "not emitted (analytic or measured scene materials, models of other files): floor (analytic), " \
           "gold (measured), elsewhere (model other.safetensors)" in text


@pytest.mark.parametrize("mutate, problem", [
    (lambda s: s["materials"]["a"].update(material="nope"), "materials.a.material: no material 'nope' in "),
    (lambda s: s["materials"]["a"].update(evaluate="maybe"),
     "materials.a.evaluate: expected 'full' or 'analytic', got 'maybe'"),
    (lambda s: s["materials"]["a"].update(colour=1), "materials.a.colour: unknown key 'colour'"),
    (lambda s: s.update(neural_max_depth=-5), "neural_max_depth: must be >= -1, got -5"),
    (lambda s: s.update(neural_max_depth=2**40), "neural_max_depth: must be <= 2147483647, got 1099511627776"),
    (lambda s: s.update(neural_depth=1), "neural_depth: unknown key 'neural_depth'"),
    (lambda s: s.pop("objects"), "missing key 'objects'"),
    (lambda s: s["materials"].update(b={"type": "model", "file": "m.safetensors", "material": "mat-0",
                                         "evaluate": "analytic"}),
     "materials.b.evaluate: 'mat-0' is also used by materials.a with \"evaluate\": \"full\""),
    (lambda s: s["materials"]["a"].update(file="other.safetensors"),
     "materials: no material of type \"model\" uses "),
    (lambda s: s.update(materials=["mat-0", {"name": "mat-1", "evaluate": "analytic"}]),
     "materials: the list form of hbrdf-codegen scenes was removed"),
])
def test_bad_scenes_give_one_line_errors(tmp_path, capsys, mutate, problem):
    path, _ = saved_random_model(tmp_path, "hybrid")
    scene = tracer_scene("m.safetensors", {"a": "mat-0"})
    mutate(scene)
    scene_path = tmp_path / "bad scene.json"
    scene_path.write_text(json.dumps(scene))
    out = tmp_path / "x.glsl"
    assert codegen_main([str(path), "--target", "glsl", "--scene", str(scene_path), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"hbrdf-codegen: error: {scene_path}: {problem}"), err
    assert not out.exists()


@pytest.mark.skipif(shutil.which("glslangValidator") is None or not MODEL.exists(),
                    reason="glslang-tools or the fitted model missing")
def test_the_example_scene_generates_glsl_that_compiles(tmp_path):
    out = tmp_path / "x.glsl"
    assert codegen_main([str(MODEL), "--target", "glsl", "--scene", str(ROOT / "scenes" / "sphere_env.json"),
                         "-o", str(out)]) == 0
    text = out.read_text()
    assert text.count("const HbrdfMaterial HBRDF_MATERIAL_") == 1
    assert "const HbrdfMaterial HBRDF_MATERIAL_PAPER_WHITE_RGB_RGL " in text
    assert "models of other files): floor (analytic)" in text
    assert "const int HBRDF_NEURAL_MAX_DEPTH = 4;" in text  # no neural_max_depth: the scene's max_depth
    src = every_function_shader(tmp_path, "glsl", text, "paper_white_rgb.rgl")
    compile_spirv(src, tmp_path / "x.spv", "glsl", include_dir=tmp_path)
