// hybridbrdf — vectorised batched inference of fitted models.
//
// Pairs are processed in chunks of kChunk in structure-of-arrays layout. A
// layer is out[j][i] = b[j] + sum_k W[j][k] in[k][i]: the weight is broadcast
// and the loop over the pairs i is a straight FMA stream. The portable kernel
// is written once and compiled for the baseline target and for AVX2+FMA; on
// x86 the layers themselves use register-blocked intrinsics (AVX2: 2 outputs x
// 32 pairs, AVX-512: 4 outputs x 64 pairs in accumulators), which load each
// input vector once per block of outputs instead of once per output: the
// portable loop does one load per FMA.
// The kernel is chosen at run time (model_simd_path()).
#include <algorithm>
#include <atomic>
#include <cmath>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "hybridbrdf/batch.hpp"
#include "hybridbrdf/model.hpp"
#include "model_math.hpp"

#if defined(__GNUC__)
#define HBRDF_KERNEL_INLINE inline __attribute__((always_inline))
#else
#define HBRDF_KERNEL_INLINE inline
#endif
#if (defined(__x86_64__) || defined(__i386__)) && defined(__GNUC__)
#define HBRDF_MB_X86 1
#include <immintrin.h>
#else
#define HBRDF_MB_X86 0
#endif

