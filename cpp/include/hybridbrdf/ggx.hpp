// hybridbrdf — the anisotropic GGX (Trowbridge-Reitz) microfacet distribution:
// normal distribution D, separable Smith masking and visible-normal sampling.
//
// Frame: n = +z, alpha_x along +x. Every function is branch-free and finite for
// alpha in [kAlphaMin, 1] and any unit-length input.
#pragma once

#include "hybridbrdf/math.hpp"

namespace hbrdf {

/// GGX roughness, with the squares and reciprocals the formulas use.
template <typename T> struct GgxAlpha {
    T ax, ay;          ///< roughness along x and y
    T ax2, ay2;        ///< ax^2, ay^2
    T inv_ax2, inv_ay2;
    T d_norm;          ///< 1 / (pi ax ay)

    GgxAlpha() = default;
    GgxAlpha(T alpha_x, T alpha_y)
        : ax(alpha_x), ay(alpha_y), ax2(alpha_x * alpha_x), ay2(alpha_y * alpha_y),
          inv_ax2(T(1) / (alpha_x * alpha_x)), inv_ay2(T(1) / (alpha_y * alpha_y)),
          d_norm(kInvPi<T> / (alpha_x * alpha_y)) {}
};

/// D(h) = 1 / (pi ax ay (hx^2/ax^2 + hy^2/ay^2 + hz^2)^2) for h.z > 0, else 0
/// (Walter et al. 2007, Eq. 33; Heitz 2014, Eq. 85). For unit h and alpha <= 1
/// the bracket is >= 1, so D <= 1/(pi ax ay) and never overflows.
template <typename T> HBRDF_INLINE T ggx_D(const Vec3<T>& h, const GgxAlpha<T>& a) {
    const T t = h.x * h.x * a.inv_ax2 + h.y * h.y * a.inv_ay2 + h.z * h.z;
    const T d = a.d_norm / (t * t);
    return h.z > T(0) ? d : T(0);
}

/// Smith masking in the form that stays finite at grazing angles:
///
///     G1(w) / (2 w.z) = 1 / (w.z + sqrt(w.z^2 + ax^2 wx^2 + ay^2 wy^2))
///
/// which is the separable Smith G1(w) = 2 / (1 + sqrt(1 + (ax^2 wx^2 + ay^2 wy^2)/wz^2))
/// (Heitz 2014, Eq. 43 and 86) divided by 2 w.z. For unit w with w.z >= 0 the
/// denominator is >= min(ax, ay) * |w| > 0.
template <typename T> HBRDF_INLINE T smith_g1_over_2cos(const Vec3<T>& w, const GgxAlpha<T>& a) {
    const T t = a.ax2 * w.x * w.x + a.ay2 * w.y * w.y;
    return T(1) / (w.z + std::sqrt(w.z * w.z + t));
}

/// Visible-normal sampling of GGX with spherical caps (Dupuy & Benyoub 2023,
/// "Sampling Visible GGX Normals with Spherical Caps", Listing 3): stretch wo
/// to the alpha = 1 configuration, sample the spherical cap of directions
/// whose half vector with wo lies on the upper hemisphere, unstretch.
/// `wo` must be unit with wo.z > 0; u in [0, 1)^2. Returns a unit h with h.z >= 0.
template <typename T> HBRDF_INLINE Vec3<T> sample_ggx_vndf(const Vec3<T>& wo, const Vec2<T>& u, const GgxAlpha<T>& a) {
    const Vec3<T> wo_stretched(wo.x * a.ax, wo.y * a.ay, wo.z);
    const Vec3<T> wo_std = wo_stretched * inverse_length_or_zero(wo_stretched);
    const T phi = T(2) * kPi<T> * u.x;
    const T z = (T(1) - u.y) * (T(1) + wo_std.z) - wo_std.z;
    const T sin_theta = safe_sqrt(T(1) - z * z);
    const Vec3<T> h_std(sin_theta * std::cos(phi) + wo_std.x, sin_theta * std::sin(phi) + wo_std.y, z + wo_std.z);
    // h_std.z >= 0 by construction of the cap; max0 only absorbs rounding.
    const Vec3<T> h(h_std.x * a.ax, h_std.y * a.ay, max0(h_std.z));
    const T inv_len = inverse_length_or_zero(h);
    // A degenerate (zero) h_std, reachable only at u.y = 1, falls back to +z.
    return inv_len > T(0) ? h * inv_len : Vec3<T>(T(0), T(0), T(1));
}

/// Solid-angle density of the direction wi = reflect(wo, h) produced by
/// sample_ggx_vndf, over the whole sphere (directions below the horizon
/// included, where it is the VNDF's leakage):
///
///     pdf(wi) = D_wo(h) / (4 wo.h) = G1(wo) D(h) / (4 wo.z),  h = normalize(wi + wo)
///
/// Heitz 2018, Eq. 17 with the reflection Jacobian. 0 when wo.z <= 0 or h.z <= 0.
template <typename T> HBRDF_INLINE T pdf_ggx_vndf(const Vec3<T>& wi, const Vec3<T>& wo, const GgxAlpha<T>& a) {
    const Vec3<T> s = wi + wo;
    const T inv_len = inverse_length_or_zero(s);
    const T pdf = ggx_D(s * inv_len, a) * T(0.5) * smith_g1_over_2cos(wo, a);
    // Two selects rather than one on an "&&", which GCC 12 cannot vectorise here (src/batch.cpp).
    const T pdf_h = inv_len > T(0) ? pdf : T(0);
    return wo.z > T(0) ? pdf_h : T(0);
}

}  // namespace hbrdf
