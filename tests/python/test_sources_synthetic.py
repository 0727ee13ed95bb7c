"""Synthetic materials (hybridbrdf.sources.synthetic): the BRDFSource contract,
energy, reciprocity, isotropy, the effect each material exists for, and
independent oracles (Mitsuba 3 roughconductor, textbook transcriptions, a
transfer-matrix thin-film solver, Mitsuba's tabulated CIE functions).

Expected numbers come from closed forms or other implementations, never from
the module's own output."""

import time

import numpy as np
import pytest

import hybridbrdf as hb
from hybridbrdf.sources.base import BRDFFormatError, BRDFSource
from hybridbrdf.sources import expand_sources, open_source
from hybridbrdf.brdf import microfacet
from hybridbrdf.sources import spectral
from hybridbrdf.sources import synthetic as syn
from hybridbrdf.sources.synthetic import SYNTHETIC_MATERIALS, open_synthetic

from hybridbrdf.evaluate.directions import cosine_directions
from textbook_reference import fresnel_textbook, pdf_vndf, sample_vndf, textbook_fa

from helpers import hard_pairs, mitsuba_f, valid_upper

import mitsuba as mi  # noqa: E402  (required: part of the test extras)

mi.set_variant("scalar_rgb")

NAMES = list(SYNTHETIC_MATERIALS)
FLIP_XY = np.array([-1.0, -1.0, 1.0])


def direction(theta_deg, phi_deg=0.0):
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])


def rows(*ws):
    return np.array(ws, dtype=np.float64)


def chroma(rgb):
    rgb = np.asarray(rgb, dtype=np.float64)
    return rgb / rgb.sum(axis=-1, keepdims=True)


# ---- registry and the BRDFSource contract ------------------------------------


def test_registry_covers_the_required_effects():
    assert isinstance(SYNTHETIC_MATERIALS, dict) and len(NAMES) == len(set(NAMES)) >= 7
    kinds = {type(open_synthetic(n)) for n in NAMES}
    for cls in (syn.RoughConductor, syn.ClearCoat, syn.Retroreflector, syn.CharlieSheen, syn.ThinFilmGGX,
                syn.LambertGGXDielectric):
        assert cls in kinds, cls.__name__
    assert any(isinstance(open_synthetic(n), syn.RoughConductor) and not open_synthetic(n).isotropic for n in NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_attributes(name):
    m = open_synthetic(name)
    assert isinstance(m, BRDFSource)
    assert m.name == name and m.origin == "synthetic (exact)" and m.path is None
    assert isinstance(m.isotropic, bool)
    assert m.reference and type(m).__doc__ and "20" in type(m).__doc__  # cites a paper (a year)
    import json

    json.dumps(m.parameters())  # plain values, for reports
    assert open_synthetic(name) is not m  # a fresh instance each time


def test_unknown_name_and_open_source():
    with pytest.raises(BRDFFormatError) as err:
        open_synthetic("unobtainium")
    assert err.value.path == "synthetic:unobtainium"
    assert str(err.value).startswith("synthetic:unobtainium: unknown synthetic material")
    assert all(n in err.value.problem for n in NAMES)
    with pytest.raises(BRDFFormatError, match="synthetic:nope"):
        open_source("synthetic:nope")
    src = open_source("synthetic:gold")
    assert src.name == "gold" and src.origin == "synthetic (exact)"
    assert expand_sources(["synthetic:all"]) == ["synthetic:" + n for n in NAMES]


def test_parameters_are_checked():
    with pytest.raises(ValueError, match="alpha_x"):
        syn.RoughConductor("x", eta=1.0, k=1.0, alpha_x=0.0, alpha_y=0.1)
    with pytest.raises(ValueError, match="sigma"):
        syn.OrenNayarFujii("x", rho=0.5, sigma=1.5)
    with pytest.raises(ValueError, match="eta_film"):
        syn.ThinFilmGGX("x", eta_film=0.9, thickness_nm=100.0, eta_base=1.5, alpha=0.1)
    with pytest.raises(ValueError, match="eta_film \\* thickness_nm"):  # too thick for the 5 nm grid
        syn.ThinFilmGGX("x", eta_film=2.0, thickness_nm=1000.0, eta_base=1.5, alpha=0.1)
    with pytest.raises(ValueError, match="kd"):
        syn.LambertGGXDielectric("x", kd=[0.1, 0.2], eta=1.5, alpha_x=0.1, alpha_y=0.1)


@pytest.mark.parametrize("name", NAMES)
def test_hard_cases_finite_nonnegative_and_zero_below_horizon(name):
    m = open_synthetic(name)
    wi, wo = hard_pairs()
    f = m.eval(wi, wo)
    assert f.shape == (len(wi), 3) and f.dtype == np.float64
    assert np.all(np.isfinite(f)) and np.all(f >= 0.0)
    ok = valid_upper(wi, np.float64) & valid_upper(wo, np.float64)
    assert np.all(f[~ok] == 0.0)
    # Grazing (z = 1e-8) against random directions, both ways, and wi = wo everywhere.
    rng = np.random.default_rng(11)
    phi = rng.random(500) * 2.0 * np.pi
    g = np.stack([np.cos(phi), np.sin(phi), np.full(500, 1e-8)], axis=1)
    d = cosine_directions(rng, 500)
    for a, b in ((g, d), (d, g), (g, g), (g, g[::-1]), (g, g * FLIP_XY), (d, d), (g, -g * FLIP_XY)):
        f = m.eval(a, b)
        assert np.all(np.isfinite(f)) and np.all(f >= 0.0), name
    assert np.all(m.eval(-g * FLIP_XY, g) == 0.0)  # z = -1e-8: below the horizon


@pytest.mark.parametrize("name", NAMES)
def test_reciprocity(name):
    m = open_synthetic(name)
    rng = np.random.default_rng(5)
    wi = np.concatenate([cosine_directions(rng, 4000), rng.normal(size=(2000, 3)) * [1, 1, 0.01]])
    wo = np.concatenate([cosine_directions(rng, 4000), rng.normal(size=(2000, 3)) * [1, 1, 0.01]])
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]) + 1e-9, np.abs(wo[:, 2]) + 1e-9
    a, b = m.eval(wi, wo), m.eval(wo, wi)
    rel = np.abs(a - b) / np.maximum(np.maximum(a, b), 1e-300)
    assert rel.max() < 1e-9, f"max relative asymmetry {rel.max():.3g}"


