// hybridbrdf — small math helpers shared by every formula in the library.
//
// Everything here is branch-free on purpose: the same scalar functions are
// inlined into the batched loops (where GCC/Clang turn the ternaries into SIMD
// blends) and mirror what the generated shaders do.
#pragma once

#include <cfloat>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

// Hot-path functions are force-inlined: the batched kernels are instantiated
// per instruction set (see src/batch.cpp) and only vectorise when the whole
// evaluation is inlined into their loop.
#if defined(__GNUC__) || defined(__clang__)
#define HBRDF_INLINE inline __attribute__((always_inline))
#else
#define HBRDF_INLINE inline
#endif

namespace hbrdf {

template <typename T> using Vec2 = glm::vec<2, T, glm::defaultp>;
template <typename T> using Vec3 = glm::vec<3, T, glm::defaultp>;

template <typename T> inline constexpr T kPi = T(3.141592653589793238462643383279502884);
template <typename T> inline constexpr T kInvPi = T(0.318309886183790671537767526745028724);

template <typename T> HBRDF_INLINE constexpr T sqr(T x) { return x * x; }

// max(x, 0) that also maps NaN to 0 ("x > 0" is false for NaN). Written as a
// ternary so that it compiles to maxps/maxpd in vectorised loops.
template <typename T> HBRDF_INLINE constexpr T max0(T x) { return x > T(0) ? x : T(0); }

// clamp(x, lo, hi) with NaN mapped to lo.
template <typename T> HBRDF_INLINE constexpr T clamp_nan_lo(T x, T lo, T hi) {
    const T y = x > lo ? x : lo;
    return y < hi ? y : hi;
}

// sqrt that never returns NaN for the tiny negative values rounding produces.
template <typename T> HBRDF_INLINE T safe_sqrt(T x) { return std::sqrt(max0(x)); }

// True for finite values; false for NaN and +-Inf. Unlike std::isfinite this
// survives vectorisation and never depends on -ffinite-math-only.
template <typename T> HBRDF_INLINE constexpr bool is_finite(T x) {
    return (x < T(0) ? -x : x) <= std::numeric_limits<T>::max();
}

template <typename T> HBRDF_INLINE constexpr T dot(const Vec3<T>& a, const Vec3<T>& b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

template <typename T> HBRDF_INLINE constexpr T mean(const Vec3<T>& v) { return (v.x + v.y + v.z) * T(1.0 / 3.0); }

// Directions are accepted at any non-zero, finite length and normalised,
// because a BRDF is a function of directions, not vectors.
//
// Returns 1/|v|, or 0 when v cannot be normalised: zero length, a squared
// length that under- or overflows T, or NaN/Inf components. A scale rather
// than a struct {w, valid} so that it stays in registers in vectorised loops.
template <typename T> HBRDF_INLINE T inverse_length_or_zero(const Vec3<T>& v) {
    const T len2 = dot(v, v);
    // len2 >= min normal: below it 1/sqrt(len2) loses precision or overflows.
    const bool ok = len2 >= std::numeric_limits<T>::min() && len2 <= std::numeric_limits<T>::max();
    const T inv_len = T(1) / std::sqrt(ok ? len2 : T(1));
    return ok ? inv_len : T(0);
}

}  // namespace hbrdf
