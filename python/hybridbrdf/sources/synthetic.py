"""Built-in synthetic BRDFs with exact ground truth (``synthetic:NAME``).

They let demos and tests run without measured data and, on purpose, cover
effects that the project's analytic model f_a (Lambert + one anisotropic GGX
lobe with a *real* dielectric Fresnel, docs/CONVENTIONS.md) cannot express,
so that the neural correction has something to learn:

=====================  ==================================================  ==================================
name                   what                                                what f_a lacks
=====================  ==================================================  ==================================
``plastic``            Lambert + GGX dielectric: exactly f_a (control)     nothing, f_a fits it exactly
``gold``               GGX conductor, complex IOR eta + i k per RGB        complex-IOR (metal) Fresnel
``brushed_aluminium``  anisotropic GGX conductor, alpha_x != alpha_y       complex-IOR Fresnel
``clearcoat_copper``   sharp GGX clear coat over a rough copper lobe       a second lobe, other width/colour
``retroreflector``     back-vector GGX lobe (MRM) + Lambert                a lobe around wi = wo
``rough_clay``         Oren-Nayar rough diffuse (Fujii's form)             diffuse back-scatter
``velvet``             Charlie sheen (Estevez & Kulla 2017) + Lambert      sheen rising toward grazing
``thin_film``          GGX, Airy thin-film Fresnel, spectrally integrated  a hue that changes with angle
=====================  ==================================================  ==================================

Every material evaluates in float64, vectorised over direction pairs, in the
frame of docs/CONVENTIONS.md (normal +z, tangent x = alpha_x axis, ``wi``
toward the light, ``wo`` toward the viewer, f without the cosine). All are
reciprocal, non-negative and finite for every pair of directions strictly
above the horizon (grazing included), and their directional albedo stays at
or below 1 (checked by tests/python/test_sources_synthetic.py).

Shared numerics follow the project's conventions so that a synthetic
material in f_a's family agrees with the C++ library to rounding:

- the GGX visibility term is written ``G1(w) / (2 w.z) = 1 / (w.z + sqrt(w.z^2
  + ax^2 wx^2 + ay^2 wy^2))``, which never divides by a grazing cosine;
- the Fresnel cosine is ``(wo.h + wi.h) / 2`` (equal to wo.h in exact
  arithmetic, symmetric in wi, wo in floating point), so reciprocity holds to
  rounding (1e-15 relative);
- squares are written as products.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Callable, Dict, Sequence

import numpy as np

from hybridbrdf.sources.base import BRDFFormatError, BRDFSource

INV_PI = 1.0 / np.pi

# ---------------------------------------------------------------------------
# Building blocks (float64, vectorised)
# ---------------------------------------------------------------------------


def _rgb(value, name: str) -> np.ndarray:
    """`value` as a read-only float64 RGB triple (a scalar is broadcast)."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full(3, float(arr))
    if arr.shape != (3,):
        raise ValueError(f"{name} must be a scalar or have 3 entries, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr.tolist()}")
    arr = arr.copy()
    arr.setflags(write=False)
    return arr