# ---- isotropy ----------------------------------------------------------------


def rotate_z(w, angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * w[:, 0] - s * w[:, 1], s * w[:, 0] + c * w[:, 1], w[:, 2]], axis=1)


@pytest.mark.parametrize("name", NAMES)
def test_isotropic_flag_is_truthful(name):
    m = open_synthetic(name)
    rng = np.random.default_rng(9)
    wi, wo = cosine_directions(rng, 3000), cosine_directions(rng, 3000)
    f = m.eval(wi, wo)
    for angle in (0.3, 1.0, np.pi / 2, 2.5):
        g = m.eval(rotate_z(wi, angle), rotate_z(wo, angle))
        rel = np.abs(g - f) / np.maximum(f, 1e-300)
        if m.isotropic:
            assert rel.max() < 1e-8, f"{name} changes under rotation ({rel.max():.3g}) but claims isotropy"
        else:
            assert rel.max() > 0.1, f"{name} claims anisotropy but rotation leaves it unchanged"


# ---- energy: directional albedo by multiple importance sampling ---------------
#
# albedo(wo) = int f(wi, wo) wi.z dwi, estimated by multi-sample MIS (Veach &
# Guibas 1995) with the balance heuristic: n/K samples from each of K
# strategies (cosine, GGX visible normals at the material's roughnesses, and
# their back-vector mirror for retro-reflection), each weighted by
# f cos / p_mix with p_mix the average of the K densities. The estimator is
# unbiased whatever the strategies (p_mix > 0 on the whole upper hemisphere
# through the cosine part); the strategies only cut its variance. Its
# standard error (stratified: per-strategy sample variances) is measured and
# used in each assertion; the seed is fixed, so the test is deterministic.


def strategies_for(m):
    """Sampling strategies that cover m's lobes: ("cos",), ("ggx", ax, ay), ("retro", ax, ay)."""
    out = [("cos",)]
    if isinstance(m, (syn.RoughConductor, syn.LambertGGXDielectric)):
        out.append(("ggx", m.alpha_x, m.alpha_y))
    elif isinstance(m, syn.ClearCoat):
        out.append(("ggx", m.alpha_coat, m.alpha_coat))
        out += [s for s in strategies_for(m.base) if s[0] != "cos"]
    elif isinstance(m, syn.Retroreflector):
        out.append(("retro", m.lobe.alpha_x, m.lobe.alpha_y))
    elif isinstance(m, syn.ThinFilmGGX):
        out.append(("ggx", m.alpha, m.alpha))
    return out


