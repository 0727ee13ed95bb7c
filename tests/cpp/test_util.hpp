// Shared helpers for the C++ tests: parameter corners and hard directions.
#pragma once

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "hybridbrdf/hybridbrdf.hpp"

namespace hbrdf::test {

template <typename T> inline Vec3<T> spherical(T theta, T phi) {
    return Vec3<T>(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
}

/// Parameter sets at the corners of the valid box plus typical ones.
template <typename T> inline std::vector<AnalyticParamsT<T>> param_corners() {
    std::vector<AnalyticParamsT<T>> out;
    const T alphas[] = {T(kAlphaMin), T(0.01), T(0.3), T(1)};
    const T etas[] = {T(1), T(1.5), T(10)};
    for (T ax : alphas)
        for (T ay : alphas)
            for (T eta : etas) {
                AnalyticParamsT<T> p;
                p.kd = Vec3<T>(T(0), T(0.5), T(1));
                p.eta = Vec3<T>(eta, T(1.33), eta);
                p.alpha = Vec2<T>(ax, ay);
                out.push_back(p);
            }
    return out;
}

/// The hard directions of the foundation issue: grazing (z = 0, 1e-8), the
/// normal, below the horizon, zero-length, NaN and Inf, huge and tiny lengths.
template <typename T> inline std::vector<Vec3<T>> hard_directions() {
    const T inf = std::numeric_limits<T>::infinity();
    const T nan = std::numeric_limits<T>::quiet_NaN();
    const T g = T(1e-8);
    const T s = std::sqrt(T(1) - g * g);
    return {
        {0, 0, 1},  {1, 0, 0},   {0, 1, 0},   {-1, 0, 0},  {s, 0, g},    {0, s, g},   {-s, 0, g},
        {s * T(0.6), s * T(0.8), g},          {0, 0, -1},  {0.6, 0, -0.8}, {0, 0, 0},   {nan, 0, 1},
        {0, nan, 1}, {0, 0, nan}, {inf, 0, 1}, {0, 0, inf}, {-inf, 0, 1}, {0.3, 0.4, std::sqrt(T(0.75))},
        {T(1e-30), 0, T(1e-30)}, {T(1e20), T(1e20), T(1e20)}, {0, 0, std::numeric_limits<T>::denorm_min()},
        {T(0.70710678), 0, T(0.70710678)},  {T(-0.70710678), 0, T(0.70710678)},
    };
}

template <typename T> inline bool finite_nonneg(const Vec3<T>& v) {
    for (int c = 0; c < 3; ++c)
        if (!(std::isfinite(v[c]) && v[c] >= T(0))) return false;
    return true;
}

}  // namespace hbrdf::test