namespace hbrdf {

namespace {
constexpr int kChunk = 64;

using detail::activate;

// out[j][0..kChunk) = bias[j] + W (rows of n_in) * in; then the activation unless `last`.
struct DensePortable {
    HBRDF_KERNEL_INLINE static void run(const float* __restrict w, const float* __restrict bias, int n_in, int n_out,
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
                for (int i = 0; i < kChunk; ++i) o[i] = activate(Activation::HardGelu, acc[i]);
        }
    }
};

#if HBRDF_MB_X86
// GCC 12's own AVX-512 intrinsics (_mm512_undefined_ps) trip -Wmaybe-uninitialized when
// inlined (GCC bug 105593, fixed in GCC 13); the warning is about the header, not this code.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
// The activations on 8 / 16 lanes; max(x, 0) returns 0 for NaN like clamp_nan_lo.
#define HBRDF_ACT_BODY(PS, SET1, MAX, MIN, MUL, FMA)                                            \
    if (last) return x;                                                                   \
    if (a == Activation::Relu) return MAX(x, SET1(0.0f));                                \
    /* hardGeLU, detail::activate: (x + knee) / (2 knee) = x / (2 knee) + 1/2 */          \
    const auto t = FMA(x, SET1(float(1.0 / (2.0 * spec::kHardgeluKnee))), SET1(0.5f));   \
    return MUL(x, MIN(MAX(t, SET1(0.0f)), SET1(1.0f)));

__attribute__((target("avx2,fma"))) HBRDF_KERNEL_INLINE __m256 act8(__m256 x, Activation a, bool last) {
    HBRDF_ACT_BODY(ps, _mm256_set1_ps, _mm256_max_ps, _mm256_min_ps, _mm256_mul_ps, _mm256_fmadd_ps)
}

struct DenseAvx2 {
    // Blocks of 2 outputs x 32 pairs: 8 accumulators + 4 inputs + 2 weights of 16 registers.
    // Not force-inlined: it is called from the target-neutral ModelBatchKernels::run.
    __attribute__((target("avx2,fma"))) static void run(
        const float* __restrict w, const float* __restrict bias, int n_in, int n_out, const float* __restrict in,
        float* __restrict out, Activation a, bool last) {
        constexpr int J = 2, V = 4;  // outputs per block, 8-lane vectors per half chunk
        int j = 0;
        for (; j + J <= n_out; j += J)
            for (int half = 0; half < kChunk; half += 8 * V) {
                __m256 acc[J][V];
                for (int r = 0; r < J; ++r)
                    for (int v = 0; v < V; ++v) acc[r][v] = _mm256_set1_ps(bias[j + r]);
                for (int k = 0; k < n_in; ++k) {
                    const float* x = in + k * kChunk + half;
                    __m256 xv[V];
                    for (int v = 0; v < V; ++v) xv[v] = _mm256_loadu_ps(x + 8 * v);
                    for (int r = 0; r < J; ++r) {
                        const __m256 wr = _mm256_set1_ps(w[(j + r) * n_in + k]);
                        for (int v = 0; v < V; ++v) acc[r][v] = _mm256_fmadd_ps(wr, xv[v], acc[r][v]);
                    }
                }
                for (int r = 0; r < J; ++r)
                    for (int v = 0; v < V; ++v)
                        _mm256_storeu_ps(out + (j + r) * kChunk + half + 8 * v, act8(acc[r][v], a, last));
            }
        if (j < n_out) DensePortable::run(w + j * n_in, bias + j, n_in, n_out - j, in, out + j * kChunk, a, last);
    }
};

__attribute__((target("avx512f,avx2,fma"))) HBRDF_KERNEL_INLINE __m512 act16(__m512 x, Activation a, bool last) {
    HBRDF_ACT_BODY(ps, _mm512_set1_ps, _mm512_max_ps, _mm512_min_ps, _mm512_mul_ps, _mm512_fmadd_ps)
}

struct DenseAvx512 {
    // Blocks of 4 outputs x 64 pairs: 16 accumulators + 4 inputs + 1 weight of 32 registers.
    __attribute__((target("avx512f,avx2,fma"))) static void run(
        const float* __restrict w, const float* __restrict bias, int n_in, int n_out, const float* __restrict in,
        float* __restrict out, Activation a, bool last) {
        constexpr int J = 4, V = kChunk / 16;
        int j = 0;
        for (; j + J <= n_out; j += J) {
            __m512 acc[J][V];
            for (int r = 0; r < J; ++r)
                for (int v = 0; v < V; ++v) acc[r][v] = _mm512_set1_ps(bias[j + r]);
            for (int k = 0; k < n_in; ++k) {
                const float* x = in + k * kChunk;
                __m512 xv[V];
                for (int v = 0; v < V; ++v) xv[v] = _mm512_loadu_ps(x + 16 * v);
                for (int r = 0; r < J; ++r) {
                    const __m512 wr = _mm512_set1_ps(w[(j + r) * n_in + k]);
                    for (int v = 0; v < V; ++v) acc[r][v] = _mm512_fmadd_ps(wr, xv[v], acc[r][v]);
                }
            }
            for (int r = 0; r < J; ++r)
                for (int v = 0; v < V; ++v) _mm512_storeu_ps(out + (j + r) * kChunk + 16 * v, act16(acc[r][v], a, last));
        }
        if (j < n_out) DenseAvx2::run(w + j * n_in, bias + j, n_in, n_out - j, in, out + j * kChunk, a, last);
    }
};
#undef HBRDF_ACT_BODY
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#endif

}  // namespace