def reflect(wo, h):
    return 2.0 * (wo * h).sum(axis=1, keepdims=True) * h - wo


def strategy_sample(strategy, wo, u):
    if strategy[0] == "cos":
        r, phi = np.sqrt(u[:, 0]), 2.0 * np.pi * u[:, 1]
        return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1.0 - u[:, 0])], axis=1)
    wi = reflect(wo, sample_vndf(wo, u, strategy[1], strategy[2]))
    return wi * FLIP_XY if strategy[0] == "retro" else wi


def strategy_pdf(strategy, wi, wo):
    if strategy[0] == "cos":
        return np.maximum(wi[:, 2], 0.0) / np.pi
    w = wi * FLIP_XY if strategy[0] == "retro" else wi
    with np.errstate(invalid="ignore", divide="ignore"):
        p = pdf_vndf(w, wo, strategy[1], strategy[2])
    return np.where(np.isfinite(p) & (wi[:, 2] > 0.0), p, 0.0)


def albedo_mis(m, wo_dir, n, rng):
    """(estimate (3,), standard error (3,)) of int f(wi, wo) wi.z dwi."""
    strategies = strategies_for(m)
    k = len(strategies)
    per = n // k
    wo = np.tile(wo_dir, (per, 1))
    estimate, variance = np.zeros(3), np.zeros(3)
    for s in strategies:
        wi = strategy_sample(s, wo, rng.random((per, 2)) * (1.0 - 1e-12))
        p_mix = sum(strategy_pdf(t, wi, wo) for t in strategies) / k
        up = (wi[:, 2] > 0.0) & (p_mix > 0.0)
        y = np.zeros((per, 3))
        y[up] = m.eval(wi[up], wo[up]) * (wi[up, 2] / p_mix[up])[:, None]
        estimate += y.mean(axis=0) / k
        variance += y.var(axis=0, ddof=1) / per / (k * k)
    return estimate, np.sqrt(variance)


def albedo_grid(m, wo_dir, n_mu=1000, n_phi=720):
    """Deterministic midpoint rule in (cos theta_i, phi_i): int = int_0^1 int_0^2pi f mu dphi dmu."""
    mu = (np.arange(n_mu) + 0.5) / n_mu
    phi = (np.arange(n_phi) + 0.5) / n_phi * 2.0 * np.pi
    MU, PHI = (a.ravel() for a in np.meshgrid(mu, phi, indexing="ij"))
    s = np.sqrt(1.0 - MU * MU)
    wi = np.stack([s * np.cos(PHI), s * np.sin(PHI), MU], axis=1)
    f = m.eval(wi, np.tile(wo_dir, (len(wi), 1)))
    return (f * MU[:, None]).sum(axis=0) * (2.0 * np.pi / (n_mu * n_phi))


VIEW_THETAS = (0.0, 30.0, 60.0, 75.0, 85.0, 89.5)


@pytest.mark.parametrize("name", NAMES)
def test_directional_albedo_at_most_one(name):
    m = open_synthetic(name)
    rng = np.random.default_rng(2024)
    phis = (0.0, 45.0, 90.0) if not m.isotropic else (0.0,)
    worst = 0.0
    for th in VIEW_THETAS:
        for ph in phis:
            a, se = albedo_mis(m, direction(th, ph), 1 << 16, rng)
            assert np.all(se < 0.01), f"{name} at {th} deg: standard error {se.max():.3g}: estimator too noisy"
            # Five standard errors: a false alarm has probability < 1e-6 per channel.
            assert np.all(a <= 1.0 + 5.0 * se), f"{name}: albedo {a} (+- {se}) at theta_o = {th}, phi_o = {ph}"
            assert np.all(a > 0.0)
            worst = max(worst, float(a.max()))
    print(f"{name}: max albedo {worst:.4f}")


