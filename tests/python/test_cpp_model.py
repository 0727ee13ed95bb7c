"""libhybridbrdf reads model files without Python and computes what the
float64 PyTorch model computes. (Its loader rejects every damaged file the Python
loader rejects, with the same message: test_model_contract.py.)"""

import pathlib

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf import _core, spec
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.model.random import random_model

from helpers import hard_pairs, valid_upper

# Every architecture of the spec, and "ARCH:material" for each that can have material output
# layers (spec/model.json, output_layers: those with an analytic part).
ARCHS = list(spec.ARCHS) + [f"{a}:material" for a, d in spec.ARCHS.items() if d["analytic"]]


def _random(arch_spec, **kwargs):
    """random_model for an ARCHS entry: (module, HybridModel) and the bare architecture name."""
    arch, _, output_layer = arch_spec.partition(":")
    _, model = random_model(arch, latent=4 if spec.ARCHS[arch]["analytic"] else 12, output_layer=output_layer or "shared", **kwargs)
    return model, arch


@pytest.mark.parametrize("arch", ARCHS)
@pytest.mark.parametrize("activation", ["hardgelu", "relu"])
def test_cpp_model_agrees_with_float64_torch(tmp_path, arch, activation):
    model, arch = _random(arch, width=32, depth=3, isotropic=[True, False, True])
    model.arch["activation"] = activation
    path = tmp_path / "m.safetensors"
    model.save(path)
    py = hb.load_model(path)
    cpp = _core.Model(str(path))
    assert cpp.materials == py.materials
    rng = np.random.default_rng(4)
    wi = cosine_directions(rng, 20000).astype(np.float32).astype(np.float64)
    wo = cosine_directions(rng, 20000).astype(np.float32).astype(np.float64)
    worst = 0.0
    for m in range(len(py.materials)):
        ref = py.eval(wi, wo, m, dtype=torch.float64)
        got = cpp.eval(wi, wo, m).astype(np.float64)
        scalar = cpp.eval_scalar(wi, wo, m).astype(np.float64)
        # The vectorised batch path and the scalar path agree like two float32 roundings.
        assert np.allclose(got, scalar, rtol=1e-5, atol=1e-6 * np.abs(scalar).max() if spec.ARCHS[arch]["combine"] == "additive" else 1e-12)
        # Relative error where the value is not tiny; the additive ablation max(f_a + o, 0)
        # cancels, so it gets an absolute floor scaled by the magnitude of its terms.
        floor = 1e-6 * np.abs(ref).max() if spec.ARCHS[arch]["combine"] == "additive" else 1e-12
        rel = np.abs(got - ref) / np.maximum(np.abs(ref), floor / 1e-5)
        worst = max(worst, float(rel.max()))
        if spec.ARCHS[arch]["analytic"]:
            assert np.allclose(cpp.eval_analytic(wi, wo, m), py.eval_analytic(wi, wo, m, dtype=torch.float64),
                               rtol=2e-4, atol=1e-9)
    assert worst < 1e-5, worst


@pytest.mark.parametrize("arch", ARCHS)
def test_cpp_model_hard_cases(tmp_path, arch):
    model, arch = _random(arch)
    path = tmp_path / "m.safetensors"
    model.save(path)
    cpp = _core.Model(str(path))
    wi, wo = hard_pairs()
    valid = valid_upper(wi) & valid_upper(wo)
    for m in range(3):
        for f in (cpp.eval(wi, wo, m), cpp.eval_scalar(wi, wo, m)):
            assert np.isfinite(f).all() and (f >= 0).all()
            assert (f[~valid] == 0).all()


def test_cpp_loader_on_truncated_files(tmp_path):
    _, model = random_model()
    good = tmp_path / "good.safetensors"
    model.save(good)
    raw = good.read_bytes()
    for name, data in {"empty": b"", "header cut": raw[:20], "data cut": raw[:-7]}.items():
        p = tmp_path / f"{name}.safetensors"
        p.write_bytes(data)
        with pytest.raises(ValueError, match="truncated|not a safetensors"):
            _core.Model(str(p))
    with pytest.raises(ValueError, match="no such file"):
        _core.Model(str(tmp_path / "missing.safetensors"))


