"""The tabulated importance-sampling baseline through Python
(hybridbrdf._core.TabulatedSampler): its pdf integrates to 1, sample() draws
from pdf() (chi-square, with a negative control), hard inputs, and a sampler
built from a fitted model gives an unbiased albedo. Small tables keep it quick;
tests/cpp/test_tabulated.cpp covers 1-degree tables in depth."""

from pathlib import Path

import numpy as np
import pytest
from scipy import stats

import hybridbrdf as hb
from hybridbrdf import _core

from helpers import spherical

MODEL = Path(__file__).resolve().parents[2] / "results" / "rgl54_hybrid_32x2.safetensors"
GLOSSY = _core.AnalyticParams(kd=[0.1, 0.08, 0.06], eta=[1.5, 1.6, 1.7], alpha=[0.1, 0.1])
ANISO = _core.AnalyticParams(kd=[0.1, 0.08, 0.06], eta=[1.5, 1.6, 1.7], alpha=[0.05, 0.3])
DEFENSIVE = 0.1


@pytest.fixture(scope="module")
def iso5():
    return _core.TabulatedSampler.build_analytic(GLOSSY, isotropic=True, resolution_deg=5)


@pytest.fixture(scope="module")
def aniso5():
    return _core.TabulatedSampler.build_analytic(ANISO, isotropic=False, resolution_deg=5)


def cell_grid(sampler, wo, sub=2):
    """Midpoints of `sub` x `sub` sub-cells of every table cell (phi measured
    from wo's azimuth for isotropic tables) and their solid angles: the table
    part of the pdf is constant on each, so the quadrature is exact for it."""
    res = np.radians(sampler.resolution_deg)
    n_t, n_p = int(round(np.pi / 2 / res)) * sub, int(round(2 * np.pi / res)) * sub
    dt, dp = np.pi / 2 / n_t, 2 * np.pi / n_p
    phi0 = np.arctan2(wo[1], wo[0]) if sampler.isotropic and (wo[0] or wo[1]) else 0.0
    t = (np.arange(n_t) + 0.5) * dt
    p = phi0 + (np.arange(n_p) + 0.5) * dp
    T, P = np.meshgrid(t, p, indexing="ij")
    wi = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1).reshape(-1, 3)
    d_omega = ((np.cos(t - dt / 2) - np.cos(t + dt / 2)) * dp)[:, None] * np.ones(n_p)[None, :]
    return wi, d_omega.ravel(), (n_t, n_p), phi0


def pdf_at(sampler, wi, wo):
    return sampler.pdf(wi.astype(np.float32), np.tile(wo, (len(wi), 1)).astype(np.float32)).astype(np.float64)


@pytest.mark.parametrize("which", ["iso5", "aniso5"])
@pytest.mark.parametrize("theta_o", [0.0, 0.6, 1.3, np.pi / 2 - 1e-6])
def test_pdf_integrates_to_one(which, theta_o, request):
    s = request.getfixturevalue(which)
    wo = spherical(theta_o, 2.0)
    wi, d_omega, _, _ = cell_grid(s, wo)
    assert (pdf_at(s, wi, wo) * d_omega).sum() == pytest.approx(1.0, abs=1e-3)


def _histogram(wi, shape, phi0):
    n_t, n_p = shape
    theta = np.arccos(np.clip(wi[:, 2], -1, 1))
    phi = np.mod(np.arctan2(wi[:, 1], wi[:, 0]) - phi0, 2 * np.pi)
    i = np.minimum((theta / (np.pi / 2) * n_t).astype(int), n_t - 1)
    j = np.minimum((phi / (2 * np.pi) * n_p).astype(int), n_p - 1)
    return np.bincount(i * n_p + j, minlength=n_t * n_p)


def _chi2_pvalue(observed, expected_prob, n):
    expected = expected_prob * n
    small = expected < 5
    e = np.append(expected[~small], expected[small].sum())
    o = np.append(observed[~small], observed[small].sum()).astype(np.float64)
    keep = e > 0
    stat = ((o[keep] - e[keep]) ** 2 / e[keep]).sum()
    return stats.chi2.sf(stat, keep.sum() - 1)


