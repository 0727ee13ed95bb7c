"""Reciprocity by construction: the hybrid-reciprocal architecture (spec/model.json, direction_inputs
reciprocal) gives f(wi, wo) == f(wo, wi) bit for bit in every implementation, and f_a does for
every analytic architecture.

The network sees s = wi + wo and the products of d = wi - wo (format 2; format 1 had their halves,
issue 60), which do not change when wi and wo are exchanged; f_a multiplies G1(wi) G1(wo) before D
and averages the two Fresnel cosines; the gated combine is per value. So the exchange changes no
number anywhere: the test requires exact equality (no tolerance) on cosine-weighted pairs and on
the hard-direction table crossed with itself (grazing, near-normal, wi = wo, mirrored and
tiny-component directions), in PyTorch (float32 and float64), libhybridbrdf's scalar path and
every batched kernel this CPU runs, and the generated GLSL, HLSL, Slang and WGSL under lavapipe.
The paper's hybrid is the control: the same check finds its error, so the check can fail.

What the inputs are is checked from outside: a float64 formula written here from the spec's text
against PyTorch's reciprocal_inputs, and against libhybridbrdf's scalar and batched paths through a
file whose network reads its inputs out (each material's f = exp(x_j) for three inputs j)."""

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf import _core, spec
from hybridbrdf.codegen.literals import material_constant
from hybridbrdf.codegen.main import generate
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.model.random import random_model

from hybridbrdf.brdf.torch_brdf import reciprocal_inputs

from helpers import hard_pairs, skip_without_vulkan
from slang_wgsl_tools import skip_without_slang, skip_without_wgpu
from test_shader_hostile import run_all_outputs

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


@pytest.mark.parametrize("target,output_layer", [("glsl", "shared"), ("glsl", "material"), ("hlsl", "material"),
                                                 ("slang", "material"), ("wgsl", "material")])
def test_the_generated_code_is_exactly_reciprocal_under_lavapipe(tmp_path, target, output_layer):
    """hbrdf_eval of the generated code on (wi, wo) and on (wo, wi), one dispatch: the same floats."""
    skip_without_vulkan()
    {"slang": skip_without_slang, "wgsl": skip_without_wgpu}.get(target, lambda: None)()
    _, model = saved(tmp_path, "hybrid-reciprocal", output_layer)
    wi, wo = pairs()
    u = np.full((2 * len(wi), 2), 0.5, dtype=np.float32)
    out = run_all_outputs(tmp_path, target, model, model.materials[1], np.concatenate([wi, wo]),
                          np.concatenate([wo, wi]), u)
    f, g = out[:len(wi), 0:3], out[len(wi):, 0:3]
    assert (f > 0).any()
    assert np.array_equal(f, g)


