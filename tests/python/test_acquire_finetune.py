"""The acquisition fit's network fine-tune (issue 61 part 2; docs/ACQUISITION_GAP.md,
acquire/network_tune.py): the prior's network, the cluster's head and values trained on the
capture with the prior's own materials replayed, then the texels fitted on the tuned network.

The sample is a material the prior lacks: a prior material evaluated through hidden layers that
differ from the prior's (its second hidden layer's weights scaled by 1 + 0.3 N(0, 1) per element),
photographed through that model's float64 output by a small light stage onto 2x2 texels, so no
(p, z) and no head on the prior's network holds it exactly."""

import json
import os

import numpy as np
import pytest
import torch
from helpers import run_cli_here, seeded_cosine_directions, shorten_acquire_fit, split_effort_final_choice
from test_acquire_report import _capture

import hybridbrdf as hb
from hybridbrdf.acquire import cluster_fit, cluster_merge, network_tune, simulate
from hybridbrdf.acquire.hybrid_fit import HybridFamily, fit_hybrid_texels
from hybridbrdf.acquire.mixture import Mixture
from hybridbrdf.acquire.noise import NoiseModel
from hybridbrdf.acquire.observations import Observations, texel_observations
from hybridbrdf.acquire.rigs import light_stage_rig
from hybridbrdf.acquire.texel_rows import ObservationTensors
from hybridbrdf.evaluate.metrics import smape
from hybridbrdf.fit.settings import MAX_DRIFT
from hybridbrdf.model.file import HybridModel
from hybridbrdf.model.prior import load_prior
from hybridbrdf.sources.model import ModelMaterialSource

SHAPE = "vch_golden_yellow_rgb.rgl"
#: The drift the fine-tune may cost the prior's materials (SMAPE of the written model against the
#: prior on 1,000 cosine pairs each): the median and the worst over the prior's 142 materials. The
#: worst is hbrdf add --refine's limit on a base's materials (fit.settings.MAX_DRIFT).
MEDIAN_DRIFT, WORST_DRIFT = 0.05, MAX_DRIFT


@pytest.fixture(autouse=True)
def one_thread():
    torch.set_num_threads(1)


@pytest.fixture(scope="module")
def fits():
    torch.set_num_threads(1)  # before one_thread (a module fixture runs first): two threads on a busy machine crawl
    prior = load_prior()
    t = {k: v.copy() for k, v in prior.tensors.items()}
    w = t["mlp.hidden.1.weight"]
    t["mlp.hidden.1.weight"] = (w * (1 + 0.3 * np.random.default_rng(0).standard_normal(w.shape))).astype(w.dtype)
    lacking = HybridModel(dict(prior.arch), prior.material_info, t, dict(prior.training))
    rig = light_stage_rig(8, 3, size=(24, 24))
    sample = Mixture([ModelMaterialSource(lacking, SHAPE)], np.ones((2, 2, 1)))
    obs = texel_observations(rig, simulate(rig, sample, NoiseModel(photons=4000.0, read_noise=1.0), seed=3).photos, (2, 2))
    mp = pytest.MonkeyPatch()
    mp.setattr(cluster_fit, "MAX_CLUSTERS", 1)  # one material: one cluster
    mp.setattr(cluster_merge, "SPLIT_CLUSTERS", 1)  # k-means makes as many
    split_effort_final_choice(mp)
    try:
        return prior, obs, {n: fit_hybrid_texels(obs, prior, steps=60, seed=0, finetune_network=n) for n in (0, 100)}
    finally:
        mp.undo()


def test_the_finetune_lowers_the_photometric_loss_of_a_material_the_prior_lacks(fits):
    # Measured: the mean squared residual of the paper's loss over the capture's observations
    # 3.58e-4 on the frozen network, 7.86e-5 fine-tuned 100 steps (0.22x; 2.68e-5 after 200 steps).
    # With the fine-tune's rates at 0 (network_tune.NETWORK_LR, HEAD_LR) 3.58e-4: seen failing.
    prior, obs, maps = fits
    data = ObservationTensors(obs)
    texel = np.repeat(np.arange(4), np.diff(obs.offsets))

    def loss(m):
        d = data.residual(torch.arange(len(texel)), torch.from_numpy(m.eval(texel, obs.wi, obs.wo)))
        return float((d * d).mean())

    frozen, tuned = loss(maps[0]), loss(maps[100])
    assert tuned < 0.5 * frozen, (tuned, frozen)
    record = maps[100].model.training["acquisition_finetune"]
    assert record["capture_loss"][1] < record["capture_loss"][0]
    assert all(".acq" in name for name in maps[100].layers)