@pytest.mark.parametrize("which,theta_o", [("iso5", 0.7), ("iso5", 1.4), ("aniso5", 1.0)])
def test_chi_square_sample_matches_pdf(which, theta_o, request):
    """Half-cell bins: sees the table's distribution and the placement inside cells."""
    s = request.getfixturevalue(which)
    n = 300_000
    wo = spherical(theta_o, 0.8)
    rng = np.random.default_rng(int(theta_o * 100))
    wi, pdf = s.sample(np.tile(wo, (n, 1)).astype(np.float32), rng.random((n, 2)).astype(np.float32))
    assert (pdf > 0).all()
    grid, d_omega, shape, phi0 = cell_grid(s, wo)
    counts = _histogram(wi.astype(np.float64), shape, phi0)
    prob = pdf_at(s, grid, wo) * d_omega
    assert _chi2_pvalue(counts, prob, n) > 1e-3
    # Negative control: the density of a wo 0.25 rad away in azimuth.
    wrong = pdf_at(s, grid, spherical(theta_o, 1.05)) * d_omega
    assert _chi2_pvalue(counts, wrong, n) < 1e-6


def test_sample_reports_pdf_of_its_direction(iso5):
    rng = np.random.default_rng(4)
    n = 20_000
    mu = rng.random(n)
    phi = 2 * np.pi * rng.random(n)
    wo = np.stack([np.sqrt(1 - mu**2) * np.cos(phi), np.sqrt(1 - mu**2) * np.sin(phi), mu], axis=1).astype(np.float32)
    wi, pdf = iso5.sample(wo, rng.random((n, 2)).astype(np.float32))
    ok = pdf > 0
    assert ok.mean() > 0.999  # only mu rounding to 0 in float32 is "no sample"
    np.testing.assert_array_equal(pdf[ok], iso5.pdf(wi[ok], wo[ok]))
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1.0, atol=1e-5)


def test_hard_inputs(iso5):
    nan, inf = np.nan, np.inf
    bad_wo = np.array([[0, 0, -1], [0.6, 0, -0.8], [1, 0, 0], [0, 0, 0], [nan, 0, 1], [0, 0, inf]], np.float32)
    wi, pdf = iso5.sample(bad_wo, np.full((len(bad_wo), 2), 0.5, np.float32))
    np.testing.assert_array_equal(pdf, 0)
    np.testing.assert_array_equal(wi, np.tile([0, 0, 1], (len(bad_wo), 1)))
    good = np.tile(spherical(0.4, 0.1), (len(bad_wo), 1)).astype(np.float32)
    np.testing.assert_array_equal(iso5.pdf(good, bad_wo), 0)
    np.testing.assert_array_equal(iso5.pdf(bad_wo, good), 0)
    # Grazing wo and u at the ends of [0, 1): valid samples.
    one = np.float32(1) - np.finfo(np.float32).eps / 2
    u = np.array([[0, 0], [one, one], [1, 1], [0, one], [nan, nan], [-1, 2]], np.float32)
    wo = np.tile([1, 0, 1e-8], (len(u), 1)).astype(np.float32)
    wi, pdf = iso5.sample(wo, u)
    assert (pdf > 0).all() and np.isfinite(pdf).all() and (wi[:, 2] > 0).all()
    with pytest.raises(ValueError):
        iso5.sample(wo, u[:, :1])
    with pytest.raises(ValueError):
        iso5.pdf(wo, wo[:2])


def test_memory_and_arguments():
    s = _core.TabulatedSampler.build_analytic(GLOSSY, isotropic=True, resolution_deg=1)
    assert s.table_count == 90 and s.phi_o_bins == 1
    # compact (default): float marginals, 16-bit conditionals over half the azimuth (mirror symmetry)
    assert s.mirrored and s.memory_bytes == 90 * 90 * 4 + 90 * 90 * 180 * 2 + 91 * 8 + 90 * 4  # 2.9 MB
    assert s.memory_bytes <= 5_620_000  # the paper's 1-degree table
    f = _core.TabulatedSampler.build_analytic(GLOSSY, isotropic=True, resolution_deg=1, storage="full")
    assert not f.mirrored and f.memory_bytes == 90 * (90 + 90 * 360) * 4 + 91 * 8 + 90 * 4  # 11.7 MB
    with pytest.raises(ValueError, match="storage must be"):
        _core.TabulatedSampler.build_analytic(GLOSSY, storage="tiny")
    a = _core.TabulatedSampler.build_analytic(ANISO, isotropic=False, resolution_deg=10)
    assert a.phi_o_bins == 4 and a.table_count == 9 * 4 and not a.mirrored
    assert a.memory_bytes == 36 * (9 * 4 + 9 * 36 * 2) + 10 * 8 + 9 * 4
    # The validated Python parameter class is accepted too.
    p = _core.TabulatedSampler.build_analytic(hb.AnalyticParams(kd=0.1, eta=1.5, alpha=0.1), resolution_deg=10)
    assert p.isotropic and p.resolution_deg == 10
    for bad in (0, 4, 7, 91):
        with pytest.raises(ValueError, match="must divide 90"):
            _core.TabulatedSampler.build_analytic(GLOSSY, resolution_deg=bad)