def _kernels():
    """The batched kernels this CPU can run, best first."""
    best = _core.model_simd_path()
    order = ["avx512", "avx2+fma", "baseline"]
    return order[order.index(best):]


@pytest.mark.parametrize("arch,width,depth", [("hybrid", 64, 3), ("hybrid", 16, 2), ("neural", 32, 2)])
def test_every_batched_kernel_agrees_with_float64_torch(tmp_path, arch, width, depth):
    """The register-blocked AVX-512 / AVX2 layers and the portable loop, each against torch
    float64: widths 16..64 and outputs 3 and 6 exercise full blocks and the remainders."""
    _, model = random_model(arch, latent=4 if spec.ARCHS[arch]["analytic"] else 12, width=width, depth=depth,
                            isotropic=[True, False, True])
    path = tmp_path / "m.safetensors"
    model.save(path)
    py = hb.load_model(path)
    cpp = _core.Model(str(path))
    rng = np.random.default_rng(5)
    n = 5003  # not a multiple of the 64-pair chunk
    wi = cosine_directions(rng, n).astype(np.float32).astype(np.float64)
    wo = cosine_directions(rng, n).astype(np.float32).astype(np.float64)
    kernels = _kernels()
    try:
        for kernel in kernels:
            _core.limit_model_simd(kernel)
            assert _core.model_simd_path() == kernel
            for m in range(3):
                ref = py.eval(wi, wo, m, dtype=torch.float64)
                got = cpp.eval(wi, wo, m).astype(np.float64)
                rel = np.abs(got - ref) / np.maximum(np.abs(ref), 1e-7)
                assert rel.max() < 1e-5, (kernel, m, rel.max())
    finally:
        _core.limit_model_simd("avx512")
    assert _core.model_simd_path() == kernels[0]
    with pytest.raises(ValueError, match="expected avx512"):
        _core.limit_model_simd("sse9")


RESULTS = sorted((pathlib.Path(__file__).resolve().parents[2] / "results").glob("*.safetensors"))


@pytest.mark.parametrize("path", RESULTS, ids=[p.name for p in RESULTS])
def test_every_model_in_results_loads_and_evaluates_alike_in_python_and_cpp(path):
    # The fitted models the docs quote stay readable by both loaders as the format code changes,
    # and C++ still computes what float64 PyTorch computes on them (real weights, not test ones).
    py = hb.load_model(path)
    cpp = _core.Model(str(path))
    assert cpp.materials == py.materials and len(py.materials) > 0
    rng = np.random.default_rng(11)
    wi = cosine_directions(rng, 2000).astype(np.float32).astype(np.float64)
    wo = cosine_directions(rng, 2000).astype(np.float32).astype(np.float64)
    for m in {0, len(py.materials) - 1}:
        ref = py.eval(wi, wo, m, dtype=torch.float64)
        got = cpp.eval(wi, wo, m).astype(np.float64)
        assert np.all(np.isfinite(got)) and np.all(got >= 0)
        rel = np.abs(got - ref) / np.maximum(np.abs(ref), 1e-7)
        assert rel.max() < 1e-4, (py.materials[m], float(rel.max()))


