"""The fit's head refit (issue 61 part 2; docs/ACQUISITION_GAP.md): each cluster's output layer
refitted on its texels' observations, for a material whose shape no head of the prior holds.

The sample is one such material: a prior material with another output layer (a head between its
own and another material's), photographed through that model's float64 output
(ModelMaterialSource) by a small light stage, so the truth is known in every direction and is
exactly what a refitted head can represent on the prior's frozen hidden layers."""

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf.acquire import cluster_fit, cluster_merge, texel_rows
from hybridbrdf.acquire.hybrid_fit import HybridFamily, fit_hybrid_texels, with_cluster_heads
from hybridbrdf.acquire.mixture import Mixture
from hybridbrdf.acquire.noise import NoiseModel
from hybridbrdf.acquire.observations import texel_observations
from hybridbrdf.acquire.rigs import light_stage_rig
from hybridbrdf.acquire import simulate
from hybridbrdf.model.file import HybridModel
from hybridbrdf.model.prior import load_prior
from hybridbrdf.sources.model import ModelMaterialSource

from helpers import seeded_cosine_directions, split_effort_final_choice

SHAPE, OTHER = "vch_golden_yellow_rgb.rgl", "paper_white_rgb.rgl"


@pytest.fixture(autouse=True)
def one_thread():
    torch.set_num_threads(1)


def _novel(prior) -> HybridModel:
    """The prior plus "novel": SHAPE's values with a head halfway to OTHER's (no prior head)."""
    t = {k: v.copy() for k, v in prior.tensors.items()}
    a, b = prior.index(SHAPE), prior.index(OTHER)
    row = {k: v[a] for k, v in t.items() if k.startswith("materials.")}
    for key in ("materials.head_weight", "materials.head_bias"):
        row[key] = 0.5 * (t[key][a] + t[key][b])
    tensors = {k: np.concatenate([v, row[k][None].astype(v.dtype)]) if k.startswith("materials.") else v
               for k, v in t.items()}
    infos = [dict(m) for m in prior.material_info] + [dict(prior.material_info[a], name="novel")]
    return HybridModel(dict(prior.arch), infos, tensors, dict(prior.training))


@pytest.fixture(scope="module")
def novel_capture():
    prior = load_prior()
    novel = _novel(prior)
    rig = light_stage_rig(8, 3, size=(24, 24))
    sample = Mixture([ModelMaterialSource(novel, "novel")], np.ones((2, 2, 1)))
    cap = simulate(rig, sample, NoiseModel(photons=4000.0, read_noise=1.0), seed=3)
    return prior, novel, texel_observations(rig, cap.photos, (2, 2))


def test_a_refitted_head_fits_a_shape_no_prior_head_holds_better_where_photographed(novel_capture, monkeypatch):
    # The cluster chooses cc_ibiza_sunset_rgb.nbrdf, a material the guard set to its f_a (head
    # weights 0, biases -200 and 200: no gradient), so this also needs the refit's start (HEAD_START).
    # Measured in the paper's loss domain (eps 1): cMAE against the truth on the photographed
    # directions 0.00509 without the refit, 0.00253 with it (0.50x); the worst texel over all
    # directions 0.00756 and 0.00637 (0.84x). Without HEAD_START the refit could not move that head:
    # 0.79x and 0.98x. In the fits' domain (eps 0.1, texel_rows.LOSS_EPS) the fit without the refit
    # is already better over all directions (0.00638) and the refit holds it there (0.00663, 1.04x)
    # while it still nearly halves the photographed directions' error (0.00325 -> 0.00187, 0.58x).
    monkeypatch.setattr(cluster_fit, "MAX_CLUSTERS", 1)  # one material: one cluster
    monkeypatch.setattr(cluster_merge, "SPLIT_CLUSTERS", 1)  # k-means makes as many
    split_effort_final_choice(monkeypatch)
    prior, novel, obs = novel_capture
    n = 20000
    wi, wo = seeded_cosine_directions(n, 1), seeded_cosine_directions(n, 2)
    truth = novel.eval(wi, wo, "novel", dtype=torch.float64)
    rows_truth = novel.eval(obs.wi.astype(np.float64), obs.wo.astype(np.float64), "novel", dtype=torch.float64)
    texel = np.repeat(np.arange(4), np.diff(obs.offsets))
    for eps, worst_ratio in ((1.0, 0.95), (texel_rows.LOSS_EPS, 1.1)):
        monkeypatch.setattr(texel_rows, "LOSS_EPS", eps)
        seen, everywhere = {}, {}
        for refit in (False, True):
            maps = fit_hybrid_texels(obs, prior, steps=60, seed=0, refit_heads=refit)
            seen[refit] = float(np.mean(np.abs((maps.eval(texel, obs.wi, obs.wo) - rows_truth) * obs.wi[:, 2:3])))
            everywhere[refit] = max(float(np.mean(np.abs((maps.eval(np.full(n, t), wi, wo) - truth) * wi[:, 2:3])))
                                    for t in range(4))
        assert seen[True] < 0.65 * seen[False], (eps, seen)
        assert everywhere[True] < worst_ratio * everywhere[False], (eps, everywhere)


