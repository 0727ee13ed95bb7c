// hybridbrdf — MERL-style table lookup and NBRDF networks (hybridbrdf/baselines.hpp).
//
// Both run in chunks of pairs in SoA layout: the half/difference vectors first
// (one branch-free loop), then the lookup or the network. The kernel bodies are
// force-inlined templates compiled for the baseline target and for AVX2+FMA and
// picked at run time like batch.cpp's (simd_path()), so the cost table compares
// them with the hybrid model on the same instruction set.
#include "hybridbrdf/baselines.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <string_view>

#include "hybridbrdf/batch.hpp"
#include "hybridbrdf/math.hpp"

#if defined(__GNUC__)
#define HBRDF_BL_INLINE inline __attribute__((always_inline))
#else
#define HBRDF_BL_INLINE inline
#endif
#if (defined(__x86_64__) || defined(__i386__)) && defined(__GNUC__)
#define HBRDF_BL_AVX2 1
#else
#define HBRDF_BL_AVX2 0
#endif

namespace hbrdf {
namespace {

constexpr int kBaselineChunk = 64;

/// Rusinkiewicz's half vector h and difference vector d (wi rotated by -phi_h
/// about z, then by -theta_h about y) of one pair, with cos/sin of the angles
/// taken from h itself (hybridbrdf/sources/rusinkiewicz.py). `valid` is false
/// for a pair the BRDF is 0 at.
HBRDF_BL_INLINE void half_diff(Vec3<float> wi, Vec3<float> wo, Vec3<float>& h, Vec3<float>& d, bool& valid) {
    wi = wi * inverse_length_or_zero(wi);
    wo = wo * inverse_length_or_zero(wo);
    valid = wi.z > 0.f && wo.z > 0.f;
    const Vec3<float> s = wi + wo;
    const float inv = 1.0f / std::sqrt(std::max(dot(s, s), 1e-30f));
    h = s * inv;
    const float sin_th = std::sqrt(h.x * h.x + h.y * h.y), cos_th = h.z;
    const bool on_axis = !(sin_th > 0.f);
    const float cos_ph = on_axis ? 1.f : h.x / sin_th, sin_ph = on_axis ? 0.f : h.y / sin_th;
    const float x1 = cos_ph * wi.x + sin_ph * wi.y, y1 = -sin_ph * wi.x + cos_ph * wi.y, z1 = wi.z;
    d = Vec3<float>(x1 * cos_th - z1 * sin_th, y1, x1 * sin_th + z1 * cos_th);
}

HBRDF_BL_INLINE int clamp_index(float x, int n) {
    // Truncation toward zero, as BRDFRead.cpp's int() casts; NaN and negatives go to 0.
    return x >= 1.0f ? std::min(int(x), n - 1) : 0;
}

HBRDF_BL_INLINE void merl_body(const float* table, std::size_t n, const float* wi, const float* wo, float* f) {
    constexpr float kHalfPi = 1.57079632679f, kPiF = 3.14159265359f;
    for (std::size_t i = 0; i < n; ++i) {
        Vec3<float> h, d;
        bool valid;
        half_diff(Vec3<float>(wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]),
                  Vec3<float>(wo[3 * i], wo[3 * i + 1], wo[3 * i + 2]), h, d, valid);
        const float theta_h = std::atan2(std::sqrt(h.x * h.x + h.y * h.y), h.z);
        const float theta_d = std::atan2(std::sqrt(d.x * d.x + d.y * d.y), d.z);
        float phi_d = std::atan2(d.y, d.x);
        phi_d = phi_d < 0.f ? phi_d + kPiF : phi_d;  // reciprocity: phi_d and phi_d + pi are one cell
        const int a = clamp_index(std::sqrt(std::max(theta_h, 0.f) / kHalfPi) * kMerlThetaH, kMerlThetaH);
        const int b = clamp_index(theta_d / kHalfPi * kMerlThetaD, kMerlThetaD);
        const int c = clamp_index(phi_d / kPiF * kMerlPhiD, kMerlPhiD);
        const float* cell = table + 3 * ((std::size_t(a) * kMerlThetaD + b) * kMerlPhiD + c);
        for (int k = 0; k < 3; ++k) f[3 * i + k] = valid ? cell[k] : 0.f;
    }
}

HBRDF_BL_INLINE void nbrdf_body(const std::vector<NbrdfNetwork::Layer>& layers, int max_width, std::size_t n,
                                const float* wi, const float* wo, float* f) {
    std::vector<float> buf(std::size_t(2) * max_width * kBaselineChunk);
    float valid[kBaselineChunk];
    for (std::size_t start = 0; start < n; start += kBaselineChunk) {
        const int cnt = int(std::min<std::size_t>(kBaselineChunk, n - start));
        float* x = buf.data();
        float* y = x + std::size_t(max_width) * kBaselineChunk;
        for (int i = 0; i < kBaselineChunk; ++i) {
            const std::size_t r = 3 * (start + std::size_t(i < cnt ? i : 0));
            Vec3<float> h, d;
            bool ok;
            half_diff(Vec3<float>(wi[r], wi[r + 1], wi[r + 2]), Vec3<float>(wo[r], wo[r + 1], wo[r + 2]), h, d, ok);
            valid[i] = ok ? 1.f : 0.f;
            x[i] = std::sqrt(h.x * h.x + h.y * h.y);  // sin theta_h (phi_h set to 0)
            x[kBaselineChunk + i] = 0.f;
            x[2 * kBaselineChunk + i] = h.z;
            x[3 * kBaselineChunk + i] = d.x, x[4 * kBaselineChunk + i] = d.y, x[5 * kBaselineChunk + i] = d.z;
        }
        for (std::size_t l = 0; l < layers.size(); ++l) {
            const NbrdfNetwork::Layer& L = layers[l];
            const bool last = l + 1 == layers.size();
            for (int j = 0; j < L.n_out; ++j) {
                float acc[kBaselineChunk];
                for (int i = 0; i < kBaselineChunk; ++i) acc[i] = L.bias[std::size_t(j)];
                for (int k = 0; k < L.n_in; ++k) {
                    const float w = L.weight[std::size_t(j) * L.n_in + k];
                    const float* xk = x + std::size_t(k) * kBaselineChunk;
                    for (int i = 0; i < kBaselineChunk; ++i) acc[i] += w * xk[i];
                }
                float* out = y + std::size_t(j) * kBaselineChunk;
                for (int i = 0; i < kBaselineChunk; ++i) out[i] = last ? acc[i] : std::max(acc[i], 0.f);
            }
            std::swap(x, y);
        }
        for (int i = 0; i < cnt; ++i)
            for (int k = 0; k < 3; ++k)
                f[3 * (start + i) + k] = valid[i] > 0.f ? std::max(std::expm1(x[std::size_t(k) * kBaselineChunk + i]), 0.f) : 0.f;
    }
}

void merl_baseline(const float* t, std::size_t n, const float* wi, const float* wo, float* f) {
    merl_body(t, n, wi, wo, f);
}
void nbrdf_baseline(const std::vector<NbrdfNetwork::Layer>& l, int w, std::size_t n, const float* wi, const float* wo,
                    float* f) {
    nbrdf_body(l, w, n, wi, wo, f);
}
#if HBRDF_BL_AVX2
__attribute__((target("avx2,fma"))) void merl_avx2(const float* t, std::size_t n, const float* wi, const float* wo,
                                                   float* f) {
    merl_body(t, n, wi, wo, f);
}
__attribute__((target("avx2,fma"))) void nbrdf_avx2(const std::vector<NbrdfNetwork::Layer>& l, int w, std::size_t n,
                                                    const float* wi, const float* wo, float* f) {
    nbrdf_body(l, w, n, wi, wo, f);
}
#endif
bool avx2() { return std::string_view(simd_path()) == "avx2+fma"; }

}  // namespace

