"""The acquisition fits' isotropy assumption (hybridbrdf.acquire.isotropy): observations turned about
the normal keep every isotropic BRDF's value, spread the rig's azimuths over the circle, and reach
the fit unless ``--anisotropic`` asks for the azimuths as photographed."""

import json
import os

import numpy as np
import pytest
from helpers import run_cli_here, shorten_acquire_fit
from test_acquire_report import _capture

from hybridbrdf.acquire import acquisition, hybrid_fit
from hybridbrdf.acquire.isotropy import turned_about_normal
from hybridbrdf.acquire.noise import NoiseModel
from hybridbrdf.acquire.observations import texel_observations
from hybridbrdf.acquire.rigs import light_stage_rig
from hybridbrdf.acquire.simulation import simulate
from hybridbrdf.acquire.mixture import Mixture
from hybridbrdf.brdf.microfacet import ggx_microfacet
from hybridbrdf.model.prior import load_prior
from hybridbrdf.sources.model import ModelMaterialSource


def _light_stage_observations():
    prior = load_prior()
    rig = light_stage_rig(4, 2, size=(24, 24))
    sample = Mixture([ModelMaterialSource(prior, prior.materials[0])], np.ones((4, 4, 1)))
    return texel_observations(rig, simulate(rig, sample, NoiseModel(photons=4000.0, read_noise=1.0), seed=1).photos, (4, 4))


def _azimuth(w):
    return np.arctan2(w[:, 1], w[:, 0])


def test_turned_rows_keep_every_isotropic_value_and_spread_the_azimuths():
    obs = _light_stage_observations()
    turned = turned_about_normal(obs, seed=3)
    wi, wo, ti, to = (x.astype(np.float64) for x in (obs.wi, obs.wo, turned.wi, turned.wo))
    # theta_i, theta_o and the azimuth between the directions are kept (float32 rounding only).
    np.testing.assert_allclose(ti[:, 2], wi[:, 2], atol=1e-6)
    np.testing.assert_allclose(to[:, 2], wo[:, 2], atol=1e-6)
    np.testing.assert_allclose(np.sum(ti * to, axis=1), np.sum(wi * wo, axis=1), atol=2e-6)
    np.testing.assert_allclose(np.linalg.norm(ti, axis=1), 1.0, atol=2e-6)
    # An isotropic GGX lobe (float64, brdf.microfacet) reads the same at every row; an anisotropic one does not.
    for ax, ay, same in ((0.3, 0.3, True), (0.1, 0.5, False)):
        before, _ = ggx_microfacet(wi, wo, ax, ay)
        after, _ = ggx_microfacet(ti, to, ax, ay)
        rel = np.abs(after - before) / np.maximum(before, 1e-12)
        assert (rel.max() < 1e-4) if same else (np.median(rel) > 0.05), (ax, ay, rel.max(), np.median(rel))
    # The rig's 8 shots see a few azimuths; turned, they cover the circle: chi-square over 12 bins.
    counts = np.histogram(_azimuth(ti), bins=12, range=(-np.pi, np.pi))[0]
    expected = len(ti) / 12
    chi2 = float(((counts - expected) ** 2 / expected).sum())
    assert chi2 < 32.9, chi2  # the 0.999 quantile of chi-square with 11 degrees of freedom
    photographed = np.histogram(_azimuth(wi), bins=12, range=(-np.pi, np.pi))[0]
    assert float(((photographed - expected) ** 2 / expected).sum()) > 10 * 32.9  # what the turn removed (2,589 here)
    # Everything but the directions is the photographs' own; the draw is the seed's.
    for name in ("value", "uv", "shot", "offsets"):
        assert getattr(turned, name) is getattr(obs, name)
    np.testing.assert_array_equal(turned_about_normal(obs, seed=3).wi, turned.wi)
    assert not np.allclose(turned_about_normal(obs, seed=4).wi, turned.wi)


@pytest.mark.parametrize("anisotropic", [False, True])
def test_the_fit_reads_turned_rows_unless_anisotropic(tmp_path, monkeypatch, anisotropic):
    # `hbrdf acquire fit [--anisotropic]`: the rows the fit receives are turned about the normal by
    # default and as photographed with the flag; the choice is recorded in acquisition.json.
    shorten_acquire_fit(monkeypatch)
    seen = []
    real = hybrid_fit.fit_hybrid_texels

    def recording(obs, *args, **kwargs):
        seen.append(obs)
        return real(obs, *args, **kwargs)
    monkeypatch.setattr(hybrid_fit, "fit_hybrid_texels", recording)
    capture, out = _capture(tmp_path, load_prior()), tmp_path / "out"
    res = run_cli_here("acquire", "fit", capture, "--out", out, "--size", "2x2", "--steps", "10", "--quiet",
                       *(["--anisotropic"] if anisotropic else []))
    assert res.returncode == 0, res.stderr
    report = json.load(open(os.path.join(out, acquisition.REPORT_FILE)))
    assert report["isotropic"] is (not anisotropic)
    photographed = acquisition._observations(capture, (2, 2), lambda msg: None)[1]
    (obs,) = seen
    np.testing.assert_allclose(obs.wi[:, 2], photographed.wi[:, 2], atol=1e-6)
    assert np.array_equal(obs.wi, photographed.wi) is anisotropic

