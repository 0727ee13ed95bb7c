// hybridbrdf — parameters of the analytic component f_a (Lambert + anisotropic GGX).
//
// p = (kd, eta, alpha): kd in [0,1]^3, eta in [1,10]^3 (real IOR per RGB
// channel), alpha = (alpha_x, alpha_y) in [kAlphaMin, 1]^2, alpha_x along the
// tangent (+x). See docs/CONVENTIONS.md.
#pragma once

#include <stdexcept>
#include <string>

#include "hybridbrdf/math.hpp"
#include "hybridbrdf/spec.hpp"

namespace hbrdf {

// The ranges are part of the model contract (spec/model.json, docs there and in
// docs/CONVENTIONS.md); these names keep the library's spelling.
inline constexpr double kAlphaMin = spec::kAlphaMin;
inline constexpr double kAlphaMax = spec::kAlphaMax;
inline constexpr double kEtaMin = spec::kEtaMin;
inline constexpr double kEtaMax = spec::kEtaMax;
inline constexpr double kKdMin = spec::kKdMin;
inline constexpr double kKdMax = spec::kKdMax;

template <typename T> struct AnalyticParamsT {
    Vec3<T> kd{T(0.5)};    ///< Lambertian albedo per channel, [0, 1]
    Vec3<T> eta{T(1.5)};   ///< real index of refraction per channel, [1, 10]
    Vec2<T> alpha{T(0.3)}; ///< GGX roughness (alpha_x, alpha_y), [kAlphaMin, 1]

    bool isotropic() const { return alpha.x == alpha.y; }
};
using AnalyticParams = AnalyticParamsT<float>;

/// Every evaluation function accepts any parameters and clamps them into the
/// valid box first (NaN goes to the lower bound), so no input can make them
/// return NaN. Front ends that want an error instead call validate().
template <typename T> HBRDF_INLINE AnalyticParamsT<T> clamped(const AnalyticParamsT<T>& p) {
    AnalyticParamsT<T> q;
    for (int c = 0; c < 3; ++c) {
        q.kd[c] = clamp_nan_lo(p.kd[c], T(kKdMin), T(kKdMax));
        q.eta[c] = clamp_nan_lo(p.eta[c], T(kEtaMin), T(kEtaMax));
    }
    for (int c = 0; c < 2; ++c) q.alpha[c] = clamp_nan_lo(p.alpha[c], T(kAlphaMin), T(kAlphaMax));
    return q;
}

/// Throws std::invalid_argument naming the first parameter outside its range
/// (or NaN). The message is meant for people: "eta[1] = 0.5 is outside [1, 10]".
template <typename T> void validate(const AnalyticParamsT<T>& p) {
    auto check = [](const char* name, int c, T v, double lo, double hi) {
        if (!(v >= T(lo) && v <= T(hi)))  // written so that NaN fails
            throw std::invalid_argument(std::string(name) + "[" + std::to_string(c) + "] = " +
                                        std::to_string(double(v)) + " is outside [" + std::to_string(lo) +
                                        ", " + std::to_string(hi) + "]");
    };
    for (int c = 0; c < 3; ++c) check("kd", c, p.kd[c], kKdMin, kKdMax);
    for (int c = 0; c < 3; ++c) check("eta", c, p.eta[c], kEtaMin, kEtaMax);
    for (int c = 0; c < 2; ++c) check("alpha", c, p.alpha[c], kAlphaMin, kAlphaMax);
}

}  // namespace hbrdf