def _in_range(value: float, lo: float, hi: float, name: str) -> float:
    value = float(value)
    if not (lo <= value <= hi):  # written so that NaN fails
        raise ValueError(f"{name} = {value!r} is outside [{lo:g}, {hi:g}]")
    return value


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def half_vector(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """h = normalize(wi + wo) for (M,3) unit directions above the horizon.

    The sum is scaled by its largest component before normalising, so the
    length never underflows: for wi ~ -wo, both grazing, h is +z, the limit
    from above that docs/CONVENTIONS.md prescribes (wi.z + wo.z > 0 always).
    """
    v = wi + wo
    v = v / np.max(np.abs(v), axis=1, keepdims=True)
    return v / np.sqrt(_dot(v, v))[:, None]


def ggx_D(h: np.ndarray, alpha_x: float, alpha_y: float) -> np.ndarray:
    """Anisotropic GGX (Trowbridge-Reitz) normal distribution D(h), (M,).

    D(h) = 1 / (pi ax ay (hx^2/ax^2 + hy^2/ay^2 + hz^2)^2)
    (Walter et al. 2007, "Microfacet Models for Refraction through Rough
    Surfaces", EGSR; anisotropic form: Heitz 2014, "Understanding the
    Masking-Shadowing Function in Microfacet-Based BRDFs", JCGT 3(2)).
    """
    hx = h[:, 0] / alpha_x
    hy = h[:, 1] / alpha_y
    t = hx * hx + hy * hy + h[:, 2] * h[:, 2]
    return 1.0 / (np.pi * alpha_x * alpha_y * t * t)


def smith_G1_over_2cos(w: np.ndarray, alpha_x: float, alpha_y: float) -> np.ndarray:
    """GGX Smith masking divided by twice the cosine, G1(w) / (2 w.z), (M,).

    G1(w) = 2 / (1 + sqrt(1 + (ax^2 wx^2 + ay^2 wy^2) / wz^2)) (Heitz 2014,
    anisotropic GGX), rewritten as 1 / (wz + sqrt(wz^2 + ax^2 wx^2 +
    ay^2 wy^2)) so that it never divides by a grazing cosine; bounded by
    1 / min(ax, ay) for unit w with wz >= 0.
    """
    ax_wx = alpha_x * w[:, 0]
    ay_wy = alpha_y * w[:, 1]
    wz = w[:, 2]
    return 1.0 / (wz + np.sqrt(wz * wz + ax_wx * ax_wx + ay_wy * ay_wy))


def ggx_microfacet(wi: np.ndarray, wo: np.ndarray, alpha_x: float, alpha_y: float):
    """The Fresnel-free GGX reflection lobe D G / (4 wi.z wo.z) and its Fresnel cosine.

    Returns ``(lobe (M,), cos_theta_d (M,))`` with separable Smith G =
    G1(wi) G1(wo) (Walter et al. 2007; Heitz 2014) and cos_theta_d =
    (wo.h + wi.h) / 2: the angle Fresnel is evaluated at, symmetric in wi
    and wo so that every material built on it is reciprocal to rounding.
    """
    h = half_vector(wi, wo)
    lobe = ggx_D(h, alpha_x, alpha_y) * smith_G1_over_2cos(wi, alpha_x, alpha_y) * smith_G1_over_2cos(
        wo, alpha_x, alpha_y
    )
    cos_theta_d = 0.5 * (_dot(wo, h) + _dot(wi, h))
    return lobe, cos_theta_d


def fresnel_dielectric(cos_theta_i, eta) -> np.ndarray:
    """Exact unpolarised Fresnel reflectance of a dielectric interface, air -> eta.

    ``cos_theta_i``: (M,) cosines (clamped to [0, 1]); ``eta``: a real index
    >= 1, scalar or per channel (C,). Returns (M,) or (M, C).

    Textbook form (Cook & Torrance 1982, "A Reflectance Model for Computer
    Graphics", ACM TOG 1(1)), c = cos, g = sqrt(eta^2 - 1 + c^2):
    F = 0.5 ((g-c)/(g+c))^2 (1 + ((c(g+c)-1)/(c(g-c)+1))^2), evaluated in the
    cancellation-free rearrangement of docs/CONVENTIONS.md: e = eta^2 - 1,
    s = g + c, a = c s - 1, b = c e + s, F = e^2 (a^2 s^2 + b^2) / (2 s^4 b^2).
    The only 0/0 (c = 0 and eta = 1) returns 0.
    """
    c = np.clip(np.asarray(cos_theta_i, dtype=np.float64), 0.0, 1.0)
    eta = np.asarray(eta, dtype=np.float64)
    if eta.ndim == 1:
        c = c[:, None]
    e = eta * eta - 1.0
    s = np.sqrt(e + c * c) + c
    a = c * s - 1.0
    b = c * e + s
    s2 = s * s
    num = e * e * (a * a * s2 + b * b)
    den = 2.0 * s2 * s2 * b * b
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0.0, num / np.where(den > 0.0, den, 1.0), 0.0)


def fresnel_conductor(cos_theta_i, eta, k) -> np.ndarray:
    """Exact unpolarised Fresnel reflectance of a conductor, air -> eta + i k.

    ``cos_theta_i``: (M,) cosines (clamped to [0, 1]); ``eta``, ``k``: per
    channel (C,). Returns (M, C) in [0, 1].

    Complex Fresnel equations (Born & Wolf, "Principles of Optics", 1.5.2,
    with a complex index; pbrt-v4's FrComplex): sin^2 theta_t = sin^2 theta_i /
    eta^2, cos theta_t = sqrt(1 - sin^2 theta_t) (principal branch),
    r_par = (eta cos_i - cos_t) / (eta cos_i + cos_t),
    r_perp = (cos_i - eta cos_t) / (cos_i + eta cos_t),
    F = (|r_par|^2 + |r_perp|^2) / 2. At normal incidence this is
    ((n-1)^2 + k^2) / ((n+1)^2 + k^2); at grazing incidence 1.
    """
    c = np.clip(np.asarray(cos_theta_i, dtype=np.float64), 0.0, 1.0)[:, None]
    eta_c = np.asarray(eta, dtype=np.float64) + 1j * np.asarray(k, dtype=np.float64)
    sin2_i = (1.0 - c) * (1.0 + c)  # 1 - c^2 without cancellation near c = 1
    cos_t = np.sqrt(1.0 - sin2_i / (eta_c * eta_c))
    eta_cos_i = eta_c * c
    eta_cos_t = eta_c * cos_t
    r_par = (eta_cos_i - cos_t) / (eta_cos_i + cos_t)
    r_perp = (c - eta_cos_t) / (c + eta_cos_t)
    return 0.5 * (r_par.real * r_par.real + r_par.imag * r_par.imag + r_perp.real * r_perp.real
                  + r_perp.imag * r_perp.imag)


# ---- spectral tools for the thin film --------------------------------------

