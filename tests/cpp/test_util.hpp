// Shared helpers for the C++ tests: parameter corners, hand-built model files. (The hard directions
// live in test_hard_cases.cpp, their one reader: it alone pays for nlohmann's JSON parser.)
#pragma once

#include <cmath>
#include <fstream>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
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

/// The same parameters in another precision, each value rounded to U.
template <typename U, typename T> inline AnalyticParamsT<U> params_as(const AnalyticParamsT<T>& p) {
    return AnalyticParamsT<U>{Vec3<U>(p.kd), Vec3<U>(p.eta), Vec2<U>(p.alpha)};
}

/// n direction pairs given as AoS arrays (x, y, z per pair) in the layout of
/// eval_analytic_soa's inputs: planes wi.x, wi.y, wi.z, wo.x, wo.y, wo.z of n values each.
inline std::vector<float> pairs_to_soa(const std::vector<float>& wi, const std::vector<float>& wo) {
    const std::size_t n = wi.size() / 3;
    std::vector<float> soa(6 * n);
    for (std::size_t i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) {
            soa[c * n + i] = wi[3 * i + c];
            soa[(3 + c) * n + i] = wo[3 * i + c];
        }
    return soa;
}

/// eval_analytic_soa on pairs_to_soa's layout; f receives planes r, g, b of n values each.
inline void eval_analytic_soa_planes(const AnalyticParams& p, const std::vector<float>& soa, std::vector<float>& f) {
    const std::size_t n = soa.size() / 6;
    const float* s = soa.data();
    float* o = f.data();
    eval_analytic_soa(p, n, {s, s + n, s + 2 * n}, {s + 3 * n, s + 4 * n, s + 5 * n}, {o, o + n, o + 2 * n});
}

template <typename T> inline bool finite_nonneg(const Vec3<T>& v) {
    for (int c = 0; c < 3; ++c)
        if (!(std::isfinite(v[c]) && v[c] >= T(0))) return false;
    return true;
}

// ---- hand-built model files (test_model.cpp, test_svbrdf.cpp) ----

struct NamedTensor {
    std::string name;
    std::vector<int> shape;
    std::vector<float> data;
};

// Writes a safetensors file with the given tensors and hybridbrdf metadata.
inline std::string write_model(const std::string& file, const std::string& metadata_json,
                        const std::vector<NamedTensor>& tensors) {
    std::string header = "{\"__metadata__\":{\"hybridbrdf\":" + metadata_json + "}";
    std::size_t offset = 0;
    for (const auto& t : tensors) {
        header += ",\"" + t.name + "\":{\"dtype\":\"F32\",\"shape\":[";
        for (std::size_t i = 0; i < t.shape.size(); ++i) header += (i ? "," : "") + std::to_string(t.shape[i]);
        header += "],\"data_offsets\":[" + std::to_string(offset) + "," + std::to_string(offset + 4 * t.data.size()) + "]}";
        offset += 4 * t.data.size();
    }
    header += "}";
    const std::string path = std::string("hbrdf_test_") + file;
    std::ofstream out(path, std::ios::binary);
    const unsigned long long n = header.size();
    for (int i = 0; i < 8; ++i) out.put(static_cast<char>((n >> (8 * i)) & 0xff));
    out << header;
    for (const auto& t : tensors) out.write(reinterpret_cast<const char*>(t.data.data()), 4 * t.data.size());
    return path;
}

// JSON string literal of the metadata document (escaped for embedding as a string value).
inline std::string meta(const std::string& kind, int width, int latent, int n_in, int n_out, bool isotropic = true) {
    std::string doc = "{\"format_version\":1,\"conventions_version\":" + std::to_string(kConventionsVersion) +
                      ",\"library_version\":\"test\",\"arch\":{\"kind\":\"" + kind + "\",\"width\":" +
                      std::to_string(width) + ",\"depth\":1,\"activation\":\"relu\",\"latent\":" +
                      std::to_string(latent) + ",\"n_in\":" + std::to_string(n_in) + ",\"n_out\":" +
                      std::to_string(n_out) + "},\"materials\":[{\"name\":\"m\",\"origin\":\"test\",\"isotropic\":" +
                      (isotropic ? "true" : "false") + "}],\"training\":{}}";
    std::string escaped = "\"";
    for (char c : doc) escaped += (c == '"' ? std::string("\\\"") : std::string(1, c));
    return escaped + "\"";
}

inline std::vector<NamedTensor> zero_hybrid(int latent) {
    return {{"mlp.hidden.0.weight", {1, 6 + latent}, std::vector<float>(6 + latent, 0.f)},
            {"mlp.hidden.0.bias", {1}, {0.f}},
            {"mlp.out.weight", {6, 1}, std::vector<float>(6, 0.f)},
            {"mlp.out.bias", {6}, std::vector<float>(6, 0.f)},
            {"materials.kd", {1, 3}, {0.2f, 0.4f, 0.6f}},
            {"materials.eta", {1, 3}, {1.5f, 1.5f, 1.5f}},
            {"materials.alpha", {1, 2}, {0.3f, 0.3f}},
            {"materials.z", {1, latent}, std::vector<float>(latent, 0.f)}};
}


}  // namespace hbrdf::test
