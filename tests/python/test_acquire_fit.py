"""The per-texel fits on a frozen prior and `hbrdf acquire fit` (docs/ACQUISITION.md, issue 46 step 2).

The samples are painted from materials of the shipped prior and photographed through the prior's
own output (ModelMaterialSource, float64), so the truth is exactly representable and known in
every direction, not only the photographed ones."""

import json
import os

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf.acquire import cluster_fit, cluster_merge, hybrid_fit
from hybridbrdf.acquire.acquisition import acquire, checkpoint_path
from hybridbrdf.acquire.capture import write_capture
from hybridbrdf.acquire.exposure import usable_pixels
from hybridbrdf.acquire.hybrid_fit import HybridMaps, fit_hybrid_texels
from hybridbrdf.acquire.mixture import Mixture
from hybridbrdf.acquire.neural_fit import NeuralMaps
from hybridbrdf.acquire.noise import NoiseModel
from hybridbrdf.acquire.observations import texel_observations
from hybridbrdf.acquire.rigs import flash_rig
from hybridbrdf.acquire import simulate
from hybridbrdf.acquire.texel_fit import fit_analytic_texels
from hybridbrdf.fit.checkpoint import CheckpointError
from hybridbrdf.model.file import load_model
from hybridbrdf.model.prior import load_prior
from hybridbrdf.sources.model import ModelMaterialSource

from helpers import seeded_cosine_directions

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
A, B = "paper_white_rgb.rgl", "vch_golden_yellow_rgb.rgl"


@pytest.fixture(autouse=True)
def one_thread():
    torch.set_num_threads(1)