#: Wavelengths (nm) at which the thin-film reflectance is integrated: 380-780 nm
#: in 5 nm steps. The interference phase 2 eta_film d cos / lambda (cycles) moves
#: by 2 eta_film d x 5 nm / lambda^2 between samples: at most 0.1 cycle at 380 nm
#: for an optical thickness eta_film d <= MAX_OPTICAL_THICKNESS_NM, so the sum
#: resolves every fringe (0.06 cycle for the built-in film).
WAVELENGTHS_NM = np.linspace(380.0, 780.0, 81)
MAX_OPTICAL_THICKNESS_NM = 1500.0

#: CIE XYZ -> linear sRGB (Rec. 709 primaries, D65 white; IEC 61966-2-1).
XYZ_TO_LINEAR_SRGB = np.array(
    [
        [3.2404542, -1.5371385, -0.4985314],
        [-0.9692660, 1.8760108, 0.0415560],
        [0.0556434, -0.2040259, 1.0572252],
    ]
)


def cie1931_xyz(wavelength_nm) -> np.ndarray:
    """CIE 1931 2-degree colour matching functions, (L,) -> (L, 3).

    The multi-lobe piecewise-Gaussian fit of Wyman, Sloan & Shirley 2013,
    "Simple Analytic Approximations to the CIE XYZ Color Matching Functions",
    JCGT 2(2), Sec. 2.1 (within about 1% of the tabulated functions), so that
    the library carries no table.
    """
    lam = np.asarray(wavelength_nm, dtype=np.float64)

    def g(mu, inv_sigma_lo, inv_sigma_hi):
        t = (lam - mu) * np.where(lam < mu, inv_sigma_lo, inv_sigma_hi)
        return np.exp(-0.5 * t * t)

    x = 0.362 * g(442.0, 0.0624, 0.0374) + 1.056 * g(599.8, 0.0264, 0.0323) - 0.065 * g(501.1, 0.0490, 0.0382)
    y = 0.821 * g(568.8, 0.0213, 0.0247) + 0.286 * g(530.9, 0.0613, 0.0322)
    z = 1.217 * g(437.0, 0.0845, 0.0278) + 0.681 * g(459.0, 0.0385, 0.0725)
    return np.stack([x, y, z], axis=-1)


def spectral_to_rgb_weights(wavelength_nm, cmf=None) -> np.ndarray:
    """Weights W (3, L) with rgb = W @ R(lambda) for a reflectance spectrum R.

    W = diag(1 / (M X 1)) M X^T with X the colour matching functions at the
    sample wavelengths (``cmf``, default :func:`cie1931_xyz`) and M the
    XYZ -> linear sRGB matrix: reflectances are integrated under an
    equal-energy illuminant and white-balanced per channel, so that a flat
    spectrum R(lambda) = r maps to rgb = (r, r, r) exactly (each row of W
    sums to 1). Rows have negative entries: saturated spectra can fall
    outside [0, 1] and are clamped by the caller.
    """
    xyz = cie1931_xyz(wavelength_nm) if cmf is None else np.asarray(cmf, dtype=np.float64)
    w = XYZ_TO_LINEAR_SRGB @ xyz.T  # (3, L)
    return w / w.sum(axis=1, keepdims=True)


def _amplitude(a, b):
    """Fresnel amplitude (a - b) / (a + b) for a, b >= 0; -1 where both vanish
    (an interface between equal indices met at exactly grazing incidence:
    the limit from above)."""
    den = a + b
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0.0, (a - b) / np.where(den > 0.0, den, 1.0), -1.0)


