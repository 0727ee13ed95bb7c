"""CONVENTIONS.md transcribed literally in NumPy float64: the textbook forms
(G1 = 2 / (1 + sqrt(1 + ...)), Fresnel with (g - c)/(g + c)), none of the
library's rewrites or guards. An independent oracle for unit directions
strictly above the horizon: the tests check the C++ library, the PyTorch
model and the package's NumPy microfacet maths (hybridbrdf.brdf.microfacet)
against it, and bench/bench_analytic.py times it as the NumPy path. It lives
with the tests, outside the package, so that nothing shipped depends on it and
the package keeps one NumPy definition of each formula."""

import numpy as np


def textbook_fa(wi, wo, kd, eta, alpha):
    kd, eta = np.asarray(kd, float), np.asarray(eta, float)
    ax, ay = float(alpha[0]), float(alpha[1])
    h = wi + wo
    h = h / np.linalg.norm(h, axis=1, keepdims=True)
    t = (h[:, 0] / ax) ** 2 + (h[:, 1] / ay) ** 2 + h[:, 2] ** 2
    D = 1.0 / (np.pi * ax * ay * t * t)

    def G1(w):
        return 2.0 / (1.0 + np.sqrt(1.0 + (ax * ax * w[:, 0] ** 2 + ay * ay * w[:, 1] ** 2) / w[:, 2] ** 2))

    G = G1(wi) * G1(wo)
    c = (wo * h).sum(axis=1)[:, None]
    g = np.sqrt(eta[None, :] ** 2 - 1.0 + c * c)
    q1 = (g - c) / (g + c)
    q2 = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    F = 0.5 * q1 * q1 * (1.0 + q2 * q2)
    return kd[None, :] / np.pi + F * (D * G / (4.0 * wi[:, 2] * wo[:, 2]))[:, None]


# ---- sampling, float64, written from the papers -----------------------------


def fresnel_textbook(c, eta):
    g = np.sqrt(eta * eta - 1.0 + c * c)
    q1 = (g - c) / (g + c)
    q2 = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return 0.5 * q1 * q1 * (1.0 + q2 * q2)


def concentric_disk(u):
    """Shirley & Chiu 1997."""
    a, b = 2.0 * u[:, 0] - 1.0, 2.0 * u[:, 1] - 1.0
    r = np.where(np.abs(a) > np.abs(b), a, b)
    with np.errstate(invalid="ignore", divide="ignore"):
        phi = np.where(np.abs(a) > np.abs(b), np.pi / 4 * b / a, np.pi / 2 - np.pi / 4 * a / b)
    phi = np.where(r == 0, 0.0, phi)
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)


def sample_cosine(u):
    d = concentric_disk(u)
    return np.concatenate([d, np.sqrt(np.maximum(0.0, 1.0 - (d * d).sum(1)))[:, None]], axis=1)


def sample_vndf(wo, u, ax, ay):
    """Dupuy & Benyoub 2023, spherical caps, with the anisotropic stretch."""
    ws = np.stack([wo[:, 0] * ax, wo[:, 1] * ay, wo[:, 2]], axis=1)
    ws /= np.linalg.norm(ws, axis=1, keepdims=True)
    phi = 2.0 * np.pi * u[:, 0]
    z = (1.0 - u[:, 1]) * (1.0 + ws[:, 2]) - ws[:, 2]
    st = np.sqrt(np.clip(1.0 - z * z, 0.0, 1.0))
    hs = np.stack([st * np.cos(phi), st * np.sin(phi), z], axis=1) + ws
    h = np.stack([hs[:, 0] * ax, hs[:, 1] * ay, hs[:, 2]], axis=1)
    return h / np.linalg.norm(h, axis=1, keepdims=True)


def ggx_lobe_probability(wo, kd, eta):
    fs = np.mean([fresnel_textbook(wo[:, 2], e) for e in eta], axis=0)
    kdm = float(np.mean(kd))
    return np.clip(fs / (fs + kdm), 0.1, 0.9)


def sample_mis(wo, u, kd, eta, alpha):
    """One-sample MIS of GGX visible normals and cosine; returns (wi, pdf, weight)."""
    ax, ay = alpha
    p = ggx_lobe_probability(wo, kd, eta)
    use_ggx = u[:, 0] < p
    u2 = u.copy()
    u2[:, 0] = np.where(use_ggx, u[:, 0] / p, (u[:, 0] - p) / (1.0 - p))
    h = sample_vndf(wo, u2, ax, ay)
    wi_ggx = 2.0 * (wo * h).sum(1, keepdims=True) * h - wo
    wi = np.where(use_ggx[:, None], wi_ggx, sample_cosine(u2))
    pdf = p * pdf_vndf(wi, wo, ax, ay) + (1.0 - p) * np.maximum(wi[:, 2], 0.0) / np.pi
    f = np.zeros_like(wi)
    up = wi[:, 2] > 0
    f[up] = textbook_fa(wi[up], wo[up], kd, eta, alpha)
    return wi, pdf, f * np.maximum(wi[:, 2:3], 0.0) / pdf[:, None]


def pdf_vndf(wi, wo, ax, ay):
    h = wi + wo
    h = h / np.linalg.norm(h, axis=1, keepdims=True)
    t = (h[:, 0] / ax) ** 2 + (h[:, 1] / ay) ** 2 + h[:, 2] ** 2
    D = np.where(h[:, 2] > 0, 1.0 / (np.pi * ax * ay * t * t), 0.0)
    g1 = 2.0 / (1.0 + np.sqrt(1.0 + (ax * ax * wo[:, 0] ** 2 + ay * ay * wo[:, 1] ** 2) / wo[:, 2] ** 2))
    return g1 * D / (4.0 * wo[:, 2])
