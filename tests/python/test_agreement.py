"""C++ (float32), PyTorch float64 and PyTorch float32 compute the same f_a,
and the float64 PyTorch f_a equals the literal textbook transcription."""

import numpy as np
import torch

import hybridbrdf as hb
from hybridbrdf.evaluate.directions import cosine_directions
from textbook_reference import textbook_fa
from hybridbrdf.brdf.torch_brdf import eval_analytic as torch_fa

from helpers import PARAM_CORNERS, hard_directions, hard_pairs, random_params, valid_upper

N_PAIRS = 100_000
N_MATERIALS = 20


def _torch(wi, wo, p, dtype):
    t = lambda a: torch.tensor(np.asarray(a), dtype=dtype)  # noqa: E731
    return torch_fa(t(wi), t(wo), t(p.kd), t(p.eta), t(p.alpha)).numpy().astype(np.float64)


def _rel(a, b):
    return np.abs(a - b) / np.maximum(np.abs(b), 1e-30)


def test_float64_torch_equals_textbook_transcription(rng):
    for _ in range(N_MATERIALS):
        p = random_params(rng)
        wi, wo = cosine_directions(rng, 5000), cosine_directions(rng, 5000)
        keep = (wi[:, 2] > 1e-3) & (wo[:, 2] > 1e-3)  # the textbook G1 loses digits at grazing angles
        ref = textbook_fa(wi[keep], wo[keep], p.kd, p.eta, p.alpha)
        got = _torch(wi[keep], wo[keep], p, torch.float64)
        assert _rel(got, ref).max() < 1e-9


def test_cpp_and_torch_float32_agree_with_torch_float64_on_1e5_pairs(rng):
    """Tolerances: 2e-5 relative for alpha >= 0.05. Below that D is ill-conditioned
    in float32: an absolute error ~6e-8 in h_x becomes ~2 * 6e-8 * |h_x| / alpha^2
    relative in D, up to ~2e-4 at alpha = 1e-3."""
    per_material = N_PAIRS // N_MATERIALS
    worst = {"cpp": [0.0, 0.0], "torch32": [0.0, 0.0]}
    for m in range(N_MATERIALS):
        p = random_params(rng)
        wi = cosine_directions(rng, per_material).astype(np.float32).astype(np.float64)
        wo = cosine_directions(rng, per_material).astype(np.float32).astype(np.float64)
        # Parameters rounded to float32 as the C++ library stores them.
        p32 = hb.AnalyticParams(*(np.float32(v).astype(np.float64) for v in (p.kd, p.eta, p.alpha)))
        ref = _torch(wi, wo, p32, torch.float64)
        rough = min(p32.alpha) >= 0.05
        for name, got in (("cpp", hb.analytic_eval(wi, wo, p)), ("torch32", _torch(wi, wo, p32, torch.float32))):
            err = _rel(got.astype(np.float64), ref).max()
            worst[name][0] = max(worst[name][0], err)
            if rough:
                worst[name][1] = max(worst[name][1], err)
    for name, (all_err, rough_err) in worst.items():
        assert all_err < 2e-4, (name, all_err)
        assert rough_err < 2e-5, (name, rough_err)


def test_all_implementations_agree_on_hard_cases():
    wi, wo = hard_pairs()
    valid = valid_upper(wi) & valid_upper(wo)
    valid64 = valid_upper(wi, np.float64) & valid_upper(wo, np.float64)
    for p in PARAM_CORNERS:
        cpp = hb.analytic_eval(wi, wo, p).astype(np.float64)
        t64 = _torch(wi, wo, p, torch.float64)
        t32 = _torch(wi, wo, p, torch.float32)
        for name, f, ok in (("cpp", cpp, valid), ("torch64", t64, valid64), ("torch32", t32, valid)):
            assert np.isfinite(f).all(), name
            assert (f >= 0).all(), name
            assert (f[~ok] == 0).all(), name
        # Where the float32 inputs are valid and not degenerate, the values agree.
        both = valid & (np.abs(wi[:, 2]) > 1e-6) & (np.abs(wo[:, 2]) > 1e-6)
        both &= np.all(np.abs(wi) < 1e10, axis=1) & np.all(np.abs(wo) < 1e10, axis=1)
        if min(p.alpha) >= 0.01:
            assert _rel(cpp[both], t64[both]).max() < 2e-4
            assert _rel(t32[both], t64[both]).max() < 2e-4