def thin_film_reflectance(cos_theta_i, eta_film: float, thickness_nm: float, eta_base: float,
                          wavelength_nm) -> np.ndarray:
    """Airy reflectance of a dielectric film on a dielectric base, (M,) x (L,) -> (M, L).

    Light comes from air (index 1), crosses a non-absorbing film of index
    ``eta_film`` and thickness ``thickness_nm`` and meets a dielectric base
    ``eta_base`` (both >= 1, non-dispersive). Per polarisation the reflected
    amplitude is the Airy sum of all internal reflections (Born & Wolf 1.6.4;
    Belcour & Barla 2017, "A Practical Extension to Microfacet Theory for the
    Modeling of Varying Iridescence", ACM TOG 36(4), Sec. 3):

        r = (r12 + r23 e^{i delta}) / (1 + r12 r23 e^{i delta}),
        delta = 4 pi eta_film d cos(theta_2) / lambda,

    with real Fresnel amplitudes r12, r23 (s: (n_a c_a - n_b c_b)/(n_a c_a +
    n_b c_b), p: (n_b c_a - n_a c_b)/(n_b c_a + n_a c_b)). All cosines are
    real because eta_film, eta_base >= 1 (no total internal reflection), so
    |r|^2 = (r12^2 + r23^2 + 2 r12 r23 cos delta) / (1 + r12^2 r23^2 + 2 r12
    r23 cos delta), evaluated as 1 - (1 - r12^2)(1 - r23^2) / (1 + r12^2 r23^2
    + 2 r12 r23 cos delta) (the same value). Returns (R_s + R_p) / 2. With
    d = 0, eta_film = 1 or eta_film = eta_base it reduces to the
    single-interface Fresnel formula.
    """
    c1 = np.clip(np.asarray(cos_theta_i, dtype=np.float64), 0.0, 1.0)[:, None]
    inv_lam = 1.0 / np.asarray(wavelength_nm, dtype=np.float64)[None, :]
    n2, n3 = float(eta_film), float(eta_base)
    sin2_1 = (1.0 - c1) * (1.0 + c1)
    c2 = np.sqrt(1.0 - sin2_1 / (n2 * n2))  # real: n2 >= 1
    c3 = np.sqrt(1.0 - sin2_1 / (n3 * n3))  # real: n2 sin(theta_2) = sin(theta_1) <= 1 <= n3
    cos_delta = np.cos(((4.0 * np.pi * n2 * thickness_nm) * c2) * inv_lam)
    # |1 + r12 r23 e^{i delta}|^2 - |r12 + r23 e^{i delta}|^2 = (1 - r12^2)(1 - r23^2), so
    # R = 1 - (1 - r12^2)(1 - r23^2) / |1 + r12 r23 e^{i delta}|^2: one division per
    # sample, and exactly 1 where the film transmits nothing (r12 = -1 at grazing).
    loss = np.zeros(np.broadcast_shapes(c1.shape, inv_lam.shape))
    for r12, r23 in (
        (_amplitude(c1, n2 * c2), _amplitude(n2 * c2, n3 * c3)),  # s
        (_amplitude(n2 * c1, c2), _amplitude(n3 * c2, n2 * c3)),  # p
    ):
        transmit = 0.5 * (1.0 - r12 * r12) * (1.0 - r23 * r23)
        den = (2.0 * r12 * r23) * cos_delta
        den += 1.0 + r12 * r12 * r23 * r23
        # den vanishes only for a free film (eta_base = 1) at exactly grazing
        # incidence, where transmit = 0 too and |r| -> 1.
        np.maximum(den, np.finfo(np.float64).tiny, out=den)
        np.divide(transmit, den, out=den)
        loss += den
    return 1.0 - loss


# ---------------------------------------------------------------------------
# Materials
# ---------------------------------------------------------------------------


class SyntheticBRDF(BRDFSource):
    """A built-in analytic material with exact values (no data file).

    Subclasses set ``name``, ``isotropic`` and ``reference`` (the papers the
    formulas come from) and implement :meth:`_eval`. ``parameters`` returns
    the constants as plain lists, for reports and figure captions.
    """

    origin = "synthetic (exact)"
    path = None
    reference: str = ""

    def parameters(self) -> Dict[str, object]:
        """The material's constants as plain Python values (for JSON)."""
        out = {}
        for key, val in vars(self).items():
            if key in ("name", "isotropic") or key.startswith("_"):
                continue
            if isinstance(val, SyntheticBRDF):
                out[key] = {"type": type(val).__name__, **val.parameters()}
            elif isinstance(val, np.ndarray):
                out[key] = val.tolist()
            elif isinstance(val, (int, float, str, bool)):
                out[key] = val
        return out


class LambertGGXDielectric(SyntheticBRDF):
    """Lambert + anisotropic GGX with exact real-IOR Fresnel: exactly f_a.

    f = kd / pi + F(cos_theta_d, eta) D(h) G1(wi) G1(wo) / (4 wi.z wo.z),
    the project's analytic model (docs/CONVENTIONS.md; GGX: Walter et al.
    2007, Heitz 2014; Fresnel: Cook & Torrance 1982), evaluated in float64.
    A control: the model can represent it exactly, so a fit must recover
    ``analytic_params``.
    """

    reference = "Walter et al. 2007 (GGX); Heitz 2014 (Smith G1); Cook & Torrance 1982 (Fresnel)"

    def __init__(self, name: str, kd, eta, alpha_x: float, alpha_y: float):
        self.name = name
        self.kd = _rgb(kd, "kd")
        self.eta = _rgb(eta, "eta")
        if np.any(self.eta < 1.0):
            raise ValueError(f"eta must be >= 1, got {self.eta.tolist()}")
        self.alpha_x = _in_range(alpha_x, 1e-4, 1.0, "alpha_x")
        self.alpha_y = _in_range(alpha_y, 1e-4, 1.0, "alpha_y")
        self.isotropic = self.alpha_x == self.alpha_y

    @property
    def analytic_params(self):
        """The same material as :class:`hybridbrdf.AnalyticParams` (float32 C++ model)."""
        from hybridbrdf.brdf.analytic import AnalyticParams

        return AnalyticParams(kd=self.kd, eta=self.eta, alpha=(self.alpha_x, self.alpha_y))

    def _eval(self, wi, wo):
        lobe, c = ggx_microfacet(wi, wo, self.alpha_x, self.alpha_y)
        return self.kd * INV_PI + fresnel_dielectric(c, self.eta) * lobe[:, None]


