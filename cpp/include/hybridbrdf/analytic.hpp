// hybridbrdf — the analytic component f_a of the hybrid model: Lambert plus an
// anisotropic GGX specular lobe with exact dielectric Fresnel (paper Sec. 3.2,
// docs/CONVENTIONS.md):
//
//     f_a(wi, wo) = kd / pi + F(wo.h, eta) D(h) G1(wi) G1(wo) / (4 wi.z wo.z)
//
// wi points to the light, wo to the viewer, both away from the surface, in the
// local frame (n = +z). f is returned without the cosine factor.
#pragma once

#include "hybridbrdf/fresnel.hpp"
#include "hybridbrdf/ggx.hpp"
#include "hybridbrdf/params.hpp"

namespace hbrdf {

/// The half vector h = normalize(wi + wo) of two unit directions above the horizon, as f_a
/// uses it. Both directions above the horizon => (wi + wo).z > 0; if its length underflows
/// (wi ~ -wo at grazing angles) the limit of h is +z. The hybrid-half architecture feeds h.z
/// and cos_theta_d to its network (spec/model.json, direction_inputs local_half), from these
/// two functions, so that the network's inputs and f_a cannot drift apart.
///
/// Two functions returning a vector and a scalar, not one returning a struct {h, cos_d}: GCC
/// 12 copies such a struct as an aggregate, and an aggregate copy in the loop body stops the
/// batched kernels from vectorising (f_a falls to the baseline kernel's speed; docs/BENCHMARKS.md,
/// "Analytic BRDF f_a"; guarded by tests/python/test_vectorisation.py).
template <typename T> HBRDF_INLINE Vec3<T> half_vector(const Vec3<T>& wi, const Vec3<T>& wo) {
    const Vec3<T> s = wi + wo;
    const T inv_len_s = inverse_length_or_zero(s);
    return Vec3<T>(s.x * inv_len_s, s.y * inv_len_s, inv_len_s > T(0) ? s.z * inv_len_s : T(1));
}

/// cos theta_d = wi.h = wo.h of the half vector h of (wi, wo). The two dot products are
/// equal in exact arithmetic; averaging them makes f(wi, wo) == f(wo, wi) bit for bit in
/// floating point too.
template <typename T> HBRDF_INLINE T cos_theta_d(const Vec3<T>& wi, const Vec3<T>& wo, const Vec3<T>& h) {
    return T(0.5) * (dot(wo, h) + dot(wi, h));
}

/// f_a with its parameters folded into the constants evaluation needs.
/// Construction clamps the parameters into their valid box (see clamped()),
/// so eval() is finite and >= 0 for any parameters and any input.
template <typename T> class AnalyticBrdfT {
public:
    explicit AnalyticBrdfT(const AnalyticParamsT<T>& params)
        : params_(clamped(params)), alpha_(params_.alpha.x, params_.alpha.y),
          kd_over_pi_(params_.kd * kInvPi<T>),
          eta2_minus_1_(params_.eta * params_.eta - Vec3<T>(T(1))) {}

    const AnalyticParamsT<T>& params() const { return params_; }
    const GgxAlpha<T>& alpha() const { return alpha_; }
    const Vec3<T>& eta2_minus_1() const { return eta2_minus_1_; }

    /// f_a(wi, wo) for unit directions (non-unit ones are normalised). Returns
    /// 0 when either direction is at or below the horizon (z <= 0), has zero
    /// length, or holds NaN/Inf. Otherwise finite: with the Smith term in its
    /// G1/(2 cos) form the specular part is bounded by
    /// D_max * V_max = 1/(pi ax ay) * 1/min(ax, ay)^2 (3e15 at kAlphaMin).
    HBRDF_INLINE Vec3<T> eval(const Vec3<T>& wi_in, const Vec3<T>& wo_in) const {
        const Vec3<T> wi = wi_in * inverse_length_or_zero(wi_in);
        const Vec3<T> wo = wo_in * inverse_length_or_zero(wo_in);
        // Invalid inputs became 0 (or NaN): "z > 0" rejects both.
        const bool valid = wi.z > T(0) && wo.z > T(0);
        const Vec3<T> h = half_vector(wi, wo);
        // G1(wi) G1(wo) multiplied first: a product of two commutes exactly, so f(wi, wo) ==
        // f(wo, wi) bit for bit ((D G1(wi)) G1(wo) rounds differently from (D G1(wo)) G1(wi)).
        const T DG = ggx_D(h, alpha_) * (smith_g1_over_2cos(wi, alpha_) * smith_g1_over_2cos(wo, alpha_));
        const T c = cos_theta_d(wi, wo, h);
        const T r = kd_over_pi_.x + fresnel_dielectric(c, eta2_minus_1_.x) * DG;
        const T g = kd_over_pi_.y + fresnel_dielectric(c, eta2_minus_1_.y) * DG;
        const T b = kd_over_pi_.z + fresnel_dielectric(c, eta2_minus_1_.z) * DG;
        // Per-component selects (not a select of vectors) keep this a SIMD blend.
        return Vec3<T>(valid ? r : T(0), valid ? g : T(0), valid ? b : T(0));
    }

private:
    AnalyticParamsT<T> params_;
    GgxAlpha<T> alpha_;
    Vec3<T> kd_over_pi_;
    Vec3<T> eta2_minus_1_;
};
using AnalyticBrdf = AnalyticBrdfT<float>;

/// Convenience: f_a for one pair of directions.
template <typename T>
HBRDF_INLINE Vec3<T> eval_analytic(const Vec3<T>& wi, const Vec3<T>& wo, const AnalyticParamsT<T>& params) {
    return AnalyticBrdfT<T>(params).eval(wi, wo);
}

}  // namespace hbrdf
