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

The shared numerics (half vector, GGX, Fresnel) are :mod:`hybridbrdf.brdf.microfacet`'s; the thin
film's spectral tools are :mod:`hybridbrdf.sources.spectral`'s.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Callable, Dict, Sequence

import numpy as np

from hybridbrdf.brdf.analytic import AnalyticParams
from hybridbrdf.brdf.microfacet import dot, fresnel_conductor, fresnel_dielectric, ggx_microfacet, half_vector
from hybridbrdf.sources.base import BRDFFormatError, BRDFSource
from hybridbrdf.sources.spectral import (MAX_OPTICAL_THICKNESS_NM, WAVELENGTHS_NM, spectral_to_rgb_weights,
                                         thin_film_reflectance)

INV_PI = 1.0 / np.pi


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
        s = dot(wi, wo) - wi[:, 2] * wo[:, 2]
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
