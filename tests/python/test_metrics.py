"""Metrics against hand-computed values and conservation facts."""

import numpy as np

import hybridbrdf as hb
from hybridbrdf.evaluate.metrics import cmae, directional_albedo, mae, metric_directions, reciprocity_error, smape


def test_smape_by_hand():
    ref = np.array([[1.0, 0.0, 2.0]])
    est = np.array([[3.0, 0.0, 2.0]])
    # terms: |1-3|/(1+3) = 0.5, both zero -> 0, equal -> 0; mean 1/6; times 2
    assert np.isclose(smape(ref, est), 2 * (0.5 / 3))
    # a model value where the reference is 0 costs the maximum term, 1 (SMAPE 2 when everywhere)
    assert np.isclose(smape(np.zeros((4, 3)), np.full((4, 3), 1e-9)), 2.0)
    # negative (noisy) references are clamped to 0 first
    assert smape(np.array([[-0.1, -5.0, 0.0]]), np.zeros((1, 3))) == 0.0


def test_cmae_and_mae_by_hand():
    ref = np.array([[1.0, 1.0, 1.0], [0.0, 0.0, 0.0]])
    est = np.array([[0.5, 1.0, 1.5], [0.3, 0.3, 0.3]])
    cos = np.array([0.5, 1.0])
    assert np.isclose(mae(ref, est), (0.5 + 0 + 0.5 + 0.9) / 6)
    assert np.isclose(cmae(ref, est, cos), (0.5 * 0.5 + 0.5 * 0.5 + 0.9 * 1.0) / 6)


def test_metric_directions_are_seeded_and_cosine_distributed():
    wi, wo = metric_directions(200_000)
    wi2, _ = metric_directions(200_000)
    assert np.array_equal(wi, wi2)
    assert np.allclose(np.linalg.norm(wi, axis=1), 1.0)
    # cosine-weighted: E[cos theta] = 2/3, E[cos^2] = 1/2
    assert abs(wi[:, 2].mean() - 2 / 3) < 3e-3 and abs((wo[:, 2] ** 2).mean() - 0.5) < 3e-3
    assert not np.array_equal(wi, wo)


def test_reciprocity_and_albedo_of_the_analytic_model():
    p = hb.AnalyticParams(kd=[0.2, 0.4, 0.6], eta=1.5, alpha=(0.2, 0.4))
    f = lambda wi, wo: hb.analytic_eval(wi, wo, p)  # noqa: E731
    assert reciprocity_error(f, n=50_000) < 1e-6
    # Lambert only (eta = 1): albedo = kd exactly
    lam = hb.AnalyticParams(kd=[0.2, 0.4, 0.6], eta=1.0, alpha=0.3)
    a = directional_albedo(lambda wi, wo: hb.analytic_eval(wi, wo, lam), 0.7, n=10_000)
    assert np.allclose(a, lam.kd, rtol=1e-5)
