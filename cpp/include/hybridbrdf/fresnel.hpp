// hybridbrdf — Fresnel reflectance.
#pragma once

#include "hybridbrdf/math.hpp"

namespace hbrdf {

/// Exact unpolarised Fresnel reflectance of a dielectric interface with real
/// relative index of refraction eta >= 1, lit from outside at cos(theta) = c
/// (Cook & Torrance 1982; Walter et al. 2007, Eq. 22):
///
///     g = sqrt(eta^2 - 1 + c^2)
///     F = 1/2 ((g-c)/(g+c))^2 (1 + ((c(g+c)-1) / (c(g-c)+1))^2)
///
/// Takes e = eta^2 - 1 (precomputed per material). The textbook form cancels
/// catastrophically in g - c as eta -> 1; with s = g + c we use
/// g - c = e / s and fold both quotients into one division:
///
///     F = e^2 (a^2 s^2 + b^2) / (2 s^4 b^2),  a = c s - 1,  b = c e + s
///
/// Finite and in [0, 1] for every c (clamped to [0, 1], NaN -> 0) and e >= 0;
/// the only 0/0 (c = 0 with eta = 1) returns 0, the eta = 1 value.
template <typename T> HBRDF_INLINE T fresnel_dielectric(T cos_theta, T eta2_minus_1) {
    const T c = clamp_nan_lo(cos_theta, T(0), T(1));
    const T e = eta2_minus_1;
    const T s = std::sqrt(e + c * c) + c;
    const T a = c * s - T(1);
    const T b = c * e + s;
    const T s2 = s * s;
    const T den = T(2) * s2 * s2 * b * b;
    const T num = e * e * (a * a * s2 + b * b);
    return den > T(0) ? num / den : T(0);
}

}  // namespace hbrdf