def test_albedo_estimator_against_closed_forms_and_a_grid():
    """The MIS estimator must find the albedo where it is known, and agree with
    a deterministic quadrature for a glossy lobe: otherwise the bound above means nothing."""
    rng = np.random.default_rng(1)
    lambert = syn.OrenNayarFujii("lambert", rho=(0.2, 0.5, 0.9), sigma=0.0)
    for th in (0.0, 60.0, 89.0):
        a, se = albedo_mis(lambert, direction(th), 1 << 15, rng)
        assert np.all(np.abs(a - [0.2, 0.5, 0.9]) < 5.0 * se + 1e-12)
    # A GGX lobe with F = 1 (k huge): albedo = the Smith-GGX single-scattering albedo,
    # which at normal incidence and alpha -> small tends to 1.
    mirror = syn.RoughConductor("mirror", eta=1.0, k=1e6, alpha_x=0.01, alpha_y=0.01)
    a, se = albedo_mis(mirror, direction(0.0), 1 << 15, rng)
    assert np.all(np.abs(a - 1.0) < 5.0 * se + 1e-3)
    gold = open_synthetic("gold")
    for th in (20.0, 70.0):
        a, se = albedo_mis(gold, direction(th), 1 << 17, rng)
        ref = albedo_grid(gold, direction(th))
        assert np.all(np.abs(a - ref) < 5.0 * se + 2e-3), (a, se, ref)


# ---- the control: exactly the project's analytic model -----------------------


def test_plastic_is_exactly_the_analytic_model():
    m = open_synthetic("plastic")
    p = m.analytic_params
    rng = np.random.default_rng(3)
    wi, wo = cosine_directions(rng, 5000), cosine_directions(rng, 5000)
    got = m.eval(wi, wo)
    exact = textbook_fa(wi, wo, p.kd, p.eta, p.alpha)
    assert np.abs(got - exact).max() / exact.max() < 1e-13
    assert (np.abs(got - exact) / exact).max() < 1e-12
    lib = hb.analytic_eval(wi, wo, p).astype(np.float64)  # float32 C++ library
    assert (np.abs(lib - got) / got).max() < 2e-5  # the documented float32 tolerance for alpha >= 0.05


def test_fresnel_dielectric_matches_the_textbook():
    c = np.linspace(0.0, 1.0, 1001)
    for eta in (1.2, 1.5, 2.5, 10.0):
        got = microfacet.fresnel_dielectric(c, eta)
        ref = fresnel_textbook(c, eta)
        assert np.allclose(got, ref, rtol=1e-12, atol=1e-15)
    assert np.all(microfacet.fresnel_dielectric(c, 1.0) == 0.0)  # eta = 1: no interface, including c = 0
    assert np.allclose(microfacet.fresnel_dielectric(c, [1.5, 2.0, 3.0])[:, 1], fresnel_textbook(c, 2.0), rtol=1e-12)


# ---- conductors: closed forms and Mitsuba 3 ----------------------------------


def normal_incidence_reflectance(eta, k):
    eta, k = np.asarray(eta), np.asarray(k)
    return ((eta - 1) ** 2 + k ** 2) / ((eta + 1) ** 2 + k ** 2)


def conductors():
    out = []
    for n in NAMES:
        m = open_synthetic(n)
        if isinstance(m, syn.RoughConductor):
            out.append(m)
        elif isinstance(m, syn.ClearCoat) and isinstance(m.base, syn.RoughConductor):
            out.append(m.base)
        elif isinstance(m, syn.Retroreflector):
            out.append(m.lobe)
    return out


@pytest.mark.parametrize("m", conductors(), ids=lambda m: m.name)
def test_conductor_normal_incidence_is_the_closed_form(m):
    """f(n, n) = F0 D(n) (G1/2cos)^2 = F0 / (4 pi ax ay), F0 = ((n-1)^2 + k^2) / ((n+1)^2 + k^2)."""
    z = rows([0.0, 0.0, 1.0])
    f0 = m.eval(z, z)[0] * 4.0 * np.pi * m.alpha_x * m.alpha_y
    assert np.allclose(f0, m.tint * normal_incidence_reflectance(m.eta, m.k), rtol=1e-12, atol=0)
    c = np.array([1.0])
    assert np.allclose(microfacet.fresnel_conductor(c, m.eta, m.k)[0], normal_incidence_reflectance(m.eta, m.k), rtol=1e-13)
    assert np.allclose(microfacet.fresnel_conductor(np.array([0.0]), m.eta, m.k), 1.0, rtol=1e-15)


@pytest.mark.parametrize("symbol,eta,k", [("Au", syn.GOLD_ETA, syn.GOLD_K), ("Cu", syn.COPPER_ETA, syn.COPPER_K),
                                            ("Al", syn.ALUMINIUM_ETA, syn.ALUMINIUM_K)])