@pytest.mark.skipif(not MODEL.exists(), reason="results/ model not present")
def test_model_sampler_is_unbiased_and_keeps_its_model_alive():
    model = _core.Model(str(MODEL))
    with pytest.raises(IndexError):
        _core.TabulatedSampler.build_model(model, len(model.materials))
    s = _core.TabulatedSampler.build_model(model, 0, resolution_deg=5)
    del model  # the sampler evaluates the model in sample(): it must keep it alive
    model = _core.Model(str(MODEL))
    wo = spherical(0.9, 0.3)
    wi_grid, d_omega, _, _ = cell_grid(s, wo)
    assert (pdf_at(s, wi_grid, wo) * d_omega).sum() == pytest.approx(1.0, abs=1e-3)

    # Albedo of f_t: tabulated estimator against a fine quadrature of Model.eval.
    n = 200_000
    rng = np.random.default_rng(8)
    wo_n = np.tile(wo, (n, 1)).astype(np.float32)
    wi, pdf = s.sample(wo_n, rng.random((n, 2)).astype(np.float32))
    f = model.eval(wi, wo_n, 0).astype(np.float64).mean(axis=1)
    w = np.where(pdf > 0, f * np.maximum(wi[:, 2], 0) / np.where(pdf > 0, pdf, 1), 0.0)
    est, se = w.mean(), w.std() / np.sqrt(n)
    mu = (np.arange(600) + 0.5) / 600
    phi = (np.arange(1200) + 0.5) * 2 * np.pi / 1200
    M, P = np.meshgrid(mu, phi, indexing="ij")
    S = np.sqrt(1 - M * M)
    grid = np.stack([S * np.cos(P), S * np.sin(P), M], axis=-1).reshape(-1, 3).astype(np.float32)
    fq = model.eval(grid, np.tile(wo, (len(grid), 1)).astype(np.float32), 0).astype(np.float64).mean(axis=1)
    reference = (fq * M.ravel()).sum() / 600 * (2 * np.pi / 1200)
    assert abs(est - reference) < 4 * se + 2e-3 * reference, (est, se, reference)


def test_compact_tables_sample_a_fitted_model_as_well_as_full_ones():
    """The compact tables fold the azimuth by mirror symmetry, which a fitted network
    only has approximately: for real materials of a fitted model, the variance of
    f cos / pdf with the compact tables stays within 10% of the full tables' (same u
    for both), and the two albedo estimates agree within their standard errors."""
    model = _core.Model(str(MODEL))
    rng = np.random.default_rng(3)
    n = 100_000
    u = rng.random((n, 2)).astype(np.float32)
    for material in (0, 3):  # cc_ibiza_sunset (goniochromatic film), paper_white
        compact = _core.TabulatedSampler.build_model(model, material, isotropic=True, resolution_deg=1)
        full = _core.TabulatedSampler.build_model(model, material, isotropic=True, resolution_deg=1, storage="full")
        for theta_o in (0.3, 1.1):
            wo = np.tile(spherical(theta_o, 0.4), (n, 1)).astype(np.float32)
            stats_ = []
            for s in (compact, full):
                wi, pdf = s.sample(wo, u)
                w = model.eval(wi, wo, material).mean(axis=1) * wi[:, 2] / pdf
                stats_.append((w.mean(), w.std() / np.sqrt(n)))
            (m_c, se_c), (m_f, se_f) = stats_
            assert (se_c / se_f) ** 2 < 1.1, (material, theta_o, (se_c / se_f) ** 2)
            assert abs(m_c - m_f) < 4 * np.hypot(se_c, se_f), (material, theta_o, m_c, m_f)