def test_batched_exp_over_its_whole_range(tmp_path):
    """The vectorised kernels' own exp (combine step) against float64 torch where the network's
    outputs sweep exp's range: f_c from the denormal range (o < -87) up to the pre-exp bound,
    and gates saturated at 0 and 1: the output layer is scaled and shifted so that the red
    channel's f_c and gate sit around exp(-95), the blue one's past the bound and at 1."""
    _, model = random_model("hybrid", width=32, depth=2)
    model.tensors["mlp.out.weight"] = model.tensors["mlp.out.weight"] * np.float32(20.0)
    model.tensors["mlp.out.bias"] = np.array([-95, 0, 10, -95, 0, 95], dtype=np.float32)
    path = tmp_path / "m.safetensors"
    model.save(path)
    py = hb.load_model(path)
    cpp = _core.Model(str(path))
    rng = np.random.default_rng(6)
    wi = cosine_directions(rng, 4099).astype(np.float32).astype(np.float64)
    wo = cosine_directions(rng, 4099).astype(np.float32).astype(np.float64)
    kernels = _kernels()
    try:
        for kernel in kernels:
            _core.limit_model_simd(kernel)
            ref = py.eval(wi, wo, 0, dtype=torch.float64)
            got = cpp.eval(wi, wo, 0).astype(np.float64)
            assert np.isfinite(got).all() and (got >= 0).all()
            assert ref.min() < 1e-30 and ref.max() > 1e5, (ref.min(), ref.max())  # the sweep reaches both ends
            # float32 normal range: relative error; below it, absolute. With |o| ~ 100 the network's
            # float32 rounding is amplified by exp: the scalar path (std::exp) is off by that much too.
            normal = ref > 1e-37
            rel = np.abs(got - ref)[normal] / ref[normal]
            assert rel.max() < 1e-4, (kernel, rel.max())
            # Denormal results are kept, not flushed to 0: the bound is a small fraction of FLT_MIN.
            assert np.abs(got - ref)[~normal].max() < 3e-41, kernel
    finally:
        _core.limit_model_simd("avx512")


def _numpy_hybrid_half(model_tensors, arch, wi, wo, m):
    """hybrid-half in NumPy float64 from the textbook forms: h = (wi + wo) / |wi + wo|, the
    network input [wi, wo, h.z, wi.h, z], hardGeLU layers, f_t = exp(o[0:3]) + sigmoid(o[3:6]) f_a
    with reference.textbook_fa: an oracle independent of the library's and the model's code."""
    from textbook_reference import textbook_fa
    t = {k: np.asarray(v, dtype=np.float64) for k, v in model_tensors.items()}
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    z = np.broadcast_to(t["materials.z"][m], (len(wi), arch["latent"]))
    x = np.concatenate([wi, wo, h[:, 2:3], (wi * h).sum(1, keepdims=True), z], axis=1)
    for i in range(arch["depth"]):
        x = x @ t[f"mlp.hidden.{i}.weight"].T + t[f"mlp.hidden.{i}.bias"]
        x = x * np.clip((x + 1.5) / 3.0, 0.0, 1.0)
    o = x @ t["mlp.out.weight"].T + t["mlp.out.bias"]
    fa = textbook_fa(wi, wo, t["materials.kd"][m], t["materials.eta"][m], t["materials.alpha"][m])
    return np.exp(np.minimum(o[:, :3], arch["pre_exp_max"])) + fa / (1.0 + np.exp(-o[:, 3:]))


def test_hybrid_half_matches_a_numpy_oracle(tmp_path):
    """The half-vector inputs are cos theta_h and cos theta_d in every implementation: the
    library's batched and scalar paths and the PyTorch model against a float64 NumPy oracle, and
    a model whose two half-vector weight columns are nonzero differs from one where they are zero
    (so the inputs are really read)."""
    _, model = random_model("hybrid-half", latent=4, width=16, depth=2, isotropic=[True, False, True])
    assert model.arch["n_in"] == 8 + 4
    path = tmp_path / "m.safetensors"
    model.save(path)
    py, cpp = hb.load_model(path), _core.Model(str(path))
    rng = np.random.default_rng(11)
    wi = cosine_directions(rng, 5000).astype(np.float32).astype(np.float64)
    wo = cosine_directions(rng, 5000).astype(np.float32).astype(np.float64)
    for m in range(3):
        ref = _numpy_hybrid_half(py.tensors, py.arch, wi, wo, m)
        for got in (cpp.eval(wi, wo, m), cpp.eval_scalar(wi, wo, m), py.eval(wi, wo, m, dtype=torch.float64)):
            rel = np.abs(np.asarray(got, np.float64) - ref) / np.maximum(np.abs(ref), 1e-12)
            assert rel.max() < 2e-4, rel.max()
    w = py.tensors["mlp.hidden.0.weight"].copy()
    w[:, 6:8] = 0.0
    zeroed = dict(py.tensors, **{"mlp.hidden.0.weight": w})
    assert not np.allclose(_numpy_hybrid_half(zeroed, py.arch, wi, wo, 0), _numpy_hybrid_half(py.tensors, py.arch, wi, wo, 0),
                           rtol=1e-3)
