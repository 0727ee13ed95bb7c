"""Model files: bit-exact round trip, atomic writes, and a clear ModelFileError
naming the file for every kind of damage."""

import os
import struct

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf import spec
from hybridbrdf.model.random import random_model

from helpers import hard_pairs, valid_upper


@pytest.mark.parametrize("arch", list(spec.ARCHS))
def test_save_then_load_is_bit_exact(tmp_path, arch):
    mod, model = random_model(arch, latent=4 if spec.ARCHS[arch]["analytic"] else 12, isotropic=[True, False, True])
    path = tmp_path / "m.safetensors"
    model.save(path)
    back = hb.load_model(path)
    assert back.materials == model.materials and back.arch == model.arch
    assert set(back.tensors) == set(model.tensors)
    for k in model.tensors:
        assert back.tensors[k].dtype == np.float32
        assert np.array_equal(back.tensors[k], model.tensors[k]), k
    rng = np.random.default_rng(0)
    wi, wo = np.abs(rng.normal(size=(500, 3))), np.abs(rng.normal(size=(500, 3)))
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    for m in model.materials:
        assert np.array_equal(back.eval(wi, wo, m), model.eval(wi, wo, m))
    # The loaded model computes what the training module computes.
    with torch.no_grad():
        f_mod = mod(torch.tensor(wi, dtype=torch.float32), torch.tensor(wo, dtype=torch.float32))[0].double().numpy()
    for i, m in enumerate(model.materials):
        # additive = max(f_a + o, 0) cancels: its rounding is absolute, relative to the terms' size.
        atol = 1e-5 if arch == "additive" else 1e-7  # its terms f_a and o are O(1)
        assert np.allclose(back.eval(wi, wo, m), f_mod[i], rtol=1e-5, atol=atol)
    # The file is a standard safetensors file.
    from safetensors.numpy import load_file

    std = load_file(str(path))
    assert all(np.array_equal(std[k], model.tensors[k]) for k in model.tensors)


def test_isotropic_materials_store_equal_alphas_and_eval_analytic_matches_the_cpp_library(tmp_path):
    _, model = random_model(isotropic=[True, False, True])
    alpha = model.tensors["materials.alpha"]
    assert alpha[0, 0] == alpha[0, 1] and alpha[2, 0] == alpha[2, 1]
    rng = np.random.default_rng(1)
    wi, wo = np.abs(rng.normal(size=(300, 3))), np.abs(rng.normal(size=(300, 3)))
    for m in model.materials:
        ref = hb.analytic_eval(wi, wo, model.analytic_params(m))
        assert np.allclose(model.eval_analytic(wi, wo, m), ref, rtol=2e-5, atol=1e-8)


def test_save_is_atomic(tmp_path, monkeypatch):
    _, model = random_model()
    path = tmp_path / "m.safetensors"
    model.save(path)
    before = path.read_bytes()

    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(OSError):
        model.save(path)
    assert path.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["m.safetensors"]


# Damaged files (every rule of the contract, both loaders alike): tests/data/malformed_models.json,
# run by test_model_contract.py.


def test_truncated_and_foreign_files(tmp_path):
    _, model = random_model()
    good = tmp_path / "good.safetensors"
    model.save(good)
    raw = good.read_bytes()
    cases = {
        "empty": b"",
        "header cut": raw[:20],
        "data cut": raw[:-7],
        "not json": struct.pack("<Q", 8) + b"notjson!" + b"\0" * 16,
        "random": os.urandom(200),
    }
    for name, data in cases.items():
        p = tmp_path / f"{name}.safetensors"
        p.write_bytes(data)
        with pytest.raises(hb.ModelFileError) as err:
            hb.load_model(p)
        assert str(p) in str(err.value), name
    with pytest.raises(hb.ModelFileError, match="no such file"):
        hb.load_model(tmp_path / "missing.safetensors")
    # A valid safetensors file that is not a hybridbrdf model.
    from safetensors.numpy import save_file

    other = tmp_path / "other.safetensors"
    save_file({"w": np.zeros(3, np.float32)}, str(other))
    with pytest.raises(hb.ModelFileError, match="not a hybridbrdf model"):
        hb.load_model(other)


def test_unknown_material_name():
    _, model = random_model()
    with pytest.raises(KeyError, match="no material 'nope'"):
        model.eval(np.zeros((1, 3)), np.zeros((1, 3)), "nope")


@pytest.mark.parametrize("arch", list(spec.ARCHS))
def test_models_are_zero_below_the_horizon_and_for_invalid_directions(arch):
    _, model = random_model(arch, latent=4 if spec.ARCHS[arch]["analytic"] else 12)
    wi, wo = hard_pairs()
    for dtype in (torch.float32, torch.float64):
        f = model.eval(wi, wo, 0, dtype=dtype)
        np_dtype = np.float32 if dtype == torch.float32 else np.float64
        valid = valid_upper(wi, np_dtype) & valid_upper(wo, np_dtype)
        assert np.isfinite(f).all() and (f >= 0).all()
        assert (f[~valid] == 0).all()
        # Scaling a direction does not change the value: the network sees unit vectors.
        # (atol: the additive ablation max(f_a + o, 0) cancels, so rounding is absolute there.)
        ok = valid & (np.abs(wi).max(axis=1) < 1e10)
        assert np.allclose(model.eval(3.0 * wi[ok], wo[ok], 0, dtype=dtype), f[ok], rtol=1e-5, atol=1e-6)


def test_saved_files_get_ordinary_permissions(tmp_path):
    _, model = random_model()
    path = tmp_path / "m.safetensors"
    old = os.umask(0o022)
    try:
        model.save(path)
    finally:
        os.umask(old)
    assert (path.stat().st_mode & 0o777) == 0o644


def test_a_model_saved_checked_evaluates_from_the_file_written(tmp_path):
    # save_checked writes a probe first; the model must end up pointing at the file it wrote,
    # not at the probe, which is deleted (the C++ evaluation would then fail to open it).
    _, model = random_model("hybrid", latent=4, isotropic=[True, False, True])
    path = tmp_path / "checked.safetensors"
    back = model.save_checked(path)
    assert model.path == str(path) and back.path == str(path)
    wi, wo = np.array([[0.3, 0.1, 0.95]]), np.array([[-0.2, 0.3, 0.93]])
    for m in model.materials:
        assert np.array_equal(model.eval(wi, wo, m), back.eval(wi, wo, m))
