"""The analytic BRDF f_a in PyTorch: differentiable, float32 or float64.

Same formulas and the same guards as the C++ library (docs/CONVENTIONS.md),
written with ``torch.where`` so that it stays branch-free and, for training,
keeps gradients finite: invalid and below-horizon directions are replaced by +z
*before* any arithmetic (the "safe where" pattern: masking only the output would
still send inf * 0 = NaN through the backward pass of the masked rows), square
roots never see 0 where their derivative matters, and normalisation has a
backward of its own that cannot overflow. For valid inputs the forward values
are those of the plain formulas, bit for bit.

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


class _Scale(torch.autograd.Function):
    """u = v * inv_len for inv_len = 1 / |v| (given, without gradient), differentiated as the
    unit vector it is: du = (g - u (u.g)) inv_len.

    Autograd's own chain through rsqrt(|v|^2) forms |v|^-3, which overflows float32 for
    |v| < ~1e-13 (valid directions go down to |v| = 1.1e-19) and turns into inf - inf = NaN,
    while the true derivative, of size 1 / |v|, is finite."""

    @staticmethod
    def forward(v: torch.Tensor, inv_len: torch.Tensor) -> torch.Tensor:
        return v * inv_len

    @staticmethod
    def setup_context(ctx, inputs, output):
        ctx.save_for_backward(output, inputs[1])

    @staticmethod
    def backward(ctx, g):
        u, inv_len = ctx.saved_tensors
        return (g - u * (u * g).sum(-1, keepdim=True)) * inv_len, None


def _normalize(v: torch.Tensor):
    """(unit vector, validity): zero, under/overflowing or non-finite vectors are
    invalid and replaced by +z, before any arithmetic, so their gradient is 0, not NaN."""
    finfo = torch.finfo(v.dtype)
    with torch.no_grad():
        len2 = (v * v).sum(-1, keepdim=True)
        ok = (len2 >= finfo.tiny) & (len2 <= finfo.max)  # NaN compares false
    # Safe where: the backward of v * v at a NaN or Inf row would give 0 * NaN = NaN.
    v_safe = torch.where(ok, v, _unit_z(v))
    with torch.no_grad():
        inv_len = torch.rsqrt((v_safe * v_safe).sum(-1, keepdim=True))  # = rsqrt(len2) on valid rows
    return _Scale.apply(v_safe, inv_len), ok[..., 0]


def _unit_z(like: torch.Tensor) -> torch.Tensor:
    """+z in the shape, dtype and device of ``like`` (..., 3)."""
    z = torch.zeros_like(like)
    z[..., 2] = 1.0
    return z


def fresnel_dielectric(cos_theta: torch.Tensor, eta2_minus_1: torch.Tensor) -> torch.Tensor:
    """Exact unpolarised dielectric Fresnel reflectance, real eta >= 1.

    The C++ ``fresnel_dielectric`` form: with s = g + c, a = c s - 1, b = c e + s
    (e = eta^2 - 1), F = e^2 (a^2 s^2 + b^2) / (2 s^4 b^2), which avoids the
    cancellation in g - c as eta -> 1. 0 for e <= 0 (eta = 1: no interface).
    """
    c = cos_theta.clamp(0.0, 1.0)
    e = eta2_minus_1
    # sqrt's derivative is infinite at 0 (e = 0 and c = 0, or c^2 underflowing): the floor keeps
    # it finite and changes no value, since F = 0 there anyway (e = 0).
    s = torch.sqrt(torch.clamp(e + c * c, min=torch.finfo(c.dtype).tiny)) + c
    a = c * s - 1.0
    b = c * e + s
    s2 = s * s
    den = 2.0 * s2 * s2 * b * b
    num = e * e * (a * a * s2 + b * b)
    # For e > 0, den >= 2 e^3 (s, b >= sqrt(e)): 2.8e-20 at the smallest float32 e. For e = 0,
    # F = 0 but den = 2 s^6 underflows at grazing c; a safe where keeps the backward from
    # forming inf = upstream / den and then inf * e^2 = inf * 0 = NaN.
    has_interface = e > 0
    ratio = num / torch.where(has_interface, den, torch.ones_like(den))
    return torch.where(has_interface, ratio, torch.zeros_like(ratio))


def ggx_D(h: torch.Tensor, ax: torch.Tensor, ay: torch.Tensor) -> torch.Tensor:
    """Anisotropic GGX normal distribution D(h) (0 for h.z <= 0); Walter et al. 2007."""
    return torch.where(h[..., 2] > 0, _ggx_D_upper(h, ax, ay), torch.zeros_like(h[..., 2]))


def _ggx_D_upper(h: torch.Tensor, ax: torch.Tensor, ay: torch.Tensor) -> torch.Tensor:
    """D(h) without the h.z > 0 mask, for half vectors known to be upper (eval_analytic)."""
    hx, hy, hz = h.unbind(-1)
    t = hx * hx / (ax * ax) + hy * hy / (ay * ay) + hz * hz
    return 1.0 / (math.pi * ax * ay * t * t)


def smith_g1_over_2cos(w: torch.Tensor, ax: torch.Tensor, ay: torch.Tensor) -> torch.Tensor:
    """G1(w) / (2 w.z) = 1 / (w.z + sqrt(w.z^2 + ax^2 wx^2 + ay^2 wy^2)), separable Smith GGX."""
    wx, wy, wz = w.unbind(-1)
    return 1.0 / (wz + torch.sqrt(wz * wz + ax * ax * wx * wx + ay * ay * wy * wy))


def half_vector(wi: torch.Tensor, wo: torch.Tensor):
    """(h, cos theta_d) for unit wi, wo above the horizon: h = normalize(wi + wo) and
    cos theta_d = (wi.h + wo.h) / 2 (libhybridbrdf's half_vector). Both above the horizon =>
    (wi + wo).z > 0; an underflowing length (wi ~ -wo at grazing angles) has the limit h = +z,
    which _normalize gives. The symmetric mean keeps f(wi, wo) = f(wo, wi) exactly."""
    h, _ = _normalize(wi + wo)
    return h, 0.5 * ((wo * h).sum(-1) + (wi * h).sum(-1))


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
    # Safe where: below-horizon rows would reach Smith's 1 / (w.z + |w|) = 1 / 0.
    up = _unit_z(wi_n)
    wi_n = torch.where(valid[..., None], wi_n, up)
    wo_n = torch.where(valid[..., None], wo_n, up)

    h, c = half_vector(wi_n, wo_n)
    # G1(wi) G1(wo) first, as libhybridbrdf: the product commutes exactly, so f is reciprocal bit for bit.
    dg = _ggx_D_upper(h, ax, ay) * (smith_g1_over_2cos(wi_n, ax, ay) * smith_g1_over_2cos(wo_n, ax, ay))
    F = fresnel_dielectric(c[..., None], eta * eta - 1.0)
    f = kd * INV_PI + F * dg[..., None]
    return torch.where(valid[..., None], f, torch.zeros_like(f))


def half_angle_cosines(wi: torch.Tensor, wo: torch.Tensor) -> torch.Tensor:
    """(cos theta_h, cos theta_d) of unit wi, wo, shape (..., 2): the extra network inputs of the
    hybrid-half architecture (spec/model.json, direction_inputs local_half), from the half vector
    eval_analytic uses."""
    h, c = half_vector(wi, wo)
    return torch.stack([h[..., 2], c], dim=-1)


def reciprocal_inputs(wi: torch.Tensor, wo: torch.Tensor) -> torch.Tensor:
    """The network inputs of the hybrid-reciprocal architecture (spec/model.json, direction_inputs
    reciprocal, format 2), shape (..., 9): s = wi + wo, then d.x d.x, d.y d.y, d.z d.z, d.x d.y,
    d.x d.z, d.y d.z of d = wi - wo. Exchanging wi and wo gives the same values bit for bit (the sum
    commutes, d only changes sign, exactly), so a network on them is exactly reciprocal. No halves:
    at half the scale (format 1) a third of the last hidden layer died in every fit (issue 60)."""
    s = wi + wo
    d = wi - wo
    dx, dy, dz = d.unbind(-1)
    return torch.cat([s, torch.stack([dx * dx, dy * dy, dz * dz, dx * dy, dx * dz, dy * dz], dim=-1)], dim=-1)


# ---- importance sampling (the library's three strategies, in PyTorch) --------

MIS_MIN_LOBE_PROBABILITY = _core.MIS_MIN_LOBE_PROBABILITY


def square_to_cosine_hemisphere(u: torch.Tensor) -> torch.Tensor:
    """Malley's method on the Shirley-Chiu concentric disk; pdf = w.z / pi."""
    a = 2.0 * u[..., 0] - 1.0
    b = 2.0 * u[..., 1] - 1.0
    a_major = a * a > b * b
    r = torch.where(a_major, a, b)
    num = torch.where(a_major, b, a)
    ratio = torch.where(r != 0, num / torch.where(r != 0, r, torch.ones_like(r)), torch.zeros_like(r))
    phi = torch.where(a_major, (math.pi / 4) * ratio, math.pi / 2 - (math.pi / 4) * ratio)
    x, y = r * torch.cos(phi), r * torch.sin(phi)
    return torch.stack([x, y, torch.sqrt(torch.clamp(1.0 - x * x - y * y, min=0.0))], dim=-1)


def sample_ggx_vndf(wo: torch.Tensor, u: torch.Tensor, ax: torch.Tensor, ay: torch.Tensor) -> torch.Tensor:
    """GGX visible normals by spherical caps (Dupuy & Benyoub 2023); wo unit, wo.z > 0."""
    wo_std, _ = _normalize(torch.stack([wo[..., 0] * ax, wo[..., 1] * ay, wo[..., 2]], dim=-1))
    phi = 2.0 * math.pi * u[..., 0]
    z = (1.0 - u[..., 1]) * (1.0 + wo_std[..., 2]) - wo_std[..., 2]
    sin_theta = torch.sqrt(torch.clamp(1.0 - z * z, min=0.0))
    h_std = torch.stack([sin_theta * torch.cos(phi), sin_theta * torch.sin(phi), z], dim=-1) + wo_std
    h, _ = _normalize(torch.stack([h_std[..., 0] * ax, h_std[..., 1] * ay, h_std[..., 2].clamp(min=0.0)], dim=-1))
    return h


def pdf_ggx_vndf(wi: torch.Tensor, wo: torch.Tensor, ax: torch.Tensor, ay: torch.Tensor) -> torch.Tensor:
    """Density of reflect(wo, h) with h from sample_ggx_vndf: G1(wo) D(h) / (4 wo.z), over the sphere.

    0 where wo is below the horizon or wi = -wo. Such rows are replaced by +z before any
    arithmetic, so that their gradient is 0 rather than inf * 0 = NaN (a straight-down wo makes
    Smith's 1 / (wo.z + |wo|) infinite), which would poison a shared alpha's gradient."""
    upper = wo[..., 2] > 0
    wo = torch.where(upper[..., None], wo, _unit_z(wo))
    h, ok = _normalize(wi + wo)
    ok = ok & upper & (h[..., 2] > 0)
    h = torch.where(ok[..., None], h, _unit_z(h))
    p = _ggx_D_upper(h, ax, ay) * 0.5 * smith_g1_over_2cos(wo, ax, ay)
    return torch.where(ok, p, torch.zeros_like(p))


def ggx_lobe_probability(wo: torch.Tensor, kd: torch.Tensor, eta: torch.Tensor) -> torch.Tensor:
    """P_ggx = clamp(Fs / (Fs + Kd), 0.1, 0.9), Fs = mean Fresnel at wo.z, Kd = mean kd."""
    fs = fresnel_dielectric(wo[..., 2:3], eta * eta - 1.0).mean(-1)
    kdm = kd.mean(-1)
    tot = fs + kdm
    p = torch.where(tot > 0, fs / torch.where(tot > 0, tot, torch.ones_like(tot)), torch.full_like(tot, 0.5))
    return p.clamp(MIS_MIN_LOBE_PROBABILITY, 1.0 - MIS_MIN_LOBE_PROBABILITY)


def _prepared(wo, kd, eta, alpha):
    dtype, dev = wo.dtype, wo.device
    kd = _clamp_nan_lo(torch.as_tensor(kd, dtype=dtype, device=dev), 0.0, 1.0)
    eta = _clamp_nan_lo(torch.as_tensor(eta, dtype=dtype, device=dev), ETA_MIN, ETA_MAX)
    alpha = _clamp_nan_lo(torch.as_tensor(alpha, dtype=dtype, device=dev), ALPHA_MIN, 1.0)
    return kd, eta, alpha


def pdf(wi: torch.Tensor, wo: torch.Tensor, kd, eta, alpha, strategy: str = "mis") -> torch.Tensor:
    """Solid-angle density of ``strategy`` (one of the library's STRATEGIES), as the C++ pdf()."""
    kd, eta, alpha = _prepared(wo, kd, eta, alpha)
    wi_n, ok_i = _normalize(wi.to(wo.dtype))
    wo_n, ok_o = _normalize(wo)
    valid = ok_i & ok_o & (wo_n[..., 2] > 0)
    # Safe where: rows without a density take +z before the arithmetic, so their gradient is 0.
    wi_n = torch.where(valid[..., None], wi_n, _unit_z(wi_n))
    wo_n = torch.where(valid[..., None], wo_n, _unit_z(wo_n))
    p_cos = torch.clamp(wi_n[..., 2], min=0.0) * INV_PI
    if strategy == "cosine":
        p = p_cos
    else:
        p_ggx = pdf_ggx_vndf(wi_n, wo_n, alpha[..., 0], alpha[..., 1])
        if strategy == "ggx":
            p = p_ggx
        elif strategy == "mis":
            w = ggx_lobe_probability(wo_n, kd, eta)
            p = w * p_ggx + (1.0 - w) * p_cos
        else:
            raise ValueError(f"unknown sampling strategy {strategy!r}; expected one of {', '.join(_core.STRATEGIES)}")
    return torch.where(valid, p, torch.zeros_like(p))


def sample(wo: torch.Tensor, u: torch.Tensor, kd, eta, alpha, strategy: str = "mis"):
    """Samples wi for each wo with u in [0,1)^2; returns (wi, pdf, weight = f cos / pdf).

    The same mapping as the C++ sample(): a row with pdf 0 is "no sample"
    (wi = +z, weight 0). Not differentiable with respect to u.
    """
    if strategy not in _core.STRATEGIES:  # the library's names; the branches below implement each
        raise ValueError(f"unknown sampling strategy {strategy!r}; expected one of {', '.join(_core.STRATEGIES)}")
    kd, eta, alpha = _prepared(wo, kd, eta, alpha)
    one_minus_eps = 1.0 - torch.finfo(wo.dtype).eps / 2
    u = _clamp_nan_lo(u.to(wo.dtype), 0.0, one_minus_eps)
    wo_n, ok_o = _normalize(wo)
    valid = ok_o & (wo_n[..., 2] > 0)
    wo_n = torch.where(valid[..., None], wo_n, _unit_z(wo_n))

    ux = u[..., 0]
    if strategy == "mis":
        p_ggx = ggx_lobe_probability(wo_n, kd, eta)
        use_ggx = ux < p_ggx
        ux = torch.where(use_ggx, ux / p_ggx, (ux - p_ggx) / (1.0 - p_ggx)).clamp(0.0, one_minus_eps)
    else:
        use_ggx = torch.full_like(ux, strategy == "ggx", dtype=torch.bool)
    u2 = torch.stack([ux, u[..., 1]], dim=-1)
    h = sample_ggx_vndf(wo_n, u2, alpha[..., 0], alpha[..., 1])
    wi_ggx = 2.0 * (wo_n * h).sum(-1, keepdim=True) * h - wo_n
    wi = torch.where(use_ggx[..., None], wi_ggx, square_to_cosine_hemisphere(u2))

    p = pdf(wi, wo_n, kd, eta, alpha, strategy)
    ok = valid & (p > 0)
    safe_p = torch.where(ok, p, torch.ones_like(p))
    weight = eval_analytic(wi, wo_n, kd, eta, alpha) * (torch.clamp(wi[..., 2], min=0.0) / safe_p)[..., None]
    return (
        torch.where(ok[..., None], wi, _unit_z(wi)),
        torch.where(ok, p, torch.zeros_like(p)),
        torch.where(ok[..., None], weight, torch.zeros_like(weight)),
    )
