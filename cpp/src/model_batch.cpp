// hybridbrdf — vectorised batched inference of fitted models.
//
// Pairs are processed in chunks of kChunk in structure-of-arrays layout. A
// layer is out[j][i] = b[j] + sum_k W[j][k] in[k][i]: the weight is broadcast
// and the loop over the pairs i is a straight FMA stream the compiler
// vectorises. The body is written once and instantiated for the baseline
// target and for AVX2+FMA (chosen at run time, as in batch.cpp).
#include <algorithm>
#include <cmath>
#include <vector>

#include "hybridbrdf/model.hpp"

#if defined(__GNUC__)
#define HBRDF_KERNEL_INLINE inline __attribute__((always_inline))
#else
#define HBRDF_KERNEL_INLINE inline
#endif
#if (defined(__x86_64__) || defined(__i386__)) && defined(__GNUC__)
#define HBRDF_MB_AVX2 1
#else
#define HBRDF_MB_AVX2 0
#endif

namespace hbrdf {

namespace {
constexpr int kChunk = 64;

HBRDF_KERNEL_INLINE float act(Activation a, float x) {
    return a == Activation::Relu ? (x > 0.f ? x : 0.f) : x * clamp_nan_lo((x + 1.5f) * (1.0f / 3.0f), 0.0f, 1.0f);
}

// out[j][0..kChunk) = bias[j] + W (rows of n_in) * in; then the activation unless `last`.
HBRDF_KERNEL_INLINE void dense(const float* __restrict w, const float* __restrict bias, int n_in, int n_out,
                               const float* __restrict in, float* __restrict out, Activation a, bool last) {
    for (int j = 0; j < n_out; ++j) {
        float acc[kChunk];
        for (int i = 0; i < kChunk; ++i) acc[i] = bias[j];
        for (int k = 0; k < n_in; ++k) {
            const float wk = w[j * n_in + k];
            const float* x = in + k * kChunk;
            for (int i = 0; i < kChunk; ++i) acc[i] += wk * x[i];
        }
        float* o = out + j * kChunk;
        if (last)
            for (int i = 0; i < kChunk; ++i) o[i] = acc[i];
        else if (a == Activation::Relu)
            for (int i = 0; i < kChunk; ++i) o[i] = acc[i] > 0.f ? acc[i] : 0.f;
        else
            for (int i = 0; i < kChunk; ++i) o[i] = act(Activation::HardGelu, acc[i]);
    }
}

HBRDF_KERNEL_INLINE float exp_clamped(float x) { return std::exp(x < kPreExpMax ? x : kPreExpMax); }

}  // namespace

struct ModelBatchKernels {
    HBRDF_KERNEL_INLINE static void run(const HybridModel& md, int m, std::size_t n, const float* wi_aos,
                                        const float* wo_aos, float* f_aos) {
        const int width = md.width_;
        const int n_dir = md.n_dir_inputs_;
        const ModelKind kind = md.kind_;
        const Activation a = md.activation_;
        std::vector<float> scratch(static_cast<std::size_t>(kChunk) * (n_dir + 2 * width + 6 + 9 + 1));
        float* X = scratch.data();          // n_dir rows
        float* A = X + n_dir * kChunk;      // width rows
        float* B = A + width * kChunk;      // width rows
        float* O = B + width * kChunk;      // 6 rows
        float* D = O + 6 * kChunk;          // wi (3 rows), wo (3 rows), f_a (3 rows)
        float* V = D + 9 * kChunk;          // valid (1 row)
        const std::vector<float>& bias0 = md.bias0_[m];
        const AnalyticBrdf* brdf = kind == ModelKind::Neural ? nullptr : &md.analytic_[m];
        const float* frames = kind == ModelKind::Neural ? md.frame_cache_[m].data() : nullptr;

        for (std::size_t start = 0; start < n; start += kChunk) {
            const int cnt = int(std::min<std::size_t>(kChunk, n - start));
            // Directions, normalised, in SoA; padding lanes get +z (valid, then dropped).
            for (int i = 0; i < kChunk; ++i) {
                const bool in = i < cnt;
                const std::size_t r = 3 * (start + (in ? i : 0));
                Vec3<float> wi = in ? Vec3<float>(wi_aos[r], wi_aos[r + 1], wi_aos[r + 2]) : Vec3<float>(0, 0, 1);
                Vec3<float> wo = in ? Vec3<float>(wo_aos[r], wo_aos[r + 1], wo_aos[r + 2]) : Vec3<float>(0, 0, 1);
                wi = wi * inverse_length_or_zero(wi);
                wo = wo * inverse_length_or_zero(wo);
                V[i] = (wi.z > 0.f && wo.z > 0.f) ? 1.f : 0.f;
                for (int c = 0; c < 3; ++c) {
                    D[c * kChunk + i] = wi[c];
                    D[(3 + c) * kChunk + i] = wo[c];
                }
            }
            if (brdf) {
                for (int i = 0; i < kChunk; ++i) {
                    const Vec3<float> fa =
                        brdf->eval(Vec3<float>(D[i], D[kChunk + i], D[2 * kChunk + i]),
                                   Vec3<float>(D[3 * kChunk + i], D[4 * kChunk + i], D[5 * kChunk + i]));
                    D[6 * kChunk + i] = fa.x;
                    D[7 * kChunk + i] = fa.y;
                    D[8 * kChunk + i] = fa.z;
                }
                std::copy(D, D + 6 * kChunk, X);
                if (kind == ModelKind::AnalyticInput)
                    for (int c = 0; c < 3; ++c)
                        for (int i = 0; i < kChunk; ++i) X[(6 + c) * kChunk + i] = std::log1p(D[(6 + c) * kChunk + i]);
            } else {
                // Neural: wi and wo in the material's 3 precomputed frames (t, b, n each).
                for (int side = 0; side < 2; ++side)
                    for (int fr = 0; fr < 3; ++fr)
                        for (int axis = 0; axis < 3; ++axis) {
                            const float* e = frames + 9 * fr + 3 * axis;
                            float* x = X + (9 * side + 3 * fr + axis) * kChunk;
                            const float* w = D + 3 * side * kChunk;
                            for (int i = 0; i < kChunk; ++i)
                                x[i] = e[0] * w[i] + e[1] * w[kChunk + i] + e[2] * w[2 * kChunk + i];
                        }
            }
            // The network: first layer from the varying inputs with the folded bias, then the rest.
            dense(md.w0_dirs_.data(), bias0.data(), n_dir, width, X, A, a, false);
            const std::size_t n_layers = md.layers_.size();
            for (std::size_t l = 1; l < n_layers; ++l) {
                const DenseLayer& L = md.layers_[l];
                const bool last = l + 1 == n_layers;
                dense(L.weight.data(), L.bias.data(), L.n_in, L.n_out, A, last ? O : B, a, last);
                if (!last) std::swap(A, B);
            }
            for (int i = 0; i < cnt; ++i) {
                float out[3];
                for (int c = 0; c < 3; ++c) {
                    const float o = O[c * kChunk + i];
                    const float fa = D[(6 + c) * kChunk + i];
                    switch (kind) {
                        case ModelKind::Neural: out[c] = exp_clamped(o); break;
                        case ModelKind::Additive: out[c] = max0(fa + o); break;
                        case ModelKind::LogMul: out[c] = fa * exp_clamped(o); break;
                        default: out[c] = exp_clamped(o) + fa / (1.0f + std::exp(-O[(3 + c) * kChunk + i])); break;
                    }
                    f_aos[3 * (start + i) + c] = V[i] > 0.f ? out[c] : 0.f;
                }
            }
        }
    }
};

namespace {
void run_baseline(const HybridModel& md, int m, std::size_t n, const float* wi, const float* wo, float* f) {
    ModelBatchKernels::run(md, m, n, wi, wo, f);
}
#if HBRDF_MB_AVX2
__attribute__((target("avx2,fma"))) void run_avx2(const HybridModel& md, int m, std::size_t n, const float* wi,
                                                  const float* wo, float* f) {
    ModelBatchKernels::run(md, m, n, wi, wo, f);
}
#endif
}  // namespace

void HybridModel::eval_batch(int m, std::size_t n, const float* wi, const float* wo, float* f) const {
    check_material(m);
#if HBRDF_MB_AVX2
    if (std::string(simd_path()) == "avx2+fma") return run_avx2(*this, m, n, wi, wo, f);
#endif
    run_baseline(*this, m, n, wi, wo, f);
}

}  // namespace hbrdf