def test_the_finetune_keeps_the_prior_materials_within_the_stated_drift(fits):
    # The written model's network is the tuned one (not the prior's), and every prior material,
    # evaluated through it with its own (p, z), head and energy table, stays near the prior's output.
    # Measured: median 0.024, worst 0.456 (black-obsidian, a dark material whose SMAPE moves most);
    # without the replay (network_tune.REPLAY_WEIGHT = 0) median 0.100, worst 1.008: seen failing.
    prior, _, maps = fits
    model = maps[100].model
    assert not np.array_equal(model.tensors["mlp.hidden.1.weight"], prior.tensors["mlp.hidden.1.weight"])
    assert np.array_equal(maps[0].model.tensors["mlp.hidden.1.weight"], prior.tensors["mlp.hidden.1.weight"])
    wi, wo = seeded_cosine_directions(1000, 7), seeded_cosine_directions(1000, 8)
    drift = np.array([smape(prior.eval(wi, wo, name), model.eval(wi, wo, name)) for name in prior.materials])
    assert np.median(drift) < MEDIAN_DRIFT and drift.max() < WORST_DRIFT, (np.median(drift), drift.max(),
                                                                          prior.materials[int(drift.argmax())])
    recorded = model.training["acquisition_finetune"]["drift"]
    assert recorded["worst_smape"] < WORST_DRIFT and recorded["median_smape"] < MEDIAN_DRIFT


def test_finetune_network_on_the_command_line_writes_the_tuned_network_and_its_drift(tmp_path, monkeypatch):
    # `hbrdf acquire fit --finetune-network STEPS`: a short fit on the 2x2 capture fixture; what is
    # checked is that the flag reaches the fit and the written folder, not what the fine-tune buys.
    shorten_acquire_fit(monkeypatch)
    monkeypatch.setattr(network_tune, "DRIFT_PAIRS", 200)
    prior = load_prior()
    out = tmp_path / "out"
    res = run_cli_here("acquire", "fit", _capture(tmp_path, prior), "--out", out, "--size", "2x2", "--steps", "10",
                       "--finetune-network", "20", "--quiet")
    assert res.returncode == 0, res.stderr
    assert "the network fine-tuned 20 steps" in res.stdout
    report = json.load(open(os.path.join(out, "acquisition.json")))
    assert report["finetune_network"] == 20 and report["refit_heads"] is False
    assert set(report["replay_drift"]) == {"median_smape", "median_cmae", "worst_smape", "worst_cmae", "worst_material"}
    assert report["replay_drift"]["worst_material"] in prior.materials
    assert all(".acq" in c["layer"] for c in report["clusters"])
    model = hb.load_model(os.path.join(out, json.load(open(os.path.join(out, "svbrdf.json")))["model"]))
    assert not np.array_equal(model.tensors["mlp.hidden.0.weight"], prior.tensors["mlp.hidden.0.weight"])
    assert model.materials[:len(prior.materials)] == prior.materials