class RoughConductor(SyntheticBRDF):
    """GGX conductor with a complex index of refraction eta + i k per RGB channel.

    f = F_conductor(cos_theta_d, eta, k) D(h) G1(wi) G1(wo) / (4 wi.z wo.z)
    (microfacet model: Walter et al. 2007; anisotropic GGX and separable
    Smith: Heitz 2014; exact conductor Fresnel: Born & Wolf 1.5.2). The same
    BRDF as Mitsuba 3's ``roughconductor`` with ``distribution = ggx``,
    ``alpha_u = alpha_x``, ``alpha_v = alpha_y``, which the tests use as an
    oracle. ``tint`` scales the lobe (Mitsuba's ``specular_reflectance``).
    f_a cannot express it exactly: its real index eta <= 10 caps the normal
    reflectance at ((10-1)/(10+1))^2 = 0.67, below gold's red 0.97 or
    aluminium's 0.92, and a real-IOR curve rises monotonically to 1 where a
    metal's first dips (by a different amount per channel) before grazing.
    """

    reference = "Walter et al. 2007 (GGX); Heitz 2014 (anisotropic Smith); Born & Wolf 1.5.2 (conductor Fresnel)"

    def __init__(self, name: str, eta, k, alpha_x: float, alpha_y: float, tint=1.0):
        self.name = name
        self.eta = _rgb(eta, "eta")
        self.k = _rgb(k, "k")
        if np.any(self.eta <= 0.0) or np.any(self.k < 0.0):
            raise ValueError("a conductor needs eta > 0 and k >= 0")
        self.alpha_x = _in_range(alpha_x, 1e-4, 1.0, "alpha_x")
        self.alpha_y = _in_range(alpha_y, 1e-4, 1.0, "alpha_y")
        self.tint = _rgb(tint, "tint")
        self.isotropic = self.alpha_x == self.alpha_y

    def fresnel(self, cos_theta):
        """F(cos_theta) per RGB, (M, 3)."""
        return self.tint * fresnel_conductor(cos_theta, self.eta, self.k)

    def _eval(self, wi, wo):
        lobe, c = ggx_microfacet(wi, wo, self.alpha_x, self.alpha_y)
        return self.fresnel(c) * lobe[:, None]


class ClearCoat(SyntheticBRDF):
    """A sharp dielectric GGX clear coat over any base material.

    f = F(cos_theta_d, eta_c) D_c(h) G_c / (4 wi.z wo.z)
        + (1 - F(wi.z, eta_c)) (1 - F(wo.z, eta_c)) f_base(wi, wo)

    The coat is a GGX dielectric interface (Walter et al. 2007). The base is
    seen through it, attenuated by the coat's Fresnel transmittance on the
    way in and on the way out, the coupling of Weidlich & Wilkie 2007
    ("Arbitrarily Layered Micro-Facet Surfaces", GRAPHITE) reduced to its
    plausible core: no refraction of the base's directions, no absorption in
    the coat and no inter-reflection between the layers (all of which only
    remove energy or move the base lobe). The product of transmittances is
    symmetric, so f stays reciprocal. The albedo is coat albedo(wo) + (1 -
    F(wo.z)) x (at most the base's albedo); since the coat's visible
    microfacets face the viewer, its albedo stays close to F(wo.z), and the
    total stays <= 1 for a base of albedo <= 1 (checked numerically by the
    tests, not proved).
    f_a cannot express it: two specular lobes of different widths and colours.
    """

    reference = "Walter et al. 2007 (GGX coat); Weidlich & Wilkie 2007 (layering, simplified)"

    def __init__(self, name: str, base: SyntheticBRDF, eta_coat: float, alpha_coat: float):
        self.name = name
        self.base = base
        self.eta_coat = _in_range(eta_coat, 1.0, 10.0, "eta_coat")
        self.alpha_coat = _in_range(alpha_coat, 1e-4, 1.0, "alpha_coat")
        self.isotropic = bool(base.isotropic)

    def _eval(self, wi, wo):
        lobe, c = ggx_microfacet(wi, wo, self.alpha_coat, self.alpha_coat)
        coat = fresnel_dielectric(c, self.eta_coat) * lobe
        transmit = (1.0 - fresnel_dielectric(wi[:, 2], self.eta_coat)) * (
            1.0 - fresnel_dielectric(wo[:, 2], self.eta_coat))
        return coat[:, None] + transmit[:, None] * self.base._eval(wi, wo)