def _halves(prior, w=8):
    weights = np.zeros((2, w, 2))
    weights[:, : w // 2, 0], weights[:, w // 2:, 1] = 1, 1
    return Mixture([ModelMaterialSource(prior, A), ModelMaterialSource(prior, B)], weights)


def _cmae(f, g, wi):
    return float(np.mean(np.abs((f - g) * wi[:, 2:3])))


@pytest.fixture(scope="module")
def halves_observations():
    prior = load_prior()
    rig = flash_rig(16, size=(40, 40))
    cap = simulate(rig, _halves(prior), NoiseModel(photons=4000.0, read_noise=1.0), seed=2)
    return prior, texel_observations(rig, cap.photos, (4, 2))


@pytest.fixture(scope="module")
def halves_fit(halves_observations):
    torch.set_num_threads(1)
    prior, obs = halves_observations
    return prior, obs, fit_hybrid_texels(obs, prior, steps=120, seed=0)


@pytest.mark.slow
def test_the_hybrid_fit_recovers_prior_materials_on_pure_texels_in_every_direction(halves_fit):
    prior, obs, maps = halves_fit
    assert (maps.counts > 0).all() and len(maps.layers) == 2
    assert (maps.layer[:, :2] == maps.layer[0, 0]).all() and (maps.layer[:, 2:] == maps.layer[0, 3]).all()
    assert maps.layer[0, 0] != maps.layer[0, 3]
    analytic = fit_analytic_texels(obs, steps=120)
    n = 20000
    wi, wo = seeded_cosine_directions(n, 1), seeded_cosine_directions(n, 2)
    for texel, name, within in ((0, A, 0.05), (4, A, 0.05), (3, B, 0.1), (7, B, 0.1)):
        truth = prior.eval(wi, wo, name, dtype=torch.float64)
        f = maps.eval(np.full(n, texel), wi, wo)
        scale = float(np.mean(np.abs(truth * wi[:, 2:3])))  # cMAE of a black BRDF
        err = _cmae(f, truth, wi)
        assert err < within * scale, (texel, name, err, scale)
        if name == B:  # glossy: the prior's network holds what one GGX lobe cannot (measured 6-20x)
            assert 3 * err < _cmae(analytic.eval(np.full(n, texel), wi, wo), truth, wi), texel


def test_the_written_folder_evaluates_in_libhybridbrdf_as_eval_does(halves_observations, tmp_path, monkeypatch):
    # A fit's maps, not a converged one's: what is written and read back is the same whatever the
    # fit's steps (its own fit: the module's accurate one would be fitted again on another worker).
    # Two clusters, as the sample has two materials: scoring a cluster against the prior's 142
    # materials costs ~1 s of CPU.
    monkeypatch.setattr(cluster_fit, "CLUSTER_STEPS", 10)
    monkeypatch.setattr(cluster_fit, "MAX_CLUSTERS", 2)
    monkeypatch.setattr(cluster_merge, "SPLIT_CLUSTERS", 2)  # k-means makes as many
    prior, obs = halves_observations
    maps = fit_hybrid_texels(obs, prior, steps=10, seed=0)
    maps.save(tmp_path / "sv")
    lib = hb._core.Svbrdf(str(tmp_path / "sv"))
    assert tuple(lib.size) == (4, 2) and lib.layer_count == 2
    sv = hb.load_svbrdf(str(tmp_path / "sv"))
    n = 4000
    texel = np.random.default_rng(3).integers(0, 8, n)
    uv = np.stack([(texel % 4 + 0.5) / 4, (texel // 4 + 0.5) / 2], axis=1)
    wi, wo = seeded_cosine_directions(n, 4), seeded_cosine_directions(n, 5)
    ours = maps.eval(texel, wi, wo)
    for filt in ("nearest", "bilinear"):  # at texel centres bilinear reads the texel alone
        got = lib.eval(uv.astype(np.float32), wi.astype(np.float32), wo.astype(np.float32), filt)
        np.testing.assert_allclose(got, ours, rtol=2e-4, atol=1e-6)
    np.testing.assert_allclose(sv.eval(uv, wi, wo), ours, rtol=2e-4, atol=1e-6)


def test_eval_of_uniform_maps_is_the_prior_materials_own_evaluation():
    # Every texel holding a material's own (p, z): eval must be the model's own f_t (head, energy table).
    prior = load_prior()
    n = 3000
    wi, wo = seeded_cosine_directions(n, 6), seeded_cosine_directions(n, 7)
    i, j = prior.index(A), prior.index(B)
    t = prior.tensors
    layer = np.array([[0, 1]])
    maps = HybridMaps(prior, [A, B], layer, *(np.stack([t[f"materials.{q}"][[i, j]]])
                                               for q in ("kd", "eta", "alpha", "z")), np.ones((1, 2)))
    for texel, name in ((0, A), (1, B)):
        np.testing.assert_allclose(maps.eval(np.full(n, texel), wi, wo),
                                   prior.eval(wi, wo, name, dtype=torch.float64), rtol=1e-4, atol=1e-6)
    neural = load_model(os.path.join(ROOT, "results", "rgl54_neural_32x3_10k.safetensors"))
    z = neural.tensors["materials.z"][[0, 5]][None]
    nm = NeuralMaps(neural, z, np.array([[0, 5]]), np.ones((1, 2)))
    for texel, m in ((0, 0), (1, 5)):
        np.testing.assert_allclose(nm.eval(np.full(n, texel), wi, wo),
                                   neural.eval(wi, wo, m, dtype=torch.float64), rtol=1e-4, atol=1e-6)


def _capture_folder(tmp_path, prior, photos_hook=None):
    rig = flash_rig(6, size=(24, 24))
    cap = simulate(rig, _halves(prior, 4))
    if photos_hook:
        photos_hook(cap.photos)
    write_capture(cap, tmp_path / "capture")
    return str(tmp_path / "capture")


class Stop(Exception):
    pass


def test_resume_continues_and_matches_and_nothing_is_half_written(tmp_path, monkeypatch):
    monkeypatch.setattr(cluster_fit, "CLUSTER_STEPS", 10)
    # Two clusters (the sample's two materials; a restored state of one would not show its clusters
    # swapped): each costs ~1 s of CPU scoring the prior's 142 materials, in each of three runs.
    monkeypatch.setattr(cluster_fit, "MAX_CLUSTERS", 2)
    monkeypatch.setattr(cluster_merge, "SPLIT_CLUSTERS", 2)  # k-means makes as many
    # The kd edits' energy tables (5 s each) are tested with hbrdf paint's; resuming does not touch them.
    monkeypatch.setattr(hybrid_fit, "bound_bright_kd", lambda model, names, kd_maps, log: (model, names))
    prior = load_prior()
    capture = _capture_folder(tmp_path, prior)
    whole = acquire(capture, tmp_path / "whole", size=(2, 2), steps=60)
    assert not os.path.lexists(checkpoint_path(tmp_path / "whole"))

    # 60 texel steps, stopped at 55: past the checkpoint of step 50, so the resumed run must both
    # restore a checkpoint and finish the steps after it to match the uninterrupted one.
    def stop_at(stage, done, total):
        if stage == "texels" and done == 55:
            raise Stop()

    out = tmp_path / "out"
    with pytest.raises(Stop):
        acquire(capture, out, size=(2, 2), steps=60, progress=stop_at)
    assert not os.path.lexists(out)  # nothing half-written
    assert os.path.isfile(checkpoint_path(out))
    with pytest.raises(CheckpointError, match="--resume continues it, --force replaces it"):
        acquire(capture, out, size=(2, 2), steps=60)
    with pytest.raises(CheckpointError, match="another run's"):
        acquire(capture, out, size=(2, 2), steps=61, resume=True)
    stages = []
    resumed = acquire(capture, out, size=(2, 2), steps=60, resume=True,
                      progress=lambda s, d, n: stages.append((s, d)))
    assert stages[0] == ("texels", 51)  # from the checkpoint at step 50: no stage redone
    for q in ("kd", "eta", "alpha", "z", "layer"):
        np.testing.assert_array_equal(getattr(resumed, q), getattr(whole, q))
    assert resumed.layers == whole.layers
    assert not os.path.lexists(checkpoint_path(out))
    # An interrupted run over a finished folder leaves it as it was.
    before = {p: open(os.path.join(out, p), "rb").read() for p in os.listdir(out)}
    with pytest.raises(Stop):
        acquire(capture, out, size=(2, 2), steps=60, progress=stop_at, force=True)
    assert {p: open(os.path.join(out, p), "rb").read() for p in os.listdir(out)} == before
    # A folder that is not a textured material's is refused before anything runs.
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    with pytest.raises(hb.errors.InputFileError, match="without svbrdf.json; refusing to replace it"):
        acquire(capture, tmp_path / "other", size=(2, 2), steps=10)


def test_nan_pixels_are_masked_and_counted():
    prior = load_prior()
    rig = flash_rig(4, size=(24, 24))
    photos = simulate(rig, _halves(prior, 4)).photos
    clean = texel_observations(rig, photos, (2, 2))
    bad = [p.copy() for p in photos]
    spots = [(0, 11, 12, 0), (0, 13, 10, 2), (2, 12, 12, 1)]  # (photo, row, column, channel)
    for k, r, c, ch in spots:
        bad[k][r, c, ch] = np.nan
    masks, report = usable_pixels(rig, bad)
    assert report["not finite"] == 3 and report["under-exposed"] == []
    assert sum(int((~m).sum()) for m in masks) == 3
    obs = texel_observations(rig, bad, (2, 2), usable=masks)
    assert np.isfinite(obs.value).all()
    assert obs.dropped["masked"] == 3 and obs.dropped["grazing"] == clean.dropped["grazing"]  # the spots see the sample head-on
    assert len(obs.value) == len(clean.value) - obs.dropped["masked"]
    with pytest.raises(ValueError, match="not finite"):  # unmasked, they are still refused
        texel_observations(rig, bad, (2, 2))


def test_an_under_exposed_capture_is_refused_in_one_line_and_one_dark_photograph_left_out(tmp_path):
    prior = load_prior()
    rig = flash_rig(4, size=(24, 24))
    photos = simulate(rig, _halves(prior, 4)).photos
    dark = [np.random.default_rng(k).normal(0.0, 0.01, p.shape).astype(np.float32) for k, p in enumerate(photos)]
    with pytest.raises(ValueError) as err:
        usable_pixels(rig, dark, floor=0.01, where="cap")
    assert "\n" not in str(err.value) and str(err.value).startswith("cap: nothing usable: 4 of 4 photographs under-exposed")
    zeros = [np.zeros_like(p) for p in photos]  # no stated floor, no background spread: all-zero photographs
    with pytest.raises(ValueError, match="4 of 4 photographs under-exposed"):
        usable_pixels(rig, zeros)
    one_dark = [dark[0]] + photos[1:]
    masks, report = usable_pixels(rig, one_dark, floor=0.01)
    assert report["under-exposed"] == [0] and not masks[0].any() and all(m.all() for m in masks[1:])
    # Through the command's run: refused before anything is written.
    def black(photos):
        for p in photos:
            p[:] = 0.0

    capture = _capture_folder(tmp_path, prior, black)
    with pytest.raises(ValueError, match="nothing usable"):
        acquire(capture, tmp_path / "out", size=(2, 2), steps=10)
    assert not os.path.lexists(tmp_path / "out") and not os.path.lexists(checkpoint_path(tmp_path / "out"))
    with pytest.raises(ValueError, match=r"--size \(texels\) 67,108,864: would allocate about"):  # before reading
        acquire(capture, tmp_path / "out", size=(8192, 8192), steps=10)
    assert json.load(open(os.path.join(capture, "capture.json")))["format_version"] == 1