MerlTable::MerlTable(std::vector<float> rgb) : rgb_(std::move(rgb)) {
    const std::size_t expected = std::size_t(3) * kMerlThetaH * kMerlThetaD * kMerlPhiD;
    if (rgb_.size() != expected)
        throw std::invalid_argument("MerlTable: expected " + std::to_string(expected) + " values (90 x 90 x 180 x RGB), got " +
                                    std::to_string(rgb_.size()));
}

void MerlTable::eval_batch(std::size_t n, const float* wi, const float* wo, float* f) const {
#if HBRDF_BL_AVX2
    if (avx2()) return merl_avx2(rgb_.data(), n, wi, wo, f);
#endif
    merl_baseline(rgb_.data(), n, wi, wo, f);
}

NbrdfNetwork::NbrdfNetwork(std::vector<Layer> layers) : layers_(std::move(layers)) {
    if (layers_.empty()) throw std::invalid_argument("NbrdfNetwork: no layers");
    int n_in = 6;
    for (std::size_t l = 0; l < layers_.size(); ++l) {
        const Layer& L = layers_[l];
        const std::string where = "NbrdfNetwork: layer " + std::to_string(l);
        if (L.n_in != n_in) throw std::invalid_argument(where + " takes " + std::to_string(L.n_in) + " inputs, expected " + std::to_string(n_in));
        if (L.n_out < 1 || L.weight.size() != std::size_t(L.n_in) * L.n_out || L.bias.size() != std::size_t(L.n_out))
            throw std::invalid_argument(where + ": weight or bias size does not match " + std::to_string(L.n_in) + " -> " + std::to_string(L.n_out));
        n_in = L.n_out;
        max_width_ = std::max(max_width_, L.n_out);
    }
    if (n_in != 3) throw std::invalid_argument("NbrdfNetwork: the last layer has " + std::to_string(n_in) + " outputs, expected 3");
    max_width_ = std::max(max_width_, 6);
}

void NbrdfNetwork::eval_batch(std::size_t n, const float* wi, const float* wo, float* f) const {
#if HBRDF_BL_AVX2
    if (avx2()) return nbrdf_avx2(layers_, max_width_, n, wi, wo, f);
#endif
    nbrdf_baseline(layers_, max_width_, n, wi, wo, f);
}

std::size_t NbrdfNetwork::memory_bytes() const {
    std::size_t b = 0;
    for (const Layer& L : layers_) b += (L.weight.size() + L.bias.size()) * sizeof(float);
    return b;
}

}  // namespace hbrdf
