"""The fits' observation model (hybridbrdf/acquire/footprint.py): a pixel predicted as the exported
textured material shows it (its own evaluation, SVBRDF.eval, is the reference), as the simulator's
mixture shows it, and what modelling the footprint buys at a layer boundary."""

import numpy as np
import pytest
import torch

from hybridbrdf.acquire import footprint, simulate
from hybridbrdf.acquire.footprint import Footprint
from hybridbrdf.acquire.hybrid_fit import HybridFamily, HybridMaps
from hybridbrdf.acquire.mixture import Mixture
from hybridbrdf.acquire.observations import texel_observations
from hybridbrdf.acquire.rigs import light_stage_rig
from hybridbrdf.acquire.texel_fit import fit_analytic_texels
from hybridbrdf.model.prior import load_prior
from hybridbrdf.sources.model import ModelMaterialSource
from hybridbrdf.sources.synthetic import LambertGGXDielectric

from helpers import seeded_cosine_directions

A, B = "acrylic_felt_purple_rgb", "blue-metallic-paint2"
NAMES = ("kd", "eta", "alpha", "z")


@pytest.fixture(autouse=True)
def one_thread():
    torch.set_num_threads(1)


def _layer_map(w=6, h=5):
    layer = np.zeros((h, w), np.int64)
    layer[:, w // 2:] = 1
    layer[0, 0] = 1  # a lone texel of layer 1 in layer 0's corner
    return layer


def _predict(prior, names, layer, values, fill, uv, wi, wo):
    family = HybridFamily(prior)
    material = torch.tensor([prior.index(n) for n in names])
    model = Footprint(uv, layer.shape[::-1], layer.reshape(-1), fill)
    with torch.no_grad():
        return model.predict(lambda k, v, a, b: family.evaluate_values(material[k], *(v[n] for n in NAMES), a, b),
                             values, torch.zeros(len(uv), dtype=torch.long), torch.arange(len(uv)),
                             torch.from_numpy(wi).float(), torch.from_numpy(wo).float()).double().numpy()


def test_the_footprint_predicts_what_the_exported_material_shows():
    prior = load_prior()
    t = prior.tensors
    layer = _layer_map()
    h, w = layer.shape
    rng = np.random.default_rng(0)
    own = {q: t[f"materials.{q}"][[prior.index(A), prior.index(B)]] for q in NAMES}
    maps = {q: own[q][layer] for q in NAMES}
    maps["kd"] = np.clip(maps["kd"] * rng.uniform(0.6, 1.2, (h, w, 1)), 0.01, 0.95).astype(np.float32)
    maps["z"] = (maps["z"] + 0.2 * rng.standard_normal(maps["z"].shape)).astype(np.float32)
    fit = HybridMaps(prior, [A, B], layer, maps["kd"], maps["eta"], maps["alpha"], maps["z"], np.ones((h, w)))
    n = 4000
    uv = rng.uniform(0, 1, (n, 2)).astype(np.float32)
    wi, wo = seeded_cosine_directions(n, 1), seeded_cosine_directions(n, 2)
    fill = {q: torch.from_numpy(np.stack([maps[q][layer == k].mean(0) for k in (0, 1)])) for q in NAMES}
    table = {q: torch.from_numpy(maps[q].reshape(h * w, -1)) for q in NAMES}
    got = _predict(prior, [A, B], layer, table, fill, uv, wi, wo)
    want = fit.svbrdf().eval(uv.astype(np.float64), wi, wo, dtype=torch.float64)
    np.testing.assert_allclose(got, want, rtol=2e-4, atol=1e-6)
    nearest = fit.eval(np.clip((uv[:, 1] * h).astype(int), 0, h - 1) * w + np.clip((uv[:, 0] * w).astype(int), 0, w - 1), wi, wo)
    assert np.abs(nearest - want).mean() > 20 * np.abs(got - want).mean()  # the test tells the two models apart


def test_layers_of_uniform_values_mix_as_the_simulators_mixture():
    # Each layer's texels at its material's own values: the pixel is the weights map's bilinear mix of
    # the two BRDFs, which is what the simulator photographs (Mixture, an independent implementation).
    prior = load_prior()
    t = prior.tensors
    layer = _layer_map()
    h, w = layer.shape
    own = {q: torch.from_numpy(t[f"materials.{q}"][[prior.index(A), prior.index(B)]]) for q in NAMES}
    table = {q: own[q][torch.from_numpy(layer.reshape(-1))] for q in NAMES}
    n = 3000
    uv = np.random.default_rng(1).uniform(0, 1, (n, 2))
    wi, wo = seeded_cosine_directions(n, 3), seeded_cosine_directions(n, 4)
    got = _predict(prior, [A, B], layer, table, own, uv, wi, wo)
    onehot = np.stack([layer == 0, layer == 1], axis=2).astype(np.float64)
    mixture = Mixture([ModelMaterialSource(prior, A), ModelMaterialSource(prior, B)], onehot)
    np.testing.assert_allclose(got, mixture.eval(uv, wi, wo), rtol=2e-4, atol=1e-6)


def test_the_footprint_fits_the_rim_of_a_layer_to_its_own_material(monkeypatch):
    # Two materials f_a represents exactly, split down the middle of an 8x8 map, photographed without
    # noise: with each pixel credited to its cell's texel, the rim texels come out between the two
    # materials; modelled as the footprint, at their own.
    left = LambertGGXDielectric("left", (0.7, 0.25, 0.1), 1.5, 0.3, 0.3)
    right = LambertGGXDielectric("right", (0.1, 0.45, 0.8), 1.5, 0.3, 0.3)
    size = 8
    weights = np.zeros((size, size, 2))
    weights[:, : size // 2, 0] = 1
    weights[:, size // 2:, 1] = 1
    rig = light_stage_rig(4, 2, size=(64, 64))
    capture = simulate(rig, Mixture([left, right], weights), seed=0)
    obs = texel_observations(rig, capture.photos, (size, size))
    truth = np.where(np.arange(size)[None, :, None] < size // 2, left.kd, right.kd)
    rim = [size // 2 - 1, size // 2]
    error = {}
    for model in ("nearest", "bilinear"):
        monkeypatch.setattr(footprint, "MODEL", model)
        kd = fit_analytic_texels(obs, steps=300, seed=0, rows_per_texel=32).kd
        error[model] = float(np.abs(kd - truth)[2:-2, rim].mean())  # rows away from the map's clamped edge
    assert error["bilinear"] < 0.02 and error["bilinear"] < 0.3 * error["nearest"], error


def test_an_unknown_observation_model_is_refused_by_name():
    from hybridbrdf.acquire.observations import Observations
    obs = Observations((1, 1), np.array([0, 0]), *(np.zeros((0, 3), np.float32),) * 3, np.zeros((0, 2), np.float32),
                       np.zeros(0, np.int32))
    with pytest.raises(ValueError, match="observation_model must be one of bilinear, nearest, got 'box'"):
        fit_analytic_texels(obs, steps=1, observation_model="box")
