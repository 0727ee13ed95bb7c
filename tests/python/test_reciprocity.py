"""Reciprocity by construction: the hybrid-reciprocal architecture (spec/model.json, direction_inputs
reciprocal) gives f(wi, wo) == f(wo, wi) bit for bit in every implementation, and f_a does for
every analytic architecture.

The network sees m = (wi + wo) / 2 and the products of e = (wi - wo) / 2, which do not change when
wi and wo are exchanged; f_a multiplies G1(wi) G1(wo) before D and averages the two Fresnel
cosines; the gated combine is per value. So the exchange changes no number anywhere: the test
requires exact equality (no tolerance) on cosine-weighted pairs and on the hard-direction table
crossed with itself (grazing, near-normal, wi = wo, mirrored and tiny-component directions), in
PyTorch (float32 and float64), libhybridbrdf's scalar path and every batched kernel this CPU runs,
and the generated GLSL under lavapipe. The paper's hybrid is the control: the same check finds
its error, so the check can fail."""

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf import _core, spec
from hybridbrdf.codegen.literals import material_constant
from hybridbrdf.codegen.main import generate
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.model.random import random_model

from helpers import hard_pairs, skip_without_vulkan
from shader_kernels import render_shader
from slang_wgsl_tools import run_kernel

RECIPROCAL = [a for a, s in spec.ARCHS.items() if s["directions"] == "reciprocal"]


def pairs():
    rng = np.random.default_rng(17)
    n = 4099  # not a multiple of the batched path's chunk
    hwi, hwo = hard_pairs()
    wi = np.concatenate([cosine_directions(rng, n), hwi]).astype(np.float32)
    wo = np.concatenate([cosine_directions(rng, n), hwo]).astype(np.float32)
    return wi, wo


def saved(tmp_path, arch, output_layer="shared"):
    _, model = random_model(arch, width=16, depth=2, isotropic=[True, False, True], output_layer=output_layer)
    path = tmp_path / "m.safetensors"
    model.save(path)
    return path, hb.load_model(path)


def _kernels():
    order = ["avx512", "avx2+fma", "baseline"]
    return order[order.index(_core.model_simd_path()):]


def test_the_contract_declares_a_reciprocal_architecture():
    assert RECIPROCAL == ["hybrid-reciprocal"]
    assert spec.ARCHS["hybrid-reciprocal"]["analytic"] and spec.ARCHS["hybrid-reciprocal"]["combine"] == "gated"


@pytest.mark.parametrize("output_layer", ["shared", "material"])
@pytest.mark.parametrize("arch", RECIPROCAL)
def test_every_cpu_implementation_is_exactly_reciprocal(tmp_path, arch, output_layer):
    path, model = saved(tmp_path, arch, output_layer)
    wi, wo = pairs()
    cpp = _core.Model(str(path))
    try:
        for kernel in _kernels():
            _core.limit_model_simd(kernel)
            for m in range(3):
                f = cpp.eval(wi, wo, m)
                assert np.array_equal(f, cpp.eval(wo, wi, m)), (kernel, m)
                assert (f > 0).any()
    finally:
        _core.limit_model_simd("avx512")
    for m in range(3):
        assert np.array_equal(cpp.eval_scalar(wi, wo, m), cpp.eval_scalar(wo, wi, m)), m
        for dtype in (torch.float32, torch.float64):
            assert np.array_equal(model.eval(wi, wo, m, dtype=dtype), model.eval(wo, wi, m, dtype=dtype)), (m, dtype)


@pytest.mark.parametrize("arch", [a for a, s in spec.ARCHS.items() if s["analytic"]])
def test_f_a_is_exactly_reciprocal(tmp_path, arch):
    path, model = saved(tmp_path, arch)
    wi, wo = pairs()
    for m in range(3):
        p = model.analytic_params(m)
        assert np.array_equal(hb.analytic_eval(wi, wo, p), hb.analytic_eval(wo, wi, p))
        for dtype in (torch.float32, torch.float64):
            assert np.array_equal(model.eval_analytic(wi, wo, m, dtype=dtype), model.eval_analytic(wo, wi, m, dtype=dtype))


def test_the_paper_hybrid_is_not_reciprocal_so_the_check_can_fail(tmp_path):
    path, _ = saved(tmp_path, "hybrid")
    wi, wo = pairs()
    cpp = _core.Model(str(path))
    f, g = cpp.eval(wi, wo, 1), cpp.eval(wo, wi, 1)
    smape = np.mean(2 * np.abs(f - g) / np.maximum(np.abs(f) + np.abs(g), 1e-30))
    assert smape > 1e-3


@pytest.mark.parametrize("output_layer", ["shared", "material"])
def test_the_generated_glsl_is_exactly_reciprocal_under_lavapipe(tmp_path, output_layer):
    """hbrdf_eval of the generated GLSL on (wi, wo) and on (wo, wi), one dispatch: the same floats."""
    skip_without_vulkan()
    _, model = saved(tmp_path, "hybrid-reciprocal", output_layer)
    wi, wo = pairs()
    u = np.full((len(wi), 2), 0.5, dtype=np.float32)
    code = generate(model, "glsl")
    (tmp_path / "model.glsl").write_text(code)
    material = model.materials[1]
    kernel = render_shader("all_outputs.comp.glsl", include="model.glsl", material=material_constant(material),
                           n=2 * len(wi))
    rows = np.concatenate([np.concatenate([wi, wo, u], axis=1), np.concatenate([wo, wi, u], axis=1)])
    out = run_kernel(tmp_path, "glsl", kernel, rows, out_floats=17)
    f, g = out[:len(wi), 0:3], out[len(wi):, 0:3]
    assert (f > 0).any()
    assert np.array_equal(f, g)