def test_metal_constants_agree_with_mitsubas_tables(symbol, eta, k):
    """Provenance: Mitsuba 3 (scalar_rgb) reduces its spectral eta, k tables to RGB."""
    params = mi.traverse(mi.load_dict({"type": "conductor", "material": symbol}))
    assert np.allclose(list(params["eta.value"]), eta, rtol=5e-3)
    assert np.allclose(list(params["k.value"]), k, rtol=5e-3)


def test_gold_is_coloured():
    gold = open_synthetic("gold")
    z = rows([0.0, 0.0, 1.0])
    f = gold.eval(z, z)[0]
    assert f[0] > f[1] > 1.5 * f[2]  # F0 of gold: red > green >> blue


def test_conductor_fresnel_matches_mitsuba():
    c = np.linspace(0.0, 1.0, 201)
    for eta, k in ((0.143119, 3.98316), (1.65746, 9.22387), (0.2, 2.0), (2.5, 0.3)):
        ours = microfacet.fresnel_conductor(c, [eta], [k])[:, 0]
        ref = np.array([float(mi.fresnel_conductor(float(x), mi.Complex2f(eta, k))) for x in c])
        assert (np.abs(ours - ref) / ref).max() < 2e-6  # Mitsuba: float32, a different (Moeller) form


def mitsuba_roughconductor(m, swap_alpha=False):
    ax, ay = (m.alpha_y, m.alpha_x) if swap_alpha else (m.alpha_x, m.alpha_y)
    return mi.load_dict({
        "type": "roughconductor", "distribution": "ggx", "alpha_u": ax, "alpha_v": ay,
        "eta": {"type": "rgb", "value": m.eta.tolist()}, "k": {"type": "rgb", "value": m.k.tolist()},
        "specular_reflectance": {"type": "rgb", "value": m.tint.tolist()},
    })


def oracle_pairs(seed, n=4000):
    rng = np.random.default_rng(seed)
    # float32-representable directions, so both sides evaluate the same pairs.
    wi = cosine_directions(rng, n).astype(np.float32).astype(np.float64)
    wo = cosine_directions(rng, n).astype(np.float32).astype(np.float64)
    # Mitsuba divides by float32 cosines; below 1e-3 its own rounding is no longer << 1e-4.
    keep = (wi[:, 2] > 1e-3) & (wo[:, 2] > 1e-3)
    return wi[keep], wo[keep]


def assert_matches_mitsuba(got, ref):
    significant = ref > 1e-12
    assert significant.mean() > 0.99
    rel = np.abs(got[significant] - ref[significant]) / ref[significant]
    # Budget 1e-4: Mitsuba's float32 D is ill-conditioned for small alpha (~2 * 6e-8 |h_x| / alpha^2,
    # 3e-5 at alpha = 0.06, docs/CONVENTIONS.md); its Fresnel and Smith terms add ~1e-6.
    assert rel.max() < 1e-4, f"max relative difference {rel.max():.3g}"
    assert np.all(got[~significant] < 1e-10)
    return rel.max()


@pytest.mark.parametrize("name", ["gold", "brushed_aluminium"])
def test_conductor_matches_mitsuba_roughconductor(name):
    m = open_synthetic(name)
    wi, wo = oracle_pairs(len(name))
    worst = assert_matches_mitsuba(m.eval(wi, wo), mitsuba_f(mitsuba_roughconductor(m), wi, wo))
    print(f"{name}: {len(wi)} pairs, max relative difference to Mitsuba {worst:.3g}")


def test_clearcoat_base_and_retro_lobe_match_mitsuba():
    coat = open_synthetic("clearcoat_copper")
    wi, wo = oracle_pairs(17)
    assert_matches_mitsuba(coat.base.eval(wi, wo), mitsuba_f(mitsuba_roughconductor(coat.base), wi, wo))
    # MRM: the retro lobe is the ordinary lobe seen from the mirrored viewer wo_b.
    retro = open_synthetic("retroreflector")
    ref = mitsuba_f(mitsuba_roughconductor(retro.lobe), wi, wo * FLIP_XY)
    assert_matches_mitsuba(retro.eval(wi, wo) - retro.kd / np.pi, ref)


def test_mitsuba_oracle_detects_a_swapped_frame():
    """Negative control: the same comparison catches alpha_x <-> alpha_y."""
    m = open_synthetic("brushed_aluminium")
    wi, wo = oracle_pairs(4, 500)
    ref = mitsuba_f(mitsuba_roughconductor(m, swap_alpha=True), wi, wo)
    assert (np.abs(m.eval(wi, wo) - ref) / ref).max() > 1e-2