def inputs_by_the_spec(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """spec/model.json, direction_inputs reciprocal, in float64: s = wi + wo, then d.x d.x, d.y d.y,
    d.z d.z, d.x d.y, d.x d.z, d.y d.z of d = wi - wo."""
    wi, wo = wi.astype(np.float64), wo.astype(np.float64)
    sx, sy, sz = (wi[:, k] + wo[:, k] for k in range(3))
    dx, dy, dz = (wi[:, k] - wo[:, k] for k in range(3))
    return np.stack([sx, sy, sz, dx ** 2, dy ** 2, dz ** 2, dx * dy, dx * dz, dy * dz], axis=1)


def test_the_spec_text_names_the_sums():
    doc = spec.DIRECTION_INPUTS["reciprocal"][1]
    assert doc.startswith("s = wi + wo, then the products of d = wi - wo: d.x d.x, d.y d.y, d.z d.z, d.x d.y, "
                          "d.x d.z, d.y d.z")
    assert spec.ARCHS["hybrid-reciprocal"]["since_format"] == 2 == spec.FORMAT_VERSION


def test_pytorch_computes_the_inputs_the_spec_states():
    rng = np.random.default_rng(5)
    wi, wo = cosine_directions(rng, 5000), cosine_directions(rng, 5000)
    ref = inputs_by_the_spec(wi, wo)
    assert np.abs(ref[:, :3]).max() > 1.5 and ref[:, 3:6].max() > 2.5  # the scale: no halves
    # float64: the same IEEE operations, so the same numbers
    x64 = reciprocal_inputs(torch.from_numpy(wi), torch.from_numpy(wo)).numpy()
    assert np.array_equal(x64, ref)
    x32 = reciprocal_inputs(torch.from_numpy(wi.astype(np.float32)), torch.from_numpy(wo.astype(np.float32))).numpy()
    assert np.allclose(x32, inputs_by_the_spec(wi.astype(np.float32), wo.astype(np.float32)), rtol=0, atol=1e-6)


def input_reader(tmp_path):
    """A hybrid-reciprocal file (no latent code, one 9-wide hidden layer of ReLU, material output
    layers) whose material k gives f = exp(x_{3k}), exp(x_{3k+1}), exp(x_{3k+2}): hidden unit j is
    x_j + 5 (identity weights, bias 5: positive, as every input is >= -4), material k's output c
    is unit 3k + c less 5, and f_a = 0 (kd 0; eta 1: no specular lobe), so the gate adds nothing."""
    _, model = random_model("hybrid-reciprocal", n=3, latent=0, width=9, depth=1, output_layer="material")
    t = model.tensors
    t["mlp.hidden.0.weight"] = np.eye(9, dtype=np.float32)
    t["mlp.hidden.0.bias"] = np.full(9, 5.0, np.float32)
    t["materials.head_weight"] = np.zeros((3, 6, 9), np.float32)
    for k in range(3):
        for c in range(3):
            t["materials.head_weight"][k, c, 3 * k + c] = 1.0
    t["materials.head_bias"] = np.tile(np.array([-5, -5, -5, 0, 0, 0], np.float32), (3, 1))
    t["materials.kd"] = np.zeros((3, 3), np.float32)
    t["materials.eta"] = np.ones((3, 3), np.float32)
    model.arch["activation"] = "relu"
    path = tmp_path / "reader.safetensors"
    model.save(path)
    return path


def test_libhybridbrdf_computes_the_inputs_the_spec_states(tmp_path):
    """Through the bindings: log f of the input reader is the inputs, on the scalar path and every
    batched kernel this CPU runs, and in PyTorch from the same file."""
    path = input_reader(tmp_path)
    rng = np.random.default_rng(6)
    wi, wo = (cosine_directions(rng, 4099).astype(np.float32) for _ in range(2))
    ref = inputs_by_the_spec(wi, wo)
    cpp, model = _core.Model(str(path)), hb.load_model(path)
    try:
        for kernel in _kernels():
            _core.limit_model_simd(kernel)
            got = np.concatenate([cpp.eval(wi, wo, k) for k in range(3)], axis=1)
            assert np.abs(np.log(got.astype(np.float64)) - ref).max() < 2e-6, kernel
    finally:
        _core.limit_model_simd("avx512")
    got = np.concatenate([cpp.eval_scalar(wi, wo, k) for k in range(3)], axis=1)
    assert np.abs(np.log(got.astype(np.float64)) - ref).max() < 2e-6
    # PyTorch in float64 normalises the float32 directions in float64 first (a change of ~1e-8)
    unit = [w.astype(np.float64) / np.linalg.norm(w.astype(np.float64), axis=1, keepdims=True) for w in (wi, wo)]
    got = np.concatenate([model.eval(wi, wo, k, dtype=torch.float64) for k in range(3)], axis=1)
    assert np.abs(np.log(got) - inputs_by_the_spec(*unit)).max() < 1e-12


def test_the_shipped_reciprocal_rgl_model_is_exactly_reciprocal_on_every_material():
    """results/rgl54_fast_reciprocal.safetensors (issue 60, docs/RECIPROCITY.md) with its energy
    tables: every one of its 54 materials bit-equal under the exchange, in libhybridbrdf's batched
    kernels and in PyTorch; the plain rgl54_fast fitted by the same recipe is the control."""
    from helpers import ROOT

    wi, wo = pairs()
    shipped = _core.Model(str(ROOT / "results" / "rgl54_fast_reciprocal.safetensors"))
    plain = _core.Model(str(ROOT / "results" / "rgl54_fast.safetensors"))
    assert len(shipped.materials) == 54
    torch_model = hb.load_model(ROOT / "results" / "rgl54_fast_reciprocal.safetensors")
    assert torch_model.arch["kind"] == "hybrid-reciprocal" and torch_model.arch.get("energy_bound")
    asymmetric = 0
    for m in range(54):
        f = shipped.eval(wi, wo, m)
        assert np.array_equal(f, shipped.eval(wo, wi, m)), m
        assert (f > 0).any(), m
        asymmetric += not np.array_equal(plain.eval(wi, wo, m), plain.eval(wo, wi, m))
    for m in (0, 27, 53):
        assert np.array_equal(torch_model.eval(wi, wo, m), torch_model.eval(wo, wi, m)), m
    assert asymmetric == 54


def test_the_shipped_reciprocal_prior_is_exactly_reciprocal_on_the_priors_materials():
    """python/hybridbrdf/data/prior_reciprocal.safetensors (issue 60): installed with the package bit
    for bit, the plain prior's materials in its order, energy tables on, and every material
    bit-equal under the exchange in libhybridbrdf; the plain prior is the control."""
    from hybridbrdf.model.prior import RECIPROCAL_PRIOR_FILE
    from helpers import ROOT

    source = ROOT / "python" / "hybridbrdf" / "data" / "prior_reciprocal.safetensors"
    assert RECIPROCAL_PRIOR_FILE.read_bytes() == source.read_bytes(), "the wheel did not carry the reciprocal prior"
    prior, plain = hb.load_prior(reciprocal=True), hb.load_prior()
    assert prior.arch["kind"] == "hybrid-reciprocal" and prior.arch.get("energy_bound")
    assert prior.materials == plain.materials and len(prior.materials) >= 100
    wi, wo = pairs()
    shipped, control = _core.Model(hb.prior_path(reciprocal=True)), _core.Model(hb.prior_path())
    asymmetric = 0
    for m in range(len(prior.materials)):
        f = shipped.eval(wi, wo, m)
        assert np.array_equal(f, shipped.eval(wo, wi, m)), prior.materials[m]
        assert (f > 0).any(), prior.materials[m]
        asymmetric += not np.array_equal(control.eval(wi, wo, m), control.eval(wo, wi, m))
    # The control: a material whose correction the guard removed is its f_a, reciprocal in either
    # prior (3 of the plain prior's 142); every other one is not.
    assert asymmetric >= 0.9 * len(prior.materials), asymmetric


def test_add_reciprocal_fits_onto_the_reciprocal_prior_and_stays_reciprocal(tmp_path, monkeypatch):
    """hbrdf add onto the shipped priors: by default (and with --reciprocal) the sparse fit and the
    fine-tune start from the reciprocal prior's network, so the model is reciprocal bit for bit;
    --no-reciprocal, the plain prior (the control: not reciprocal); either flag with --to is
    refused in one line before any training."""
    import hybridbrdf.model.prior as prior_module
    from hybridbrdf.fit import fit
    from hybridbrdf.fit.settings import FitSettings
    from hybridbrdf.sources import open_source

    # 5 steps: what is checked is which network the fit starts from and keeps, not how well it fits.
    tiny = dict(steps=5, batch=256, pool=2048, eval_pairs=2000, energy_bound=False, analytic_guard=False)
    for arch, name in (("hybrid-reciprocal", "RECIPROCAL_PRIOR_FILE"), ("hybrid", "PRIOR_FILE")):
        path = tmp_path / f"{arch}.safetensors"
        fit([open_source("synthetic:gold"), open_source("synthetic:plastic")],
            FitSettings(arch=arch, width=8, depth=1, latent=2, **tiny), progress=False, log=lambda m: None).save(path)
        monkeypatch.setattr(prior_module, name, path)
    wi, wo = pairs()
    for reciprocal, expected in ((None, True), (True, True), (False, False)):  # None: the default
        out = tmp_path / f"added_{reciprocal}.safetensors"
        model = hb.add(["synthetic:brushed_aluminium"], out=out, settings=FitSettings(**tiny), progress=False,
                       finetune_steps=5, reciprocal=reciprocal)
        assert model.training["mode"] == "fine-tune"
        f, g = _core.Model(str(out)).eval(wi, wo, 0), _core.Model(str(out)).eval(wo, wi, 0)
        assert (model.arch["kind"] == "hybrid-reciprocal") == expected, reciprocal
        assert np.array_equal(f, g) == expected, reciprocal
    for reciprocal in (True, False):
        with pytest.raises(ValueError, match="--reciprocal and --no-reciprocal choose between the shipped priors"):
            hb.add(["synthetic:velvet"], to=tmp_path / "hybrid.safetensors", reciprocal=reciprocal, progress=False)
