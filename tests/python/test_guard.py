"""Never worse than f_a (hybridbrdf.fit.guard; docs/FITTING.md, "Never worse than f_a"): a material
whose hybrid measures worse than its own analytic part after a fit is restarted, tempered or set
to its f_a, and the others are not touched. The damaged material is made here by hand (its
correction multiplied by e^4), so the guard has something to repair whatever the fit did; its
metrics before the repair are the control."""

import dataclasses

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf.evaluate.evaluation import evaluate
from hybridbrdf.fit import joint as fit_module
from hybridbrdf.fit import guard
from hybridbrdf.fit import fit
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.model.random import random_model
from hybridbrdf.sources import open_source


def small_settings(**kw):
    return FitSettings(steps=300, batch=512, pool=8192, eval_pairs=20000, width=16, depth=2, seed=3,
                       energy_bound=False, analytic_guard=False, **kw)


@pytest.fixture(scope="module")
def fitted():
    srcs = [open_source("synthetic:" + n) for n in ("plastic", "rough_clay")]
    settings = small_settings()
    model = fit(srcs, settings, progress=False, log=lambda msg: None)
    return model, srcs, settings


def damaged(model, srcs, settings, i=0, dc=4.0):
    """``model`` with material ``i``'s correction multiplied by e^dc, its metrics re-measured."""
    tensors = dict(model.tensors)
    b = tensors["materials.head_bias"].copy()
    b[i, 0:3] += dc
    tensors["materials.head_bias"] = b
    bad = hb.HybridModel(dict(model.arch), [dict(m) for m in model.material_info], tensors, model.training)
    for info, row in zip(bad.material_info, evaluate(bad, srcs, n_pairs=settings.eval_pairs, names=bad.materials)):
        info["metrics"] = {k: v for k, v in row.items() if k not in ("material", "origin")}
    return bad


def test_a_damaged_material_is_repaired_and_the_other_left_alone(fitted):
    model, srcs, settings = fitted
    bad = damaged(model, srcs, settings)
    assert guard.is_worse(bad.material_info[0]["metrics"])  # the control: the damage shows
    log = []
    fixed = guard.apply(bad, srcs, bad.materials, settings, fit, log=log.append, steps=200)
    rec = fixed.material_info[0]
    assert not guard.is_worse(rec["metrics"])
    assert rec["guard"]["action"] in ("restart", "tempered", "analytic")
    assert rec["guard"]["before"]["smape"] == bad.material_info[0]["metrics"]["smape"]
    assert len(log) == 1 and bad.materials[0] in log[0]
    # the metrics recorded are the model's own (evaluate's pairs)
    again = evaluate(fixed, srcs[:1], n_pairs=settings.eval_pairs, names=fixed.materials[:1])[0]
    assert again["smape"] == pytest.approx(rec["metrics"]["smape"], rel=1e-9)
    for k, v in bad.tensors.items():  # the other material and the network: bit for bit
        if k.startswith("materials."):
            assert np.array_equal(fixed.tensors[k][1], v[1]), k
        else:
            assert np.array_equal(fixed.tensors[k], v), k


def test_the_analytic_head_makes_f_t_equal_f_a(fitted, tmp_path):
    model, _, _ = fitted
    a = guard.analytic_head(model, 1).save_checked(tmp_path / "a.safetensors")
    rng = np.random.default_rng(4)
    wi, wo = np.abs(rng.normal(size=(3000, 3))), np.abs(rng.normal(size=(3000, 3)))
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    # libhybridbrdf's batched kernels use polynomial exp and sigmoid: f_t = f_a to a few float32 ulps
    np.testing.assert_allclose(a.eval(wi, wo, 1), a.eval_analytic(wi, wo, 1), rtol=1e-6)
    np.testing.assert_allclose(a.eval(wi, wo, 1, dtype=torch.float64), a.eval_analytic(wi, wo, 1, dtype=torch.float64),
                               rtol=1e-12)
    assert not np.allclose(a.eval(wi, wo, 0), a.eval_analytic(wi, wo, 0))  # material 0 keeps its correction


def test_a_shared_output_layer_is_left_as_it_is_and_said_so():
    _, model = random_model("hybrid", n=2)  # shared output layer: no head to change per material
    model.material_info[0]["metrics"] = {"smape": 0.9, "cmae": 0.1, "smape_analytic": 0.1, "cmae_analytic": 0.01}
    log = []
    assert guard.apply(model, [None, None], model.materials, small_settings(), fit, log=log.append) is model
    assert "shared output layer" in log[0]


def test_every_fit_ends_with_the_guard_unless_told_not_to(monkeypatch):
    calls = []
    monkeypatch.setattr(fit_module.guard, "apply", lambda model, *a, **k: calls.append(a) or model)
    srcs = [open_source("synthetic:plastic")]
    fit(srcs, dataclasses.replace(small_settings(), analytic_guard=True, steps=20), progress=False, log=lambda m: None)
    assert len(calls) == 1
    fit(srcs, dataclasses.replace(small_settings(), steps=20), progress=False, log=lambda m: None)  # --no-analytic-guard
    assert len(calls) == 1