# ---- each material's effect ----------------------------------------------------


def test_brushed_metal_highlight_is_stretched_across_the_brushing():
    """alpha_y > alpha_x: moving the light off the mirror direction along y keeps
    more of the highlight than moving it the same angle along x."""
    m = open_synthetic("brushed_aluminium")
    assert m.alpha_y > 2 * m.alpha_x
    wo = rows([0.0, 0.0, 1.0])
    along_x = m.eval(rows(direction(10.0, 0.0)), wo)[0]
    along_y = m.eval(rows(direction(10.0, 90.0)), wo)[0]
    assert np.all(along_y > 5.0 * along_x)


@pytest.mark.parametrize("name", ["retroreflector", "rough_clay"])
def test_retroreflection_beats_the_mirror_direction(name):
    m = open_synthetic(name)
    control = open_synthetic("plastic")
    for th in (45.0, 60.0, 75.0, 85.0):
        w = rows(direction(th, 30.0))
        retro = m.eval(w, w)[0]  # light comes from where the viewer is
        mirror = m.eval(w * FLIP_XY, w)[0]  # the mirror configuration
        assert np.all(retro > 1.5 * mirror), (th, retro, mirror)
        # ... the opposite of an ordinary glossy material.
        assert np.all(control.eval(w * FLIP_XY, w)[0] > control.eval(w, w)[0])


def test_retroreflector_peak_is_at_wi_equals_wo():
    m = open_synthetic("retroreflector")
    wo = rows(direction(50.0, 0.0))
    thetas = np.linspace(-89.0, 89.0, 357)
    wi = np.stack([np.sin(np.radians(thetas)), np.zeros_like(thetas), np.cos(np.radians(thetas))], axis=1)
    f = m.eval(wi, np.repeat(wo, len(wi), axis=0))[:, 1]
    # Near wi = wo (theta_i = +50), not the mirror (-50); like any GGX lobe's peak in f
    # (no cosine) it sits a little toward grazing: the 1 / (4 wi.z wo.z) factor.
    assert 50.0 <= thetas[np.argmax(f)] < 60.0
    assert f.max() > 5.0 * f[np.argmin(np.abs(thetas + 50.0))]


def test_velvet_sheen_grows_toward_grazing():
    m = open_synthetic("velvet")
    z = rows([0.0, 0.0, 1.0])
    # Charlie's D vanishes for h = n: at normal incidence only the Lambert base is left.
    assert np.allclose(m.eval(z, z)[0], m.kd / np.pi, rtol=1e-14)
    # Reflected radiance f cos for light and viewer together, rising to grazing.
    ths = (0.0, 30.0, 50.0, 70.0, 80.0)
    sheen = [(m.eval(rows(direction(t)), rows(direction(t)))[0] - m.kd / np.pi) for t in ths]
    lum = [s.sum() for s in sheen]
    assert all(b > a for a, b in zip(lum, lum[1:]))
    # The whole material, Lambert base included, is much brighter at grazing than at normal incidence.
    assert np.all(m.eval(rows(direction(80.0)), rows(direction(80.0)))[0] > 2.0 * m.eval(z, z)[0])


def test_velvet_charlie_terms_follow_the_paper():
    m = syn.CharlieSheen("v", kd=0.0, sheen=1.0, r=0.5)
    # D is normalised: int D(h) cos(theta_h) dh = 1 over the hemisphere.
    th = (np.arange(20000) + 0.5) / 20000 * np.pi / 2
    h = np.stack([np.sin(th), np.zeros_like(th), np.cos(th)], axis=1)
    integral = (m.charlie_D(h) * np.cos(th) * np.sin(th)).sum() * (np.pi / 2 / 20000) * 2 * np.pi
    assert abs(integral - 1.0) < 1e-6
    # Lambda is continuous at cos = 1/2 (the two branches of the fit meet) and decreasing.
    lam = m.charlie_lambda(np.array([0.5 - 1e-12, 0.5, 0.5 + 1e-12]))
    assert np.allclose(lam, lam[1], rtol=1e-9)
    cs = np.linspace(1e-6, 1.0, 1000)
    assert np.all(np.diff(m.charlie_lambda(cs)) < 0)
    # The fit's coefficients (Estevez & Kulla 2017, Table 1) at r = 1, and at r = 0.5 where
    # the paper interpolates with weight t = (1 - r)^2 = 1/4 on the r = 0 row.
    p0 = np.array([25.3245, 3.32435, 0.16801, -1.27393, -4.85967])
    p1 = np.array([21.5473, 3.82987, 0.19823, -1.97760, -4.32054])

    def L(x, p):
        return p[0] / (1 + p[1] * x ** p[2]) + p[3] * x + p[4]

    for r, p in ((1.0, p1), (0.5, 0.75 * p1 + 0.25 * p0), (0.2, 0.36 * p1 + 0.64 * p0)):
        mr = syn.CharlieSheen("v", kd=0.0, sheen=1.0, r=r)
        assert np.isclose(mr.charlie_lambda(np.array([0.3]))[0], np.exp(L(0.3, p)), rtol=1e-13)
        assert np.isclose(mr.charlie_lambda(np.array([0.8]))[0], np.exp(2 * L(0.5, p) - L(0.2, p)), rtol=1e-13)


