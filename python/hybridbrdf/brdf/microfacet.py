"""f_a's microfacet building blocks in NumPy float64, vectorised over direction pairs: the package's
one NumPy definition of the half vector, anisotropic GGX D and Smith G1, and exact dielectric and
conductor Fresnel (the synthetic materials are built from them). Forms as libhybridbrdf's
(cpp/include/hybridbrdf/ggx.hpp, fresnel.hpp, analytic.hpp), so that a material in f_a's family
agrees with the C++ library to rounding:

- the GGX visibility term is written ``G1(w) / (2 w.z) = 1 / (w.z + sqrt(w.z^2
  + ax^2 wx^2 + ay^2 wy^2))``, which never divides by a grazing cosine;
- the Fresnel cosine is ``(wo.h + wi.h) / 2`` (equal to wo.h in exact
  arithmetic, symmetric in wi, wo in floating point), so reciprocity holds to
  rounding (1e-15 relative);
- squares are written as products.
"""

from __future__ import annotations

import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products of (M, 3) arrays, (M,)."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def half_vector(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """h = normalize(wi + wo) for (M,3) unit directions above the horizon.

    The sum is scaled by its largest component before normalising, so the
    length never underflows: for wi ~ -wo, both grazing, h is +z, the limit
    from above that docs/CONVENTIONS.md prescribes (wi.z + wo.z > 0 always).
    """
    v = wi + wo
    v = v / np.max(np.abs(v), axis=1, keepdims=True)
    return v / np.sqrt(dot(v, v))[:, None]


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
    # G1(wi) G1(wo) first: a product of two commutes exactly, so the lobe is reciprocal bit for bit.
    lobe = ggx_D(h, alpha_x, alpha_y) * (smith_G1_over_2cos(wi, alpha_x, alpha_y)
                                         * smith_G1_over_2cos(wo, alpha_x, alpha_y))
    cos_theta_d = 0.5 * (dot(wo, h) + dot(wi, h))
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