def test_torch_gradients_are_finite_on_hard_cases():
    wi, wo = hard_pairs()
    for p in PARAM_CORNERS[::5]:
        kd = torch.tensor(p.kd, requires_grad=True)
        eta = torch.tensor(np.maximum(p.eta, 1.0 + 1e-6), requires_grad=True)  # eta = 1 exactly: sqrt'(0)
        alpha = torch.tensor(p.alpha, requires_grad=True)
        wi_t = torch.tensor(wi, requires_grad=True)
        f = torch_fa(wi_t, torch.tensor(wo), kd, eta, alpha)
        (f * torch.rand_like(f)).sum().backward()
        for t in (kd, eta, alpha):
            assert torch.isfinite(t.grad).all()


def test_reciprocity_cpp_and_torch(rng):
    for _ in range(10):
        p = random_params(rng)
        wi, wo = cosine_directions(rng, 10000), cosine_directions(rng, 10000)
        a, b = hb.analytic_eval(wi, wo, p), hb.analytic_eval(wo, wi, p)
        assert _rel(a.astype(np.float64), b.astype(np.float64)).max() < 1e-6
        ta, tb = _torch(wi, wo, p, torch.float32), _torch(wo, wi, p, torch.float32)
        assert _rel(ta, tb).max() < 1e-6


def test_torch_sampler_matches_cpp(rng):
    """Same (wo, u): the PyTorch sampler and pdf reproduce the C++ ones."""
    from hybridbrdf.brdf.torch_brdf import pdf as torch_pdf
    from hybridbrdf.brdf.torch_brdf import sample as torch_sample

    n = 20000
    for _ in range(5):
        p = random_params(rng, alpha_min=0.05)
        wo = cosine_directions(rng, n).astype(np.float32)
        u = rng.random((n, 2)).astype(np.float32)
        t = lambda a: torch.tensor(np.asarray(a), dtype=torch.float64)  # noqa: E731
        for strategy in hb.STRATEGIES:
            wi_c, pdf_c, w_c = hb.sample(wo, u, p, strategy)
            wi_t, pdf_t, w_t = (x.numpy() for x in torch_sample(t(wo), t(u), t(p.kd), t(p.eta), t(p.alpha), strategy))
            # Lobe choice can flip where u.x is within rounding of P_ggx, and
            # float32 reflection loses absolute precision in wi.z at the horizon.
            same = np.abs(wi_c - wi_t).max(axis=1) < 1e-4
            assert same.mean() > 0.995, strategy
            good = same & (wi_t[:, 2] > 0.05)
            assert np.allclose(pdf_c[good], pdf_t[good], rtol=5e-4)
            assert np.allclose(w_c[good], w_t[good], rtol=5e-4, atol=1e-7)
            q = torch_pdf(t(wi_c), t(wo), t(p.kd), t(p.eta), t(p.alpha), strategy).numpy()
            assert np.allclose(q[good], pdf_c[good], rtol=5e-4)


def test_torch_sampler_hard_cases():
    """The PyTorch sampler keeps the hard-case contract of the C++ one."""
    from hybridbrdf.brdf.torch_brdf import sample as torch_sample

    d = hard_directions()
    us = np.array([[0, 0], [0.5, 0.5], [1, 1], [np.nan, 0.5], [-1, 2], [0.999999, 0.1]])
    wo = torch.tensor(np.repeat(d, len(us), axis=0))
    u = torch.tensor(np.tile(us, (len(d), 1)))
    invalid = ~torch.tensor(valid_upper(np.repeat(d, len(us), axis=0), np.float64))
    for p in PARAM_CORNERS:
        for dtype in (torch.float32, torch.float64):
            for strategy in hb.STRATEGIES:
                wi, q, w = torch_sample(wo.to(dtype), u.to(dtype), torch.tensor(p.kd), torch.tensor(p.eta),
                                        torch.tensor(p.alpha), strategy)
                assert torch.isfinite(wi).all() and torch.isfinite(q).all() and torch.isfinite(w).all()
                assert (q >= 0).all() and (w >= 0).all()
                if dtype == torch.float64:
                    assert (q[invalid] == 0).all()
                assert (w[q == 0] == 0).all()