@pytest.mark.parametrize("theta_o", [0.0, 30.0, 60.0, 80.0])
def test_rough_clay_albedo_matches_the_oren_nayar_reduction(theta_o):
    """Fujii's form integrates over phi in closed form: with s = sin_i sin_o cos(phi),
    int cos(phi) = 2 where s > 0 (t = max(cos_i, cos_o)) and -2 where s < 0 (t = 1), so
    albedo = rho A + (2 rho B / pi) int_0^{pi/2} sin_o sin_i (1 / max(cos_i, cos_o) - 1) cos_i sin_i dtheta_i,
    A = 1 / (1 + (pi/2 - 2/3) sigma), B = sigma A (Fujii 2012). At theta_o = 0 it is rho A."""
    from scipy.integrate import quad

    m = open_synthetic("rough_clay")
    A = 1.0 / (1.0 + (np.pi / 2 - 2.0 / 3.0) * m.sigma)
    B = m.sigma * A
    to = np.radians(theta_o)

    def integrand(ti):
        return np.sin(to) * np.sin(ti) * (1.0 / max(np.cos(ti), np.cos(to)) - 1.0) * np.cos(ti) * np.sin(ti)

    reduction, _ = quad(integrand, 0.0, np.pi / 2, points=[to] if 0 < to < np.pi / 2 else None, epsabs=1e-12)
    expected = m.rho * (A + 2.0 * B / np.pi * reduction)
    got = albedo_grid(m, direction(theta_o, 20.0), n_mu=2000, n_phi=720)
    assert np.allclose(got, expected, rtol=2e-4), (got, expected)


def test_clearcoat_has_two_lobes_of_different_width_and_colour():
    m = open_synthetic("clearcoat_copper")
    wo = rows(direction(30.0, 0.0))
    off = lambda deg: m.eval(rows(direction(30.0 - deg, 180.0) if deg <= 30 else direction(deg - 30.0, 0.0)), wo)[0]
    peak, near, far = off(0.0), off(10.0), off(30.0)
    # The sharp coat (alpha 0.04) collapses within 10 degrees of the mirror direction ...
    assert peak.sum() > 4.0 * near.sum()
    # ... while the rough base (alpha 0.35) is still there 30 degrees away.
    assert far.sum() > 0.25 * near.sum()
    # The coat is a colourless dielectric, the base is copper: the peak is much less red than the flank.
    assert chroma(far)[0] > chroma(peak)[0] + 0.1
    # Without the coat's Fresnel weighting the base would be brighter: the layering takes energy off it.
    assert np.all(m.base.eval(rows(direction(60.0, 180.0)), wo) > m.eval(rows(direction(60.0, 180.0)), wo))


def mirror_hue_spread(m, thetas=np.linspace(0.0, 80.0, 17)):
    """Largest change of chromaticity of the highlight (mirror configuration) with angle."""
    wo = np.stack([direction(t) for t in thetas])
    f = m.eval(wo * FLIP_XY, wo)
    ch = chroma(f)
    return (ch.max(axis=0) - ch.min(axis=0)).max()


def test_thin_film_hue_changes_with_angle():
    film = open_synthetic("thin_film")
    no_film = syn.ThinFilmGGX("bare", eta_film=film.eta_film, thickness_nm=0.0, eta_base=film.eta_base,
                              alpha=film.alpha)
    spread_film = mirror_hue_spread(film)
    assert spread_film > 0.2
    assert mirror_hue_spread(no_film) < 1e-9  # a real IOR: the highlight's hue never changes
    assert spread_film > 5.0 * mirror_hue_spread(open_synthetic("gold"))


