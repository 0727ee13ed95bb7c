"""Fits that say what they chose (docs/ACQUISITION.md, "What the fit says"; issue 61 part 3): a line
per cluster with its material, loss and relative error and the runner-up's, a warning when no
material of the prior explains a cluster, a message or bar for every phase to the end, and the
choices recorded in the written folder."""

import json
import os

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf.acquire import cluster_fit, cluster_merge, hybrid_fit, simulate
from hybridbrdf.acquire.capture import write_capture
from hybridbrdf.acquire.cluster_report import POOR_EXCESS, cluster_report, poor_fit_warnings, report_lines
from hybridbrdf.acquire.hybrid_fit import HybridFamily
from hybridbrdf.acquire.mixture import Mixture
from hybridbrdf.acquire.noise import NoiseModel
from hybridbrdf.acquire.observations import texel_observations
from hybridbrdf.acquire.rigs import flash_rig
from hybridbrdf.model.prior import load_prior
from hybridbrdf.sources.model import ModelMaterialSource

from helpers import run_cli_here, shorten_acquire_fit

PAPER = "paper_white_rgb.rgl"


@pytest.fixture(autouse=True)
def one_thread():
    torch.set_num_threads(1)


def _halves(left, right, w=32):
    """Left and right halves of the sample; 32 weight texels, so that a 2x1 texel map's texels are
    pure but for the 1/32 of each that the bilinear weights mix at the border."""
    weights = np.zeros((1, w, 2))
    weights[:, : w // 2, 0], weights[:, w // 2:, 1] = 1, 1
    return Mixture([left, right], weights)


class Stop(Exception):
    pass


def _report(prior, mixture, noise):
    rig = flash_rig(8, size=(24, 24))
    obs = texel_observations(rig, simulate(rig, mixture, noise, seed=3).photos, (2, 1))
    family, out = HybridFamily(prior), {}

    def hook(labels, clusters):
        out["report"] = cluster_report(family, prior.materials, obs, rig, labels, clusters, 0, noise)
        raise Stop()  # the texel stage is not what is tested

    with pytest.raises(Stop):
        cluster_fit.fit_on_prior(family, obs, 40, 0, on_clusters=hook)
    return out["report"]


@pytest.mark.slow
def test_a_material_outside_the_prior_is_warned_about_and_prior_materials_are_not(monkeypatch):
    monkeypatch.setattr(cluster_fit, "MAX_CLUSTERS", 2)
    monkeypatch.setattr(cluster_merge, "SPLIT_CLUSTERS", 2)  # k-means makes as many
    prior = load_prior()
    noise = NoiseModel(4000.0, 1.0)
    inside = _report(prior, _halves(ModelMaterialSource(prior, PAPER), ModelMaterialSource(prior, "vch_golden_yellow_rgb.rgl")),
                     noise)
    outside = _report(prior, _halves(ModelMaterialSource(prior, PAPER), hb.open_source("synthetic:retroreflector")), noise)
    for report in (inside, outside):
        assert [e["texels"] for e in report] == [1, 1] and all(e["share"] == 0.5 for e in report)
        for e in report:
            assert len(e["candidates"]) == 2 and e["candidates"][0]["loss"] <= e["candidates"][1]["loss"]
            assert 0 < e["candidates"][0]["noise"] < 0.1  # 4,000 photons: a few percent
    assert {e["candidates"][0]["material"] for e in inside} == {PAPER, "vch_golden_yellow_rgb.rgl"}
    assert not any(e["poor"] for e in inside), [e["candidates"][0] for e in inside]
    assert poor_fit_warnings(inside) == []
    # The retroreflector (a lobe back toward the flash that no material of the prior has) is flagged,
    # the paper beside it is not.
    flagged = [e for e in outside if e["poor"]]
    assert len(flagged) == 1 and flagged[0]["candidates"][0]["material"] != PAPER
    assert flagged[0]["candidates"][0]["excess"] > POOR_EXCESS
    (line,) = poor_fit_warnings(outside)
    assert line.startswith(f"warning: cluster {flagged[0]['cluster']} (1 texels): its best prior material") and "\n" not in line
    lines = report_lines(outside)
    assert len(lines) == 2 and all("runner-up" in s and "relative error" in s and "loss" in s for s in lines)


def _capture(tmp_path, prior):
    rig = flash_rig(6, size=(24, 24))
    cap = simulate(rig, _halves(ModelMaterialSource(prior, PAPER), ModelMaterialSource(prior, "vch_golden_yellow_rgb.rgl"), 4))
    write_capture(cap, tmp_path / "capture")
    return str(tmp_path / "capture")


def test_the_command_prints_the_clusters_and_every_phase_and_records_the_choices(tmp_path, monkeypatch):
    monkeypatch.setattr(cluster_fit, "CLUSTER_STEPS", 10)
    monkeypatch.setattr(cluster_fit, "MAX_CLUSTERS", 2)
    monkeypatch.setattr(cluster_merge, "SPLIT_CLUSTERS", 2)  # k-means makes as many
    real = hybrid_fit.bound_bright_kd
    calls = []

    def counted(model, names, kd_maps, log):  # the energy tables (5 s each) are tested with hbrdf paint's
        calls.append(sorted(kd_maps))
        return model, names
    monkeypatch.setattr(hybrid_fit, "bound_bright_kd", counted)
    assert real is not counted
    capture = _capture(tmp_path, load_prior())
    out = tmp_path / "out"
    res = run_cli_here("acquire", "fit", capture, "--out", out, "--size", "2x2", "--steps", "10")
    assert res.returncode == 0, res.stderr
    cluster_lines = [s for s in res.stdout.splitlines() if s.startswith("cluster ")]
    assert len(cluster_lines) == 2 and all("texels (" in s and "runner-up" in s for s in cluster_lines)
    assert any(s.startswith(f"writing {out}") for s in res.stdout.splitlines())
    assert "acquisition.json" in res.stdout.splitlines()[-1]
    for stage in ("analytic", "clusters", "texels", "energy tables"):  # one bar per phase, to the end
        assert stage in res.stderr
    assert calls == [[k] for k in range(len(calls))] and calls  # a bar step per layer
    report = json.load(open(os.path.join(out, "acquisition.json")))
    svbrdf = json.load(open(os.path.join(out, "svbrdf.json")))
    assert report["layers"] == [layer["material"] for layer in svbrdf["layers"]]
    assert report["refit_heads"] is False and not any(".acq" in name for name in report["layers"])
    assert [c["cluster"] for c in report["clusters"]] == [0, 1] and sum(c["texels"] for c in report["clusters"]) == 4
    for c in report["clusters"]:
        assert c["layer"] in report["layers"] and c["candidates"][0]["material"] in c["layer"]
        # "tied": how many of the final choice's candidates tied (acquire/consensus.py); "consensus" with 3 or more
        assert set(c["candidates"][0]) - {"consensus"} == {"material", "loss", "relative_error", "noise", "excess", "tied"}
    quiet = run_cli_here("acquire", "fit", capture, "--out", tmp_path / "quiet", "--size", "2x2", "--steps", "10",
                         "--quiet")
    assert quiet.returncode == 0 and quiet.stdout.count("\n") == 1 and quiet.stdout.startswith("wrote ")
    assert "energy tables" not in quiet.stderr and "cluster" not in quiet.stderr


def test_refit_heads_on_the_command_line_gives_each_cluster_its_head_and_is_recorded(tmp_path, monkeypatch):
    # `hbrdf acquire fit --refit-heads` (docs/ACQUISITION_GAP.md): each cluster a layer <material>.acq<k>
    # whose head is not its prior material's, and acquisition.json says the refit ran. A short fit:
    # what is checked is that the flag reaches the fit, not what the refit buys (test_acquire_gap.py).
    shorten_acquire_fit(monkeypatch)
    monkeypatch.setattr(cluster_fit, "HEAD_STEPS", 10)
    prior = load_prior()
    out = tmp_path / "out"
    res = run_cli_here("acquire", "fit", _capture(tmp_path, prior), "--out", out, "--size", "2x2", "--steps", "10",
                       "--refit-heads", "--quiet")
    assert res.returncode == 0, res.stderr
    assert "each cluster with its head refitted" in res.stdout
    report = json.load(open(os.path.join(out, "acquisition.json")))
    assert report["refit_heads"] is True
    assert [c["layer"] for c in report["clusters"]] == report["layers"] and len(report["layers"]) == 2
    model = hb.load_model(os.path.join(out, json.load(open(os.path.join(out, "svbrdf.json")))["model"]))
    for c in report["clusters"]:
        source = c["candidates"][0]["material"]
        assert c["layer"].startswith(source + ".acq")
        assert not np.array_equal(model.tensors["materials.head_weight"][model.index(c["layer"])],
                                  prior.tensors["materials.head_weight"][prior.index(source)])


def test_a_consensus_choice_says_how_many_candidates_tied():
    def cand(name, loss, **extra):
        return {"material": name, "loss": loss, "relative_error": 0.1, "noise": 0.02, "excess": 0.098, **extra}
    entry = {"cluster": 0, "texels": 12, "share": 0.5, "poor": False,
             "candidates": [cand("satin_gold_rgb.rgl", 0.0005, tied=4, consensus=True), cand("vch_ultra_pink_rgb.rgl", 0.0004, tied=4)]}
    (line,) = report_lines([entry])
    assert "consensus of 4 candidates" in line and line.index("satin_gold") < line.index("runner-up vch_ultra_pink")
    plain = {**entry, "candidates": [cand("satin_gold_rgb.rgl", 0.0004, tied=1), cand("vch_ultra_pink_rgb.rgl", 0.0005, tied=1)]}
    assert "consensus" not in report_lines([plain])[0]
