"""The Python API: parameter checking, shape errors, strategies, hard cases
through the bindings."""

import numpy as np
import pytest

import hybridbrdf as hb

from helpers import PARAM_CORNERS, hard_directions, hard_pairs, valid_upper


def test_params_broadcast_and_isotropy():
    p = hb.AnalyticParams(kd=0.25, eta=1.5, alpha=0.2)
    assert p.kd.tolist() == [0.25] * 3 and p.eta.tolist() == [1.5] * 3 and p.alpha.tolist() == [0.2, 0.2]
    assert p.isotropic
    assert not hb.AnalyticParams(alpha=(0.1, 0.2)).isotropic
    with pytest.raises(ValueError):
        p.kd[0] = 0.9  # read-only


@pytest.mark.parametrize(
    "kwargs,message",
    [
        ({"kd": 1.5}, "kd[0] = 1.5 is outside [0, 1]"),
        ({"kd": [0.1, -0.1, 0.2]}, "kd[1]"),
        ({"eta": 0.9}, "eta[0] = 0.9 is outside [1, 10]"),
        ({"eta": [1.5, 1.5, 11]}, "eta[2]"),
        ({"alpha": 0.0}, "alpha[0] = 0.0 is outside [0.0001, 1]"),
        ({"alpha": (0.5, float("nan"))}, "alpha[1] = nan"),
        ({"alpha": (0.1, 0.2, 0.3)}, "alpha must be a scalar or have 2 entries"),
        ({"kd": [0.1, 0.2]}, "kd must be a scalar or have 3 entries"),
    ],
)
def test_params_out_of_range_are_rejected_by_name(kwargs, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        hb.AnalyticParams(**kwargs)


def test_core_validate_names_the_parameter():
    core = hb._core.AnalyticParams([0.5] * 3, [1.5, 20.0, 1.5], [0.3, 0.3])
    with pytest.raises(ValueError, match=r"eta\[1\]"):
        core.validate()


@pytest.mark.parametrize(
    "call",
    [
        lambda p: hb.analytic_eval(np.zeros((4, 2)), np.zeros((4, 3)), p),
        lambda p: hb.analytic_eval(np.zeros((4, 3)), np.zeros((5, 3)), p),
        lambda p: hb.analytic_eval(np.zeros(3), np.zeros(3), p),
        lambda p: hb.sample(np.zeros((4, 3)), np.zeros((4, 3)), p),
        lambda p: hb.sample(np.zeros((4, 3)), np.zeros((3, 2)), p),
        lambda p: hb.pdf(np.zeros((4, 3)), np.zeros((4, 4)), p),
    ],
)
def test_wrong_shapes_raise_value_error(call):
    with pytest.raises(ValueError, match="shape|rows"):
        call(hb.AnalyticParams())


def test_unknown_strategy_and_wrong_params_type():
    with pytest.raises(ValueError, match="unknown sampling strategy 'vndf'"):
        hb.sample(np.zeros((1, 3)), np.zeros((1, 2)), hb.AnalyticParams(), "vndf")
    with pytest.raises(TypeError, match="AnalyticParams"):
        hb.analytic_eval(np.zeros((1, 3)), np.zeros((1, 3)), {"kd": 0.5})


def test_empty_batches():
    p = hb.AnalyticParams()
    assert hb.analytic_eval(np.zeros((0, 3)), np.zeros((0, 3)), p).shape == (0, 3)
    wi, q, w = hb.sample(np.zeros((0, 3)), np.zeros((0, 2)), p)
    assert wi.shape == (0, 3) and q.shape == (0,) and w.shape == (0, 3)


def test_non_contiguous_and_float64_inputs_are_accepted():
    rng = np.random.default_rng(0)
    big = rng.normal(size=(100, 6))
    wi, wo = big[:, :3], big[:, 3:]  # strided views
    wo = np.abs(wo)
    p = hb.AnalyticParams(alpha=(0.2, 0.4))
    f = hb.analytic_eval(wi, wo, p)
    g = hb.analytic_eval(np.ascontiguousarray(wi, dtype=np.float32), np.ascontiguousarray(wo, dtype=np.float32), p)
    assert np.array_equal(f, g)


def test_hard_cases_through_the_bindings():
    wi, wo = hard_pairs()
    valid = valid_upper(wi) & valid_upper(wo)
    for p in PARAM_CORNERS:
        f = hb.analytic_eval(wi, wo, p)
        assert np.isfinite(f).all() and (f >= 0).all()
        assert (f[~valid] == 0).all()
        for s in hb.STRATEGIES:
            q = hb.pdf(wi, wo, p, s)
            assert np.isfinite(q).all() and (q >= 0).all()
    d = hard_directions()
    us = np.array([[0, 0], [0.5, 0.5], [1, 1], [np.nan, 0.5], [-1, 2], [0.999999, 0.1]])
    wo = np.repeat(d, len(us), axis=0)
    u = np.tile(us, (len(d), 1))
    for p in PARAM_CORNERS:
        for s in hb.STRATEGIES:
            wi, q, w = hb.sample(wo, u, p, s)
            assert np.isfinite(wi).all() and np.isfinite(q).all() and np.isfinite(w).all()
            assert (q >= 0).all() and (w >= 0).all()
            assert (q[~valid_upper(wo)] == 0).all()
            assert (w[q == 0] == 0).all()


def test_simd_paths_agree():
    rng = np.random.default_rng(2)
    wi, wo = rng.normal(size=(5000, 3)), np.abs(rng.normal(size=(5000, 3)))
    p = hb.AnalyticParams(kd=0.2, eta=2.0, alpha=(0.3, 0.1))
    fast = hb.analytic_eval(wi, wo, p)
    hb._core.force_baseline_simd(True)
    try:
        base = hb.analytic_eval(wi, wo, p)
        assert hb.simd_path() == "baseline"
    finally:
        hb._core.force_baseline_simd(False)
    assert np.allclose(fast, base, rtol=1e-5, atol=0)
