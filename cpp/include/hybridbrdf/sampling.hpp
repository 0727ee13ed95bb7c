// hybridbrdf — importance sampling of the analytic component f_a.
//
// Three strategies, each with a pdf() consistent with its sampler:
//   Cosine  cosine-weighted hemisphere (Malley),                 pdf = wi.z / pi
//   Ggx     GGX visible normals (Dupuy & Benyoub 2023), reflected, pdf = G1(wo) D(h) / (4 wo.z)
//   Mis     one-sample mixture of the two (the paper's Sec. 5.2 sampler for
//           the hybrid model): pdf = P_ggx pdf_ggx + (1 - P_ggx) pdf_cos
//
// Densities are per unit solid angle over the whole sphere: the GGX sampler
// can produce directions below the horizon (the VNDF's leakage); those are
// returned with their pdf and weight 0, and pdf() integrates to 1 over the
// sphere for every strategy.
#pragma once

#include <cstddef>
#include <cstdint>
#include <iterator>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "hybridbrdf/analytic.hpp"
#include "hybridbrdf/warp.hpp"

namespace hbrdf {

enum class Strategy : std::uint8_t { Cosine = 0, Ggx = 1, Mis = 2 };

/// Every strategy, in enum order: the one list that parsers, error messages,
/// the bindings (hybridbrdf.STRATEGIES) and the renderer's samplers build on.
inline constexpr Strategy kStrategies[] = {Strategy::Cosine, Strategy::Ggx, Strategy::Mis};

/// The strategy's name in scene files, the Python API and the command line:
/// "cosine", "ggx" or "mis".
constexpr const char* strategy_name(Strategy s) {
    switch (s) {
        case Strategy::Cosine: return "cosine";
        case Strategy::Ggx: return "ggx";
        default: return "mis";
    }
}

/// The strategy called `name`; nullopt for any other name.
inline std::optional<Strategy> find_strategy(std::string_view name) {
    for (Strategy s : kStrategies)
        if (name == strategy_name(s)) return s;
    return std::nullopt;
}

/// Like find_strategy(), but an unknown name throws std::invalid_argument
/// "unknown sampling strategy 'x'; expected cosine, ggx or mis".
inline Strategy parse_strategy(std::string_view name) {
    if (const std::optional<Strategy> s = find_strategy(name)) return *s;
    std::string expected;
    const std::size_t n = std::size(kStrategies);
    for (std::size_t i = 0; i < n; ++i)
        expected += std::string(i == 0 ? "" : i + 1 == n ? " or " : ", ") + strategy_name(kStrategies[i]);
    throw std::invalid_argument("unknown sampling strategy '" + std::string(name) + "'; expected " + expected);
}

/// A sampled direction. pdf == 0 means "no sample" (wo below the horizon or
/// invalid); then wi = +z and weight = 0.
template <typename T> struct BrdfSampleT {
    Vec3<T> wi;      ///< sampled direction toward the light (unit)
    T pdf;           ///< solid-angle density of wi
    Vec3<T> weight;  ///< f(wi, wo) * max(wi.z, 0) / pdf, 0 when pdf == 0
};
using BrdfSample = BrdfSampleT<float>;

/// Neither lobe of the MIS mixture is ever picked with a probability below
/// this (spec/model.json, mis_min_lobe_probability): the hybrid model's
/// additive correction f_c can put energy anywhere, so both lobes must keep
/// covering the hemisphere.
inline constexpr double kMisMinLobeProbability = spec::kMisMinLobeProbability;

/// Probability with which the Mis strategy samples the GGX lobe for viewing
/// direction wo (unit, wo.z > 0):
///
///     P_ggx = clamp(Fs / (Fs + Kd), p_min, 1 - p_min),  Fs = mean_rgb F(wo.z, eta),  Kd = mean_rgb kd
///
/// Fs is the Fresnel reflectance at the viewing angle, a cheap stand-in for
/// the specular albedo; Kd is the diffuse albedo. A function of wo only, so
/// pdf() can recompute it for any wi.
template <typename T> HBRDF_INLINE T ggx_lobe_probability(const AnalyticBrdfT<T>& brdf, const Vec3<T>& wo) {
    const Vec3<T>& e = brdf.eta2_minus_1();
    const T fs = (fresnel_dielectric(wo.z, e.x) + fresnel_dielectric(wo.z, e.y) + fresnel_dielectric(wo.z, e.z)) *
                 T(1.0 / 3.0);
    const T kd = mean(brdf.params().kd);
    const T p = fs + kd > T(0) ? fs / (fs + kd) : T(0.5);
    return clamp_nan_lo(p, T(kMisMinLobeProbability), T(1.0 - kMisMinLobeProbability));
}

/// Density with which strategy S samples wi given wo, over the sphere.
/// Directions are normalised; 0 for invalid directions or wo.z <= 0.
template <Strategy S, typename T>
HBRDF_INLINE T pdf(const AnalyticBrdfT<T>& brdf, const Vec3<T>& wi_in, const Vec3<T>& wo_in) {
    const T inv_len_i = inverse_length_or_zero(wi_in);
    const Vec3<T> wi = wi_in * inv_len_i;
    const Vec3<T> wo = wo_in * inverse_length_or_zero(wo_in);
    T p;
    if constexpr (S == Strategy::Cosine) {
        p = square_to_cosine_hemisphere_pdf(wi);
    } else if constexpr (S == Strategy::Ggx) {
        p = pdf_ggx_vndf(wi, wo, brdf.alpha());
    } else {
        const T p_ggx = ggx_lobe_probability(brdf, wo);
        p = p_ggx * pdf_ggx_vndf(wi, wo, brdf.alpha()) + (T(1) - p_ggx) * square_to_cosine_hemisphere_pdf(wi);
    }
    // wi valid and wo above the horizon ("z > 0" is false for NaN). Two selects, not one
    // select on an "&&": GCC 12 cannot vectorise that select in the batched pdf and sampling
    // kernels (src/batch.cpp) once the pdf's own selects are inlined beside it.
    p = inv_len_i > T(0) ? p : T(0);
    return wo.z > T(0) ? p : T(0);
}

/// Runtime-dispatched pdf().
template <typename T>
HBRDF_INLINE T pdf(Strategy s, const AnalyticBrdfT<T>& brdf, const Vec3<T>& wi, const Vec3<T>& wo) {
    switch (s) {
        case Strategy::Cosine: return pdf<Strategy::Cosine>(brdf, wi, wo);
        case Strategy::Ggx: return pdf<Strategy::Ggx>(brdf, wi, wo);
        default: return pdf<Strategy::Mis>(brdf, wi, wo);
    }
}

/// Samples wi for viewing direction wo with strategy S from u in [0, 1)^2
/// (clamped into it; NaN -> 0). Mis picks its lobe with u.x and rescales u.x
/// to [0, 1) for the chosen warp, so two numbers suffice.
template <Strategy S, typename T>
HBRDF_INLINE BrdfSampleT<T> sample(const AnalyticBrdfT<T>& brdf, const Vec3<T>& wo_in, const Vec2<T>& u_in) {
    const T inv_len_o = inverse_length_or_zero(wo_in);
    const bool valid = wo_in.z * inv_len_o > T(0);  // false for NaN
    // An invalid wo is replaced by +z so that the warps below stay finite.
    const Vec3<T> wo = valid ? wo_in * inv_len_o : Vec3<T>(T(0), T(0), T(1));
    Vec2<T> u = clamp_unit_square(u_in);

    bool use_ggx = S == Strategy::Ggx;
    if constexpr (S == Strategy::Mis) {
        const T p_ggx = ggx_lobe_probability(brdf, wo);
        use_ggx = u.x < p_ggx;
        u.x = use_ggx ? u.x / p_ggx : (u.x - p_ggx) / (T(1) - p_ggx);
        u.x = clamp_nan_lo(u.x, T(0), kOneMinusEps<T>);
    }
    Vec3<T> wi;
    if (use_ggx) {
        const Vec3<T> h = sample_ggx_vndf(wo, u, brdf.alpha());
        wi = T(2) * dot(wo, h) * h - wo;
    } else {
        wi = square_to_cosine_hemisphere(u);
    }

    BrdfSampleT<T> s;
    s.pdf = pdf<S>(brdf, wi, wo);
    const T cos_i = max0(wi.z);
    const bool ok = valid && s.pdf > T(0);
    s.wi = ok ? wi : Vec3<T>(T(0), T(0), T(1));
    s.weight = ok ? brdf.eval(wi, wo) * (cos_i / s.pdf) : Vec3<T>(T(0));
    s.pdf = ok ? s.pdf : T(0);
    return s;
}

/// Runtime-dispatched sample().
template <typename T>
HBRDF_INLINE BrdfSampleT<T> sample(Strategy s, const AnalyticBrdfT<T>& brdf, const Vec3<T>& wo, const Vec2<T>& u) {
    switch (s) {
        case Strategy::Cosine: return sample<Strategy::Cosine>(brdf, wo, u);
        case Strategy::Ggx: return sample<Strategy::Ggx>(brdf, wo, u);
        default: return sample<Strategy::Mis>(brdf, wo, u);
    }
}

}  // namespace hbrdf