struct ModelBatchKernels {
    template <class Dense>
    HBRDF_KERNEL_INLINE static void run(const HybridModel& md, int m, std::size_t n, const float* wi_aos,
                                        const float* wo_aos, float* f_aos) {
        const int width = md.width_;
        const int n_dir = md.n_dir_inputs_;
        const spec::ArchSpec& as = md.arch();
        const Activation a = md.activation_;
        std::vector<float> scratch(static_cast<std::size_t>(kChunk) * (n_dir + 2 * width + 6 + 9 + 1));
        float* X = scratch.data();          // n_dir rows
        float* A = X + n_dir * kChunk;      // width rows
        float* B = A + width * kChunk;      // width rows
        float* O = B + width * kChunk;      // 6 rows
        float* D = O + 6 * kChunk;          // wi (3 rows), wo (3 rows), f_a (3 rows)
        float* V = D + 9 * kChunk;          // valid (1 row)
        const std::vector<float>& bias0 = md.bias0_[m];
        const float bound = md.pre_exp_max_;
        const AnalyticBrdf* brdf = as.analytic ? &md.analytic_[m] : nullptr;
        const float* frames = as.directions == spec::DirectionInputs::Frames ? md.frame_cache_[m].data() : nullptr;

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
                if (as.extra == spec::ExtraInputs::Log1pFa)
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
            Dense::run(md.w0_dirs_.data(), bias0.data(), n_dir, width, X, A, a, false);
            const std::size_t n_layers = md.layers_.size();
            for (std::size_t l = 1; l < n_layers; ++l) {
                const DenseLayer& L = md.layers_[l];
                const bool last = l + 1 == n_layers;
                Dense::run(L.weight.data(), L.bias.data(), L.n_in, L.n_out, A, last ? O : B, a, last);
                if (!last) std::swap(A, B);
            }
            const spec::Combine rule = as.combine;
            const bool gated = as.n_out == 6;
            for (int i = 0; i < cnt; ++i)
                for (int c = 0; c < 3; ++c) {
                    const float f = detail::combine(rule, O[c * kChunk + i], gated ? O[(3 + c) * kChunk + i] : 0.f,
                                                    D[(6 + c) * kChunk + i], bound);
                    f_aos[3 * (start + i) + c] = V[i] > 0.f ? f : 0.f;
                }
        }
    }
};

namespace {
void run_baseline(const HybridModel& md, int m, std::size_t n, const float* wi, const float* wo, float* f) {
    ModelBatchKernels::run<DensePortable>(md, m, n, wi, wo, f);
}
#if HBRDF_MB_X86
__attribute__((target("avx2,fma"))) void run_avx2(const HybridModel& md, int m, std::size_t n, const float* wi,
                                                  const float* wo, float* f) {
    ModelBatchKernels::run<DenseAvx2>(md, m, n, wi, wo, f);
}
__attribute__((target("avx512f,avx2,fma"))) void run_avx512(const HybridModel& md, int m, std::size_t n,
                                                            const float* wi, const float* wo, float* f) {
    ModelBatchKernels::run<DenseAvx512>(md, m, n, wi, wo, f);
}
bool cpu_has_avx512() {
    static const bool has = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx2") &&
                            __builtin_cpu_supports("fma");
    return has;
}
#endif
}  // namespace

namespace {
std::atomic<int> g_model_simd_limit{2};  // 0 baseline, 1 avx2+fma, 2 avx512 (the best the CPU has)
}

namespace {
// 2 avx512, 1 avx2+fma, 0 baseline: the best kernel the CPU runs, capped by the limit.
int model_kernel_level() {
    int level = 0;
#if HBRDF_MB_X86
    if (std::string_view(simd_path()) == "avx2+fma") level = cpu_has_avx512() ? 2 : 1;  // "baseline" when forced
#endif
    return std::min(level, g_model_simd_limit.load(std::memory_order_relaxed));
}
}  // namespace

const char* model_simd_path() {
    static const char* const kNames[] = {"baseline", "avx2+fma", "avx512"};
    return kNames[model_kernel_level()];
}

void limit_model_simd(const std::string& path) {
    if (path == "avx512")
        g_model_simd_limit.store(2);
    else if (path == "avx2+fma")
        g_model_simd_limit.store(1);
    else if (path == "baseline")
        g_model_simd_limit.store(0);
    else
        throw std::invalid_argument("limit_model_simd: expected avx512, avx2+fma or baseline, got '" + path + "'");
}

void HybridModel::eval_batch(int m, std::size_t n, const float* wi, const float* wo, float* f) const {
    check_material(m);
#if HBRDF_MB_X86
    switch (model_kernel_level()) {
        case 2: return run_avx512(*this, m, n, wi, wo, f);
        case 1: return run_avx2(*this, m, n, wi, wo, f);
        default: break;
    }
#endif
    run_baseline(*this, m, n, wi, wo, f);
}

}  // namespace hbrdf
