"""Textured materials in the generated code (docs/SVBRDF.md): hbrdf_eval_layers and
hbrdf_pdf_layers of a texel whose four layers are material constants, layer 0's kd replaced by an
8-bit sRGB value decoded in the shader (hbrdf_decode_srgb), run under lavapipe (GLSL, HLSL, Slang,
WGSL; glsl/layers.comp.j2) and compiled as C++, against libhybridbrdf's HybridModel::eval_texel and
the library's MIS pdf on the same inputs. Tolerance as the shader conformance suite: 1e-4 relative
where |f| > 1e-6 (lavapipe's exp and pow are a few ULP off, its multiply-adds fused)."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

import hybridbrdf as hb
from hybridbrdf import _core
from hybridbrdf.codegen.literals import material_constant
from hybridbrdf.codegen.main import generate
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.svbrdf.asset import SVBRDF
from hybridbrdf.svbrdf.decode import transfer
from hybridbrdf.svbrdf.maps import read_map

from helpers import hard_pairs, saved_random_model, skip_without_vulkan
from shader_kernels import render_shader
from slang_wgsl_tools import run_kernel, skip_without_slang, skip_without_wgpu

STORED_KD = np.array([[0.0, 0.5, 1.0], [0.2, 0.2, 0.2], [1.0, 0.04, 0.6], [0.73, 0.91, 0.05]])


def texel_inputs(n=20_000, seed=5):
    """(17 floats per pair, the layers' material indices (N, 4), weights (N, 4), stored kd row (N,)):
    pure texels, two-layer and four-layer mixtures, zero-weight layers; plus the hard pairs."""
    rng = np.random.default_rng(seed)
    hwi, hwo = hard_pairs()
    wi = np.concatenate([cosine_directions(rng, n), hwi]).astype(np.float32)
    wo = np.concatenate([cosine_directions(rng, n), hwo]).astype(np.float32)
    m = len(wi)
    mats = rng.integers(0, 3, size=(m, 4))
    raw = rng.uniform(0, 1, size=(m, 4)) * (rng.uniform(0, 1, size=(m, 4)) < 0.6)
    raw[: m // 4] = np.eye(4)[rng.integers(0, 4, m // 4)]  # a quarter pure texels
    raw[raw.sum(axis=1) == 0, 0] = 1.0
    w = (raw / raw.sum(axis=1, keepdims=True)).astype(np.float32)
    kd_row = rng.integers(0, len(STORED_KD), size=m)
    rows = np.concatenate([wi, wo, w, mats.astype(np.float32), STORED_KD[kd_row]], axis=1).astype(np.float32)
    return rows, wi, wo, mats, w, kd_row


def reference(path, model, wi, wo, mats, w, kd_row):
    """libhybridbrdf's scalar texel path and the mixture of the library's MIS pdfs (float64 sums)."""
    t = model.tensors
    L = 4
    kd = t["materials.kd"][mats].astype(np.float32)
    stored = STORED_KD[kd_row]
    kd[:, 0] = np.array([transfer("srgb", v) for v in stored.ravel()]).reshape(stored.shape).astype(np.float32)
    eta, alpha, z = (t[f"materials.{k}"][mats].astype(np.float32) for k in ("eta", "alpha", "z"))
    f = _core.Model(str(path)).eval_texels(wi, wo, mats.astype(np.int32), w, kd, eta, alpha, z)
    pdf = np.zeros(len(wi))
    for k in range(L):
        for key in {(int(a), int(b)) for a, b in zip(mats[:, k], kd_row if k == 0 else np.zeros(len(wi), int))}:
            sel = (mats[:, k] == key[0]) & ((kd_row == key[1]) if k == 0 else True) & (w[:, k] > 0)
            if not sel.any():
                continue
            p = hb.AnalyticParams(kd=np.clip(kd[sel][0, k], 0, 1), eta=eta[sel][0, k], alpha=tuple(alpha[sel][0, k]))
            pdf[sel] += w[sel, k] * hb.pdf(wi[sel], wo[sel], p, strategy="mis")
    return f, pdf


def check(got, f_ref, pdf_ref):
    assert np.isfinite(got).all()
    f = got[:, :3]
    assert np.array_equal(f == 0, f_ref == 0)
    big = np.abs(f_ref) > 1e-6
    assert (np.abs(f[big] - f_ref[big]) / np.abs(f_ref[big])).max() < 1e-4
    bigp = pdf_ref > 1e-6
    assert (np.abs(got[bigp, 3] - pdf_ref[bigp]) / pdf_ref[bigp]).max() < 1e-3
    assert np.all(got[~bigp, 3] < 1e-5)


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("layers")
    path, model = saved_random_model(tmp, "hybrid", output_layer="material", energy_bound=True)
    rows, wi, wo, mats, w, kd_row = texel_inputs()
    f_ref, pdf_ref = reference(path, model, wi, wo, mats, w, kd_row)
    assert (w > 0).sum(axis=1).max() == 4 and (w == 1).any(axis=1).sum() > 1000  # the control: both kinds of texel
    return model, rows, f_ref, pdf_ref


@pytest.mark.parametrize("target", ["glsl", "hlsl", "slang", "wgsl"])
def test_generated_texel_functions_match_the_library(tmp_path, case, target):
    model, rows, f_ref, pdf_ref = case
    if target == "wgsl":
        skip_without_wgpu()
    elif target == "slang":
        skip_without_slang()
    else:
        skip_without_vulkan()
    code = generate(model, target)
    materials = [material_constant(n) for n in model.materials]
    extra = {"model_code": code} if target == "wgsl" else {}
    kernel = render_shader(f"layers.comp.{target}", include=f"model.{target}", materials=materials, n=len(rows), **extra)
    (tmp_path / f"model.{target}").write_text(code)
    got = run_kernel(tmp_path, target, kernel, rows, out_floats=4)
    check(got, f_ref, pdf_ref)


CPP_DRIVER = r"""
#include <cstdio>
#include <cstdlib>
#include "model.h"
int main() {
    unsigned n = 0;
    if (std::fread(&n, 4, 1, stdin) != 1) return 1;
    const std::size_t count = std::size_t(17) * n;
    float* const in = static_cast<float*>(std::calloc(count + 1, 4));  // not <vector>: 0.13 s less g++ a compile
    if (in == nullptr || std::fread(in, 4, count, stdin) != count) return 1;
    const hbrdf::HbrdfMaterial mats[] = {MATS};
    for (unsigned i = 0; i < n; ++i) {
        const float* p = &in[17ull * i];
        hbrdf::HbrdfMaterial m[4];
        for (int k = 0; k < 4; ++k) m[k] = mats[int(p[10 + k])];
        m[0].kd = hbrdf::float3(hbrdf::hbrdf_decode_srgb(p[14]), hbrdf::hbrdf_decode_srgb(p[15]), hbrdf::hbrdf_decode_srgb(p[16]));
        const hbrdf::float3 wi(p[0], p[1], p[2]), wo(p[3], p[4], p[5]);
        const hbrdf::float3 f = hbrdf::hbrdf_eval_layers(wi, wo, m[0], m[1], m[2], m[3], p[6], p[7], p[8], p[9]);
        const float out[4] = {f.x, f.y, f.z, hbrdf::hbrdf_pdf_layers(wi, wo, m[0], m[1], m[2], m[3], p[6], p[7], p[8], p[9])};
        std::fwrite(out, 4, 4, stdout);
    }
    return 0;
}
"""


def test_generated_cpp_texel_functions_match_the_library(tmp_path, case):
    model, rows, f_ref, pdf_ref = case
    (tmp_path / "model.h").write_text(generate(model, "cpp"))
    mats = ", ".join("hbrdf::" + material_constant(n) for n in model.materials)
    (tmp_path / "driver.cpp").write_text(CPP_DRIVER.replace("MATS", mats))
    r = subprocess.run(["g++", "-std=c++17", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror", "-I", str(tmp_path),
                        str(tmp_path / "driver.cpp"), "-o", str(tmp_path / "driver")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[:3000]
    payload = np.uint32(len(rows)).tobytes() + rows.astype(np.float32).tobytes()
    out = subprocess.run([str(tmp_path / "driver")], input=payload, capture_output=True)
    assert out.returncode == 0
    got = np.frombuffer(out.stdout, dtype=np.float32).reshape(-1, 4)
    check(got, f_ref, pdf_ref)
    # The header is the library's scalar path: f bit for bit where the library's texel is the header's.
    pure = (rows[:, 6:10] == 1).any(axis=1)
    assert np.abs(got[pure, :3] - f_ref[pure]).max() <= 1e-6 * np.abs(f_ref[pure]).max()


def test_textured_kernel_reads_the_maps_like_the_library(tmp_path):
    """glsl/textured.comp.j2: a GLSL kernel that looks texels up in the maps itself (weights and an
    sRGB kd map of layer 0, bilinear, repeat) and evaluates hbrdf_eval_layers, under lavapipe,
    against libhybridbrdf's Svbrdf::eval and Svbrdf::pdf on the saved folder: uv anywhere (beyond
    [0, 1] too, texel centres and cell edges), pure regions, soft edges, the hard pairs."""
    skip_without_vulkan()
    path, model = saved_random_model(tmp_path, "hybrid", output_layer="material", energy_bound=True)
    rng = np.random.default_rng(31)
    h, w = 10, 12
    weights = np.zeros((h, w, 3), np.float32)
    weights[:5, 6:, 0] = 1.0                                     # layer 1 pure
    weights[6:, :, 1] = np.linspace(0, 1, w, dtype=np.float32)   # layer 2 ramping in
    weights[5] = 0.25                                            # a band of four-way mixtures... of three layers
    kd = rng.uniform(0, 1, (h, w, 3)).astype(np.float32)
    SVBRDF(model, model.materials[:3], (w, h), weights, [{"kd": kd}, {}, {}]).save(tmp_path / "sv", format="png")
    stored_w, _ = read_map(tmp_path / "sv" / "weights.png")
    stored_kd, _ = read_map(tmp_path / "sv" / "layer0_kd.png")
    hwi, hwo = hard_pairs()
    n = 6000
    wi = np.concatenate([cosine_directions(rng, n), hwi]).astype(np.float32)
    wo = np.concatenate([cosine_directions(rng, n), hwo]).astype(np.float32)
    m = len(wi)
    uv = rng.uniform(-1.5, 2.5, (m, 2))
    uv[:500] = (rng.integers(0, [w, h], (500, 2)) + 0.5) / [w, h]   # texel centres
    uv[500:1000] = rng.integers(0, [w, h], (500, 2)) / [w, h]       # cell corners
    uv = uv.astype(np.float32)
    rows = np.concatenate([uv, wi, wo], axis=1)
    maps = np.concatenate([stored_w.ravel(), stored_kd.ravel()]).astype(np.float32)
    maps = np.concatenate([maps, np.zeros(-len(maps) % 8, np.float32)]).reshape(-1, 8)
    code = generate(model, "glsl")
    (tmp_path / "model.glsl").write_text(code)
    consts = [material_constant(name) for name in model.materials[:3]]
    kernel = render_shader("textured.comp.glsl", include="model.glsl", materials=consts + consts[:1], n=m, width=w,
                           height=h, kd0=True)
    got = run_kernel(tmp_path, "glsl", kernel, np.concatenate([rows, maps]), out_floats=4)[:m]
    lib = _core.Svbrdf(str(tmp_path / "sv"))
    f_ref = lib.eval(uv, wi, wo, "bilinear")
    pdf_ref = lib.pdf(uv, wi, wo, "mis", "bilinear").astype(np.float64)
    assert (weights.reshape(-1, 3).max(axis=1) == 1).any() and (f_ref > 0).mean() > 0.5  # the control
    check(got, f_ref, pdf_ref)