def test_refitted_heads_are_layers_of_their_own_that_libhybridbrdf_evaluates_as_eval_does(novel_capture, tmp_path,
                                                                                          monkeypatch):
    # A short fit (what is written and read back is the same whatever the steps): each cluster a
    # layer whose material is the prior's with the cluster's head, named <material>.acq<k>.
    monkeypatch.setattr(cluster_fit, "CLUSTER_STEPS", 10)
    monkeypatch.setattr(cluster_fit, "HEAD_STEPS", 10)
    monkeypatch.setattr(cluster_fit, "MAX_CLUSTERS", 2)
    monkeypatch.setattr(cluster_merge, "SPLIT_CLUSTERS", 2)  # k-means makes as many
    prior, _, obs = novel_capture
    maps = fit_hybrid_texels(obs, prior, steps=10, seed=0, refit_heads=True)
    assert all(".acq" in name for name in maps.layers) and len(maps.layers) == maps.layer.max() + 1
    for k, name in enumerate(maps.layers):
        source = name.split(".acq")[0]
        assert not np.array_equal(maps.model.tensors["materials.head_weight"][maps.model.index(name)],
                                  prior.tensors["materials.head_weight"][prior.index(source)])
    maps.save(tmp_path / "sv")
    lib = hb._core.Svbrdf(str(tmp_path / "sv"))
    n = 4000
    texel = np.random.default_rng(3).integers(0, 4, n)
    uv = np.stack([(texel % 2 + 0.5) / 2, (texel // 2 + 0.5) / 2], axis=1)
    wi, wo = seeded_cosine_directions(n, 4), seeded_cosine_directions(n, 5)
    ours = maps.eval(texel, wi, wo)
    got = lib.eval(uv.astype(np.float32), wi.astype(np.float32), wo.astype(np.float32), "nearest")
    np.testing.assert_allclose(got, ours, rtol=2e-4, atol=1e-6)
    np.testing.assert_allclose(hb.load_svbrdf(str(tmp_path / "sv")).eval(uv, wi, wo), ours, rtol=2e-4, atol=1e-6)


def test_a_cluster_layer_never_takes_a_name_its_prior_holds():
    # The prior may itself be an acquisition's model, holding <material>.acq0 already.
    prior = load_prior()
    m = prior.index(SHAPE)
    t = prior.tensors

    def one_cluster(model):
        family = HybridFamily(model)
        i = model.index(SHAPE)
        heads = {"weight": torch.from_numpy(t["materials.head_weight"][[m]]),
                 "bias": torch.from_numpy(t["materials.head_bias"][[m]]),
                 "centres": {n: v[[i]] for n, v in family.raw_of_materials().items()}}
        return with_cluster_heads(model, family, {"material": torch.tensor([i]), "heads": heads})

    first, (name,) = one_cluster(prior)
    second, (again,) = one_cluster(first)
    assert name not in prior.materials and again not in first.materials and again != name
    assert second.materials[:len(first.materials)] == first.materials
