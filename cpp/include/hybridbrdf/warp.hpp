// hybridbrdf — warps from the unit square to the hemisphere.
#pragma once

#include "hybridbrdf/math.hpp"

namespace hbrdf {

/// Largest float/double below 1: random numbers are clamped to [0, kOneMinusEps]
/// so that every warp sees the half-open square [0, 1)^2 it is defined on.
template <typename T> inline constexpr T kOneMinusEps = T(1) - std::numeric_limits<T>::epsilon() / T(2);

template <typename T> HBRDF_INLINE Vec2<T> clamp_unit_square(const Vec2<T>& u) {
    return Vec2<T>(clamp_nan_lo(u.x, T(0), kOneMinusEps<T>), clamp_nan_lo(u.y, T(0), kOneMinusEps<T>));
}

/// Shirley & Chiu 1997 concentric map: area-preserving, low distortion, so
/// stratified samples stay stratified on the disk.
template <typename T> HBRDF_INLINE Vec2<T> square_to_concentric_disk(const Vec2<T>& u) {
    const T a = T(2) * u.x - T(1);
    const T b = T(2) * u.y - T(1);
    const bool a_major = a * a > b * b;
    const T r = a_major ? a : b;
    // The minor/major ratio is in [-1, 1]; at the centre (0/0) any angle works.
    const T num = a_major ? b : a;
    const T ratio = r != T(0) ? num / r : T(0);
    const T phi = a_major ? (kPi<T> / T(4)) * ratio : (kPi<T> / T(2)) - (kPi<T> / T(4)) * ratio;
    return Vec2<T>(r * std::cos(phi), r * std::sin(phi));
}

/// Cosine-weighted hemisphere (Malley's method): pdf(w) = w.z / pi.
template <typename T> HBRDF_INLINE Vec3<T> square_to_cosine_hemisphere(const Vec2<T>& u) {
    const Vec2<T> d = square_to_concentric_disk(u);
    return Vec3<T>(d.x, d.y, safe_sqrt(T(1) - d.x * d.x - d.y * d.y));
}

/// Density of square_to_cosine_hemisphere over the sphere (0 below the horizon).
template <typename T> HBRDF_INLINE T square_to_cosine_hemisphere_pdf(const Vec3<T>& w) {
    return max0(w.z) * kInvPi<T>;
}

}  // namespace hbrdf