class Retroreflector(SyntheticBRDF):
    """Lambert + a retro-reflective GGX conductor lobe (the back-vector / MRM model).

    f = kd / pi + f_spec(wi, wo_b),  wo_b = (-wo.x, -wo.y, wo.z),

    where f_spec is a GGX conductor lobe (:class:`RoughConductor`): the
    Minimal Retroreflective Microfacet model (Portsmouth, Raab, Belcour & Liu
    2026, "The Minimal Retroreflective Microfacet Model", JCGT 15(1), built
    on the back-vector formulation adopted by OpenPBR) replaces the view
    direction by its mirror image about the normal. The half vector becomes
    the "back vector" h_b = normalize(wi + wo_b), which is +z when wi = wo:
    the lobe peaks at retro-reflection instead of the mirror direction.
    Because GGX is symmetric under (x, y) -> (-x, -y), the lobe is reciprocal
    and, for each wo, has exactly the albedo of the ordinary lobe (the map
    wi -> (-wi.x, -wi.y, wi.z) preserves solid angle and wi.z); with
    kd + tint <= 1 the albedo stays <= 1.
    The default models aluminium-coated glass-bead sheeting under a yellow
    dye: Fresnel of aluminium, tinted.
    """

    reference = "Portsmouth et al. 2026 (MRM, JCGT 15(1)); Walter et al. 2007 (GGX); Born & Wolf (Fresnel)"

    def __init__(self, name: str, kd, lobe: RoughConductor):
        self.name = name
        self.kd = _rgb(kd, "kd")
        self.lobe = lobe
        self.isotropic = bool(lobe.isotropic)

    def _eval(self, wi, wo):
        wo_b = wo * np.array([-1.0, -1.0, 1.0])
        return self.kd * INV_PI + self.lobe._eval(wi, wo_b)


class OrenNayarFujii(SyntheticBRDF):
    """Rough diffuse with back-scatter: Oren-Nayar in Fujii's form.

    f = rho / pi (A + B s / t),  s = wi.wo - wi.z wo.z = sin_i sin_o cos(phi_i - phi_o),
    t = max(wi.z, wo.z) where s > 0 and 1 otherwise,
    A = 1 / (1 + (pi/2 - 2/3) sigma), B = sigma A

    (Oren & Nayar 1994, "Generalization of Lambert's Reflectance Model",
    SIGGRAPH; the "tiny improvement" of Fujii 2012, which removes the
    original's dark ring and needs no trigonometry). sigma in [0, 1]
    (0 is Lambert; above 1, A - B < 0 and f could turn negative). The
    back-scatter term grows toward wi = wo at grazing angles (as
    sin^2 theta / cos theta: large but finite for wi.z > 0).
    f_a cannot express it: Lambert has no angular dependence.
    """

    reference = "Oren & Nayar 1994; Fujii 2012 (improved Oren-Nayar)"

    def __init__(self, name: str, rho, sigma: float):
        self.name = name
        self.rho = _rgb(rho, "rho")
        self.sigma = _in_range(sigma, 0.0, 1.0, "sigma")
        self.isotropic = True

    def _eval(self, wi, wo):
        A = 1.0 / (1.0 + (0.5 * np.pi - 2.0 / 3.0) * self.sigma)
        B = self.sigma * A
        s = _dot(wi, wo) - wi[:, 2] * wo[:, 2]
        t = np.where(s > 0.0, np.maximum(wi[:, 2], wo[:, 2]), 1.0)
        # A + B s / t >= A - B >= 0 for sigma <= 1; the clamp only removes rounding.
        return self.rho * INV_PI * np.maximum(A + B * s / t, 0.0)[:, None]


# Estevez & Kulla 2017: the fitted coefficients (a, b, c, d, e) of
# L(x) = a / (1 + b x^c) + d x + e (L = log Lambda) at r = 0 and at r = 1.
_CHARLIE_L_R0 = np.array([25.3245, 3.32435, 0.16801, -1.27393, -4.85967])
_CHARLIE_L_R1 = np.array([21.5473, 3.82987, 0.19823, -1.97760, -4.32054])


