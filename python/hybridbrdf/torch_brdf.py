"""The analytic BRDF f_a in PyTorch: differentiable, float32 or float64.

Same formulas and the same guards as the C++ library (docs/CONVENTIONS.md),
written with ``torch.where`` so that it stays branch-free and, for training,
keeps gradients finite: invalid directions are replaced by +z *before* any
arithmetic (the "double where" pattern), so no NaN reaches the backward pass.

Shapes: directions ``(..., 3)``; ``kd``/``eta`` ``(..., 3)`` and ``alpha``
``(..., 2)`` broadcast against them (one material, or one per row, or a
material axis for joint fitting).
"""

from __future__ import annotations

import math

import torch

from hybridbrdf import _core

ALPHA_MIN = _core.ALPHA_MIN
ETA_MIN = _core.ETA_MIN
ETA_MAX = _core.ETA_MAX
INV_PI = 1.0 / math.pi


def _clamp_nan_lo(x: torch.Tensor, lo: float, hi: float) -> torch.Tensor:
    """clamp(x, lo, hi) with NaN mapped to lo, as the C++ library does."""
    return torch.where(torch.isnan(x), torch.full_like(x, lo), x).clamp(lo, hi)


def _normalize(v: torch.Tensor):
    """(unit vector, validity): zero, under/overflowing or non-finite vectors are
    invalid and replaced by +z."""
    finfo = torch.finfo(v.dtype)
    len2 = (v * v).sum(-1, keepdim=True)
    ok = (len2 >= finfo.tiny) & (len2 <= finfo.max)
    safe_len2 = torch.where(ok, len2, torch.ones_like(len2))
    z = torch.zeros_like(v)
    z[..., 2] = 1.0
    w = torch.where(ok, v * torch.rsqrt(safe_len2), z)
    return w, ok[..., 0]


def fresnel_dielectric(cos_theta: torch.Tensor, eta2_minus_1: torch.Tensor) -> torch.Tensor:
    """Exact unpolarised dielectric Fresnel reflectance, real eta >= 1.

    The C++ ``fresnel_dielectric`` form: with s = g + c, a = c s - 1, b = c e + s
    (e = eta^2 - 1), F = e^2 (a^2 s^2 + b^2) / (2 s^4 b^2), which avoids the
    cancellation in g - c as eta -> 1. 0 for the single 0/0 (c = 0, eta = 1).
    """
    c = cos_theta.clamp(0.0, 1.0)
    e = eta2_minus_1
    s = torch.sqrt(e + c * c) + c
    a = c * s - 1.0
    b = c * e + s
    s2 = s * s
    den = 2.0 * s2 * s2 * b * b
    num = e * e * (a * a * s2 + b * b)
    ok = den > 0
    return torch.where(ok, num / torch.where(ok, den, torch.ones_like(den)), torch.zeros_like(den))


def ggx_D(h: torch.Tensor, ax: torch.Tensor, ay: torch.Tensor) -> torch.Tensor:
    """Anisotropic GGX normal distribution D(h) (0 for h.z <= 0); Walter et al. 2007."""
    hx, hy, hz = h.unbind(-1)
    t = hx * hx / (ax * ax) + hy * hy / (ay * ay) + hz * hz
    d = 1.0 / (math.pi * ax * ay * t * t)
    return torch.where(hz > 0, d, torch.zeros_like(d))


def smith_g1_over_2cos(w: torch.Tensor, ax: torch.Tensor, ay: torch.Tensor) -> torch.Tensor:
    """G1(w) / (2 w.z) = 1 / (w.z + sqrt(w.z^2 + ax^2 wx^2 + ay^2 wy^2)), separable Smith GGX."""
    wx, wy, wz = w.unbind(-1)
    return 1.0 / (wz + torch.sqrt(wz * wz + ax * ax * wx * wx + ay * ay * wy * wy))


def eval_analytic(
    wi: torch.Tensor, wo: torch.Tensor, kd: torch.Tensor, eta: torch.Tensor, alpha: torch.Tensor
) -> torch.Tensor:
    """f_a(wi, wo) = kd/pi + F(wo.h, eta) D(h) G1(wi) G1(wo) / (4 wi.z wo.z), shape (..., 3).

    0 where either direction is below the horizon or invalid. Parameters
    outside their ranges are clamped (NaN -> lower bound). Computed in the
    dtype of ``wi``; parameters are cast to it.
    """
    dtype = wi.dtype
    kd = _clamp_nan_lo(torch.as_tensor(kd, dtype=dtype, device=wi.device), 0.0, 1.0)
    eta = _clamp_nan_lo(torch.as_tensor(eta, dtype=dtype, device=wi.device), ETA_MIN, ETA_MAX)
    alpha = _clamp_nan_lo(torch.as_tensor(alpha, dtype=dtype, device=wi.device), ALPHA_MIN, 1.0)
    ax, ay = alpha[..., 0], alpha[..., 1]

    wi_n, ok_i = _normalize(wi)
    wo_n, ok_o = _normalize(wo.to(dtype))
    valid = ok_i & ok_o & (wi_n[..., 2] > 0) & (wo_n[..., 2] > 0)
    up = torch.zeros_like(wi_n)
    up[..., 2] = 1.0
    wi_n = torch.where(valid[..., None], wi_n, up)
    wo_n = torch.where(valid[..., None], wo_n, up)

    # Both above the horizon => (wi + wo).z > 0; an underflowing length
    # (wi ~ -wo at grazing angles) has the limit h = +z, which _normalize gives.
    h, _ = _normalize(wi_n + wo_n)
    dg = ggx_D(h, ax, ay) * smith_g1_over_2cos(wi_n, ax, ay) * smith_g1_over_2cos(wo_n, ax, ay)
    c = 0.5 * ((wo_n * h).sum(-1) + (wi_n * h).sum(-1))  # symmetric: exact reciprocity
    F = fresnel_dielectric(c[..., None], eta * eta - 1.0)
    f = kd * INV_PI + F * dg[..., None]
    return torch.where(valid[..., None], f, torch.zeros_like(f))