# ---- thin film physics and colour ----------------------------------------------


def transfer_matrix_reflectance(c1, n2, d, n3, lam):
    """Characteristic-matrix (Abeles) reflectance of one film, per polarisation,
    averaged: an independent derivation of the Airy sum (Born & Wolf 1.6.2)."""
    s1 = np.sqrt(1.0 - c1 * c1)
    c2 = np.sqrt(1.0 - (s1 / n2) ** 2 + 0j)
    c3 = np.sqrt(1.0 - (s1 / n3) ** 2 + 0j)
    beta = 2.0 * np.pi * n2 * d * c2 / lam
    R = 0.0
    for y1, y2, y3 in ((c1, n2 * c2, n3 * c3), (1.0 / c1, n2 / c2, n3 / c3)):  # s, p admittances
        m11, m12 = np.cos(beta), -1j * np.sin(beta) / y2
        m21, m22 = -1j * y2 * np.sin(beta), np.cos(beta)
        r = (y1 * m11 + y1 * y3 * m12 - m21 - y3 * m22) / (y1 * m11 + y1 * y3 * m12 + m21 + y3 * m22)
        R = R + 0.5 * np.abs(r) ** 2
    return R


def test_thin_film_airy_sum_matches_the_transfer_matrix_method():
    rng = np.random.default_rng(8)
    c = rng.uniform(0.01, 1.0, 300)
    lam = np.linspace(380.0, 780.0, 41)
    for n2, d, n3 in ((1.5, 600.0, 2.5), (1.33, 350.0, 1.0), (2.2, 800.0, 1.5), (1.2, 100.0, 3.0)):
        got = spectral.thin_film_reflectance(c, n2, d, n3, lam)
        ref = transfer_matrix_reflectance(c[:, None], n2, d, n3, lam[None, :])
        assert np.allclose(got, ref, rtol=1e-10, atol=1e-13)


def test_thin_film_reduces_to_the_bare_interface():
    c = np.linspace(0.0, 1.0, 501)
    lam = spectral.WAVELENGTHS_NM
    bare = fresnel_textbook(c, 2.5)[:, None]
    for n2, d in ((1.5, 0.0), (1.0, 700.0), (2.5, 450.0)):  # no film, an air film, a film of base index
        assert np.allclose(spectral.thin_film_reflectance(c, n2, d, 2.5, lam), bare, rtol=1e-12, atol=1e-15)
    # Through the colour pipeline too: a flat spectrum keeps its value in every channel.
    film = syn.ThinFilmGGX("bare", eta_film=1.5, thickness_nm=0.0, eta_base=2.5, alpha=0.1)
    assert np.allclose(film.fresnel(c), bare, rtol=1e-12, atol=1e-15)
    # Free film at exactly grazing incidence: total reflection, no 0/0.
    assert np.allclose(spectral.thin_film_reflectance(np.array([0.0]), 1.33, 300.0, 1.0, lam), 1.0)


def test_colour_matching_functions_match_mitsubas_cie_tables():
    lam = np.arange(380.0, 781.0, 5.0)
    ref = np.array([list(mi.cie1931_xyz(float(x))) for x in lam])
    ours = spectral.cie1931_xyz(lam)
    # Wyman et al. 2013 quote their multi-lobe fit within ~1% of the peak; allow 2.5%.
    assert np.abs(ours - ref).max() < 0.025 * ref.max()
    # The resulting film colour differs from one integrated with the tables by little.
    film = open_synthetic("thin_film")
    c = np.linspace(0.05, 1.0, 40)
    spectrum = spectral.thin_film_reflectance(c, film.eta_film, film.thickness_nm, film.eta_base, lam)
    rgb_tab = np.clip(spectrum @ spectral.spectral_to_rgb_weights(lam, cmf=ref).T, 0.0, 1.0)
    assert np.abs(film.fresnel(c) - rgb_tab).max() < 0.02


# ---- speed ---------------------------------------------------------------------


@pytest.mark.parametrize("name", NAMES)
def test_speed_1e5_pairs(name):
    m = open_synthetic(name)
    rng = np.random.default_rng(0)
    wi, wo = cosine_directions(rng, 100_000), cosine_directions(rng, 100_000)
    best = np.inf
    for _ in range(3):
        t = time.perf_counter()
        m.eval(wi, wo)
        best = min(best, time.perf_counter() - t)
    print(f"{name}: {best * 1e3:.1f} ms for 1e5 pairs")
    assert best < 1.0