class CharlieSheen(SyntheticBRDF):
    """Velvet: Lambert + the "Charlie" microfacet sheen of Estevez & Kulla 2017.

    f = kd / pi + sheen D(h) G(wi, wo) / (4 wi.z wo.z)

    - D(h) = (2 + 1/r) sin(theta_h)^(1/r) / (2 pi): an "inverted" microfacet
      distribution whose normals lie mostly along the surface (fibres);
    - G = 1 / (1 + Lambda(wi) + Lambda(wo)): height-correlated Smith masking
      with Lambda(cos) = exp(L(cos)) for cos < 1/2 and exp(2 L(1/2) - L(1 -
      cos)) otherwise, L the paper's fitted curve whose coefficients are
      interpolated between r = 0 and r = 1 with weight (1 - r)^2.

    (Estevez & Kulla 2017, "Production Friendly Microfacet Sheen BRDF",
    SIGGRAPH course "Physically Based Shading in Theory and Practice"; the
    same D and Lambda are in glTF's KHR_materials_sheen.) The paper's
    "terminator softening" of Lambda is left out: it applies to shading
    normals and would break reciprocity. Lambda stays finite at grazing
    (L(0) = a + e), so f is finite for every wi.z, wo.z > 0.
    f_a cannot express it: the lobe vanishes at normal incidence (D(n) = 0),
    has no mirror peak and is strongest at grazing angles.
    """

    reference = "Estevez & Kulla 2017 (Charlie sheen D and Lambda fit)"

    def __init__(self, name: str, kd, sheen, r: float):
        self.name = name
        self.kd = _rgb(kd, "kd")
        self.sheen = _rgb(sheen, "sheen")
        self.r = _in_range(r, 0.05, 1.0, "r")  # below ~0.05, sin^(1/r) is a numerical spike
        t = (1.0 - self.r) * (1.0 - self.r)
        self._L_coeff = (1.0 - t) * _CHARLIE_L_R1 + t * _CHARLIE_L_R0
        self.isotropic = True

    def _L(self, x):
        a, b, c, d, e = self._L_coeff
        return a / (1.0 + b * np.power(x, c)) + d * x + e

    def charlie_lambda(self, cos_theta):
        """Lambda(cos_theta), Estevez & Kulla 2017's fit, (M,); the two branches meet at cos = 1/2."""
        x = np.clip(cos_theta, 0.0, 1.0)
        near = np.exp(self._L(np.minimum(x, 0.5)))
        far = np.exp(2.0 * self._L(0.5) - self._L(np.minimum(1.0 - x, 0.5)))
        return np.where(x < 0.5, near, far)

    def charlie_D(self, h):
        """D(h) = (2 + 1/r) sin(theta_h)^(1/r) / (2 pi), (M,)."""
        sin2 = h[:, 0] * h[:, 0] + h[:, 1] * h[:, 1]  # no cancellation near theta_h = 0
        inv_r = 1.0 / self.r
        return (2.0 + inv_r) * np.power(np.minimum(sin2, 1.0), 0.5 * inv_r) / (2.0 * np.pi)

    def _eval(self, wi, wo):
        h = half_vector(wi, wo)
        G = 1.0 / (1.0 + self.charlie_lambda(wi[:, 2]) + self.charlie_lambda(wo[:, 2]))
        lobe = self.charlie_D(h) * G / (4.0 * wi[:, 2] * wo[:, 2])
        return self.kd * INV_PI + self.sheen * lobe[:, None]


_SPECTRAL_BLOCK = 1024


class ThinFilmGGX(SyntheticBRDF):
    """GGX dielectric whose Fresnel term is thin-film interference (iridescence).

    f = kd / pi + F_film(cos_theta_d) D(h) G1(wi) G1(wo) / (4 wi.z wo.z)

    F_film is the Airy reflectance of a film (index ``eta_film``, thickness
    ``thickness_nm``) on a dielectric base (``eta_base``), the model of
    Belcour & Barla 2017 ("A Practical Extension to Microfacet Theory for the
    Modeling of Varying Iridescence", ACM TOG 36(4)) evaluated per microfacet
    at cos_theta_d. Where they integrate the Airy series over the spectrum
    analytically (Fourier-domain Gaussian fits of the XYZ sensitivities),
    this integrates it numerically: 81 wavelengths from 380 to 780 nm
    (:data:`WAVELENGTHS_NM`), CIE 1931 colour matching functions
    (:func:`cie1931_xyz`), equal-energy illuminant, linear sRGB, white
    balanced so that a flat spectrum keeps its value, clamped to [0, 1] as
    Belcour & Barla do. With F <= 1 and GGX single scattering (albedo <= 1
    for F = 1), the albedo is at most max(F) + kd. The hue of the highlight
    changes with angle, which a real per-channel IOR (f_a) cannot produce.
    """

    reference = "Belcour & Barla 2017 (Airy thin-film Fresnel); Walter et al. 2007 (GGX); Wyman et al. 2013 (CMFs)"

    def __init__(self, name: str, eta_film: float, thickness_nm: float, eta_base: float, alpha: float, kd=0.0):
        self.name = name
        self.eta_film = _in_range(eta_film, 1.0, 5.0, "eta_film")
        self.thickness_nm = _in_range(thickness_nm, 0.0, 2000.0, "thickness_nm")
        self.eta_base = _in_range(eta_base, 1.0, 5.0, "eta_base")
        # Thicker films would need a finer wavelength grid (see WAVELENGTHS_NM).
        _in_range(self.eta_film * self.thickness_nm, 0.0, MAX_OPTICAL_THICKNESS_NM, "eta_film * thickness_nm")
        self.alpha = _in_range(alpha, 1e-4, 1.0, "alpha")
        self.kd = _rgb(kd, "kd")
        self.isotropic = True
        self._weights = spectral_to_rgb_weights(WAVELENGTHS_NM)

    def fresnel(self, cos_theta):
        """F_film(cos_theta) in linear sRGB, (M, 3), each channel in [0, 1]."""
        cos_theta = np.asarray(cos_theta, dtype=np.float64)
        out = np.empty((cos_theta.shape[0], 3))
        # Row blocks keep the (rows x wavelengths) spectra in cache: several times faster than one pass.
        for start in range(0, cos_theta.shape[0], _SPECTRAL_BLOCK):
            block = cos_theta[start:start + _SPECTRAL_BLOCK]
            spectrum = thin_film_reflectance(block, self.eta_film, self.thickness_nm, self.eta_base, WAVELENGTHS_NM)
            out[start:start + _SPECTRAL_BLOCK] = spectrum @ self._weights.T
        return np.clip(out, 0.0, 1.0)

    def _eval(self, wi, wo):
        lobe, c = ggx_microfacet(wi, wo, self.alpha, self.alpha)
        return self.kd * INV_PI + self.fresnel(c) * lobe[:, None]