def test_the_anchor_keeps_a_cluster_from_brightening_where_no_photograph_looked(monkeypatch):
    # A capture that sees one narrow cone of directions (both near the normal) and photographs the
    # material 3x brighter there than the prior's: the fine-tune brightens the cluster to match. Where
    # no photograph looked (both directions beyond 60 degrees) the one-sided anchor holds it near its
    # start: without it (network_tune.ANCHOR_WEIGHT = 0) it brightens there too, as a vch_golden_yellow
    # capture's layer once did by orders of magnitude (docs/ACQUISITION_GAP.md). Compared: the mean
    # log brightening there over the start, anchored and free.
    prior = load_prior()
    family = HybridFamily(prior)
    m = prior.index("red-plastic")
    every = family.raw_of_materials()
    clusters = {"material": torch.tensor([m]), "centres": {k: v[m:m + 1].clone() for k, v in every.items()},
                "sigma2": torch.tensor([1e-3])}
    wi, wo = seeded_cosine_directions(20000, 1), seeded_cosine_directions(20000, 2)
    seen = (wi[:, 2] > 0.9) & (wo[:, 2] > 0.9)
    wi, wo = torch.from_numpy(wi[seen].astype(np.float32)), torch.from_numpy(wo[seen].astype(np.float32))
    raw = {k: v.expand(len(wi), -1) for k, v in clusters["centres"].items()}
    with torch.no_grad():
        g = 3 * family.evaluate(torch.full((len(wi),), m), raw, wi, wo)
    n = len(g)
    obs = Observations((1, 1), np.array([0, n]), wi.numpy(), wo.numpy(), g.numpy().astype(np.float32),
                       np.zeros((n, 2), np.float32), np.zeros(n, np.int32))
    far_i, far_o = (torch.from_numpy(d.astype(np.float32)) for d in
                    (seeded_cosine_directions(4000, 3), seeded_cosine_directions(4000, 4)))
    far = (far_i[:, 2] < 0.5) & (far_o[:, 2] < 0.5)
    far_i, far_o = far_i[far], far_o[far]
    with torch.no_grad():
        start = family.evaluate(torch.full((len(far_i),), m), {k: v.expand(len(far_i), -1) for k, v in
                                                                clusters["centres"].items()}, far_i, far_o)
    brightening, default = {}, network_tune.ANCHOR_WEIGHT
    for weight in (default, 0.0):
        monkeypatch.setattr(network_tune, "ANCHOR_WEIGHT", weight)
        tuned = network_tune.finetune_network(family, obs, ObservationTensors(obs), np.zeros(1, np.int64), clusters,
                                              cluster_fit.start_heads(family, clusters), 100, seed=0)
        view = network_tune.tuned_family(family, tuned["network"]).with_heads(clusters["material"], tuned["weight"],
                                                                              tuned["bias"])
        with torch.no_grad():
            f = view.evaluate(torch.zeros(len(far_i), dtype=torch.long),
                              {k: v.expand(len(far_i), -1) for k, v in tuned["centres"].items()}, far_i, far_o)
            brightening[weight] = float(torch.log(f.clamp_min(1e-8) / start.clamp_min(1e-8)).clamp_min(0).mean())
        assert tuned["loss"][1] < 0.5 * tuned["loss"][0]  # the capture is fitted either way
    assert brightening[default] < 0.5 * brightening[0.0], brightening  # measured 0.49 against 3.04


@pytest.mark.parametrize("lights", [8, 7])
def test_the_fit_fine_tunes_the_network_by_default_from_32_photographs_on(lights, tmp_path, monkeypatch):
    # acquire() with no finetune_network: the fine-tune runs on a light stage of 8 x 4 = 32
    # photographs (FINETUNE_STEPS steps, recorded, each cluster a .acq layer) and not on one of 7 x 4.
    # The steps are cut to 5: what is checked is the rule, not what the fine-tune buys.
    from hybridbrdf.acquire import acquisition, sizes
    from hybridbrdf.acquire.capture import write_capture

    shorten_acquire_fit(monkeypatch)
    monkeypatch.setattr(network_tune, "DRIFT_PAIRS", 200)
    monkeypatch.setattr(sizes, "FINETUNE_STEPS", 5)
    prior = load_prior()
    rig = light_stage_rig(lights, 4, size=(16, 16))
    sample = Mixture([ModelMaterialSource(prior, "red-plastic")], np.ones((2, 2, 1)))
    write_capture(simulate(rig, sample, NoiseModel(photons=4000.0, read_noise=1.0), seed=3), tmp_path / "capture")
    maps = acquisition.acquire(tmp_path / "capture", tmp_path / "out", size=(2, 2), steps=10)
    report = json.load(open(tmp_path / "out" / acquisition.REPORT_FILE))
    tuned = lights * 4 >= sizes.FINETUNE_MIN_SHOTS
    assert report["finetune_network"] == (5 if tuned else 0), report["finetune_network"]
    assert all((".acq" in name) == tuned for name in maps.layers), maps.layers
    assert ("acquisition_finetune" in maps.model.training) == tuned