# ---------------------------------------------------------------------------
# The built-in materials
# ---------------------------------------------------------------------------

# Complex refractive indices eta + i k at RGB (red, green, blue) of common use
# in renderers: reductions of measured spectra to three channels. They agree
# within 0.5% with the RGB values Mitsuba 3 derives from its built-in spectral
# tables (conductor ``material = "Au" / "Cu" / "Al"``; tested). They are
# constants of the synthetic materials, not measurements to quote.
GOLD_ETA, GOLD_K = (0.143119, 0.374957, 1.44248), (3.98316, 2.38572, 1.60322)
COPPER_ETA, COPPER_K = (0.200438, 0.924033, 1.10221), (3.91295, 2.45285, 2.14219)
ALUMINIUM_ETA, ALUMINIUM_K = (1.65746, 0.880369, 0.521229), (9.22387, 6.26952, 4.83700)


def _plastic():
    return LambertGGXDielectric("plastic", kd=(0.45, 0.22, 0.08), eta=1.5, alpha_x=0.2, alpha_y=0.2)


def _gold():
    return RoughConductor("gold", eta=GOLD_ETA, k=GOLD_K, alpha_x=0.25, alpha_y=0.25)


def _brushed_aluminium():
    # Brushed along x: the grooves tilt normals across x, so alpha_y >> alpha_x.
    return RoughConductor("brushed_aluminium", eta=ALUMINIUM_ETA, k=ALUMINIUM_K, alpha_x=0.06, alpha_y=0.35)


def _clearcoat_copper():
    base = RoughConductor("copper_base", eta=COPPER_ETA, k=COPPER_K, alpha_x=0.35, alpha_y=0.35)
    return ClearCoat("clearcoat_copper", base=base, eta_coat=1.5, alpha_coat=0.04)


def _retroreflector():
    lobe = RoughConductor("retro_lobe", eta=ALUMINIUM_ETA, k=ALUMINIUM_K, alpha_x=0.3, alpha_y=0.3,
                          tint=(0.9, 0.75, 0.15))
    return Retroreflector("retroreflector", kd=(0.08, 0.07, 0.02), lobe=lobe)


def _rough_clay():
    return OrenNayarFujii("rough_clay", rho=(0.9, 0.55, 0.35), sigma=1.0)


def _velvet():
    return CharlieSheen("velvet", kd=(0.3, 0.02, 0.08), sheen=(0.7, 0.35, 0.45), r=0.4)


def _thin_film():
    # A 600 nm lacquer-like film (1.5) on a high-index base (2.5, TiO2-like): the
    # highlight runs magenta -> green -> cyan -> violet as the angle grows.
    return ThinFilmGGX("thin_film", eta_film=1.5, thickness_nm=600.0, eta_base=2.5, alpha=0.15, kd=0.0)


#: name -> factory of the built-in materials, in the order ``synthetic:all`` lists them.
SYNTHETIC_MATERIALS: "OrderedDict[str, Callable[[], SyntheticBRDF]]" = OrderedDict(
    [
        ("plastic", _plastic),
        ("gold", _gold),
        ("brushed_aluminium", _brushed_aluminium),
        ("clearcoat_copper", _clearcoat_copper),
        ("retroreflector", _retroreflector),
        ("rough_clay", _rough_clay),
        ("velvet", _velvet),
        ("thin_film", _thin_film),
    ]
)


def open_synthetic(name: str) -> BRDFSource:
    """A new instance of the built-in material ``name`` (see :data:`SYNTHETIC_MATERIALS`).

    Raises :class:`BRDFFormatError` ``"synthetic:<name>: unknown synthetic
    material ...; known: ..."`` for any other name.
    """
    factory = SYNTHETIC_MATERIALS.get(name)
    if factory is None:
        raise BRDFFormatError(
            "synthetic:" + str(name),
            f"unknown synthetic material {name!r}; known: {', '.join(SYNTHETIC_MATERIALS)}",
        )
    return factory()


def synthetic_names() -> Sequence[str]:
    """Names of the built-in materials, in order."""
    return list(SYNTHETIC_MATERIALS)


__all__ = [
    "SYNTHETIC_MATERIALS",
    "MAX_OPTICAL_THICKNESS_NM",
    "WAVELENGTHS_NM",
    "CharlieSheen",
    "ClearCoat",
    "LambertGGXDielectric",
    "OrenNayarFujii",
    "Retroreflector",
    "RoughConductor",
    "SyntheticBRDF",
    "ThinFilmGGX",
    "cie1931_xyz",
    "fresnel_conductor",
    "fresnel_dielectric",
    "ggx_D",
    "ggx_microfacet",
    "half_vector",
    "open_synthetic",
    "smith_G1_over_2cos",
    "spectral_to_rgb_weights",
    "synthetic_names",
    "thin_film_reflectance",
]
