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
#include "simd_env.hpp"

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
                // vectorises: dense_portable (tests/python/test_vectorisation.py)
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

    // The gated combine (paper Eq. 1), lane by lane with the scalar path's math: rows of kChunk
    // values in, three rows of f out, 0 where the pair is invalid.
    HBRDF_KERNEL_INLINE static void combine_gated(const float* __restrict O, const float* __restrict fa,
                                                  const float* __restrict valid, float bound, float* __restrict f) {
        for (int c = 0; c < 3; ++c)
            for (int i = 0; i < kChunk; ++i) {
                const float v = detail::combine(spec::Combine::Gated, O[c * kChunk + i], O[(3 + c) * kChunk + i],
                                                fa[c * kChunk + i], bound);
                f[c * kChunk + i] = valid[i] > 0.f ? v : 0.f;
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

// exp(x) on 8 lanes for the combine step, within about 1 ulp of the exact value: Cody-Waite
// reduction x = n ln2 + r (ln2 split in a 9-bit head and a tail, so n * head is exact),
// Cephes' degree-6 polynomial for e^r on |r| <= ln2/2, and 2^n applied as two halves so that
// results in the denormal range (x down to -103.9) and the overflow to +inf (x > 88.72) come
// out as expf gives them. Inputs are finite (the loader bounds every network value).
__attribute__((target("avx2,fma"))) HBRDF_KERNEL_INLINE __m256 exp8(__m256 x) {
    x = _mm256_min_ps(_mm256_max_ps(x, _mm256_set1_ps(-104.0f)), _mm256_set1_ps(89.0f));
    const __m256 n = _mm256_round_ps(_mm256_mul_ps(x, _mm256_set1_ps(1.44269504f)),
                                     _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
    __m256 r = _mm256_fnmadd_ps(n, _mm256_set1_ps(0.693359375f), x);
    r = _mm256_fnmadd_ps(n, _mm256_set1_ps(-2.12194440e-4f), r);
    __m256 p = _mm256_set1_ps(1.9875691500e-4f);
    p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(1.3981999507e-3f));
    p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(8.3334519073e-3f));
    p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(4.1665795894e-2f));
    p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(1.6666665459e-1f));
    p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(5.0000001201e-1f));
    const __m256 y = _mm256_add_ps(_mm256_fmadd_ps(p, _mm256_mul_ps(r, r), r), _mm256_set1_ps(1.0f));
    const __m256i ni = _mm256_cvtps_epi32(n);
    const __m256i n1 = _mm256_srai_epi32(ni, 1);
    const __m256i n2 = _mm256_sub_epi32(ni, n1);
    const __m256i bias = _mm256_set1_epi32(127);
    const __m256 s1 = _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_add_epi32(n1, bias), 23));
    const __m256 s2 = _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_add_epi32(n2, bias), 23));
    return _mm256_mul_ps(_mm256_mul_ps(y, s1), s2);
}

// J output rows x 16 pairs (two 8-lane vectors) per register block, for every 16 pairs of the
// chunk: 2J accumulators + 2 inputs + 1 broadcast weight of the 16 ymm registers (J = 6 uses
// 15). Per input k: 2 vector loads and J broadcasts feed 2J FMAs, so at J = 6 the two FMA pipes,
// not the load ports, are the limit (the 6x16 shape of BLIS's Haswell kernel).
template <int J>
__attribute__((target("avx2,fma"))) HBRDF_KERNEL_INLINE void dense_rows_avx2(
    const float* __restrict w, const float* __restrict bias, int n_in, const float* __restrict in,
    float* __restrict out, Activation a, bool last) {
    for (int col = 0; col < kChunk; col += 16) {
        __m256 acc[J][2];
        for (int r = 0; r < J; ++r) acc[r][0] = acc[r][1] = _mm256_set1_ps(bias[r]);
        const float* x = in + col;
        for (int k = 0; k < n_in; ++k, x += kChunk) {
            const __m256 x0 = _mm256_loadu_ps(x), x1 = _mm256_loadu_ps(x + 8);
            for (int r = 0; r < J; ++r) {
                const __m256 wr = _mm256_broadcast_ss(w + r * n_in + k);
                acc[r][0] = _mm256_fmadd_ps(wr, x0, acc[r][0]);
                acc[r][1] = _mm256_fmadd_ps(wr, x1, acc[r][1]);
            }
        }
        for (int r = 0; r < J; ++r) {
            _mm256_storeu_ps(out + r * kChunk + col, act8(acc[r][0], a, last));
            _mm256_storeu_ps(out + r * kChunk + col + 8, act8(acc[r][1], a, last));
        }
    }
}

struct DenseAvx2 {
    // Blocks of 6 rows, then one block of the 1-5 rows left.
    // Not force-inlined: it is called from the target-neutral ModelBatchKernels::run.
    __attribute__((target("avx2,fma"))) static void run(
        const float* __restrict w, const float* __restrict bias, int n_in, int n_out, const float* __restrict in,
        float* __restrict out, Activation a, bool last) {
        int j = 0;
        for (; j + 6 <= n_out; j += 6)
            dense_rows_avx2<6>(w + j * n_in, bias + j, n_in, in, out + j * kChunk, a, last);
        const float* wj = w + j * n_in;
        float* oj = out + j * kChunk;
        switch (n_out - j) {
            case 5: dense_rows_avx2<5>(wj, bias + j, n_in, in, oj, a, last); break;
            case 4: dense_rows_avx2<4>(wj, bias + j, n_in, in, oj, a, last); break;
            case 3: dense_rows_avx2<3>(wj, bias + j, n_in, in, oj, a, last); break;
            case 2: dense_rows_avx2<2>(wj, bias + j, n_in, in, oj, a, last); break;
            case 1: dense_rows_avx2<1>(wj, bias + j, n_in, in, oj, a, last); break;
            default: break;
        }
    }

    // The gated combine (paper Eq. 1) f = exp(min(o, bound)) + sigmoid(g) f_a on 8 lanes, 0 where
    // the pair is invalid: rows of kChunk values in, three rows of f out.
    __attribute__((target("avx2,fma"))) static void combine_gated(const float* __restrict O,
                                                                  const float* __restrict fa,
                                                                  const float* __restrict valid, float bound,
                                                                  float* __restrict f) {
        const __m256 vbound = _mm256_set1_ps(bound), one = _mm256_set1_ps(1.0f), zero = _mm256_setzero_ps();
        for (int i = 0; i < kChunk; i += 8) {
            const __m256 ok = _mm256_cmp_ps(_mm256_loadu_ps(valid + i), zero, _CMP_GT_OQ);
            for (int c = 0; c < 3; ++c) {
                const __m256 fc = exp8(_mm256_min_ps(_mm256_loadu_ps(O + c * kChunk + i), vbound));
                const __m256 e = exp8(_mm256_sub_ps(zero, _mm256_loadu_ps(O + (3 + c) * kChunk + i)));
                const __m256 gate = _mm256_div_ps(one, _mm256_add_ps(one, e));
                const __m256 v = _mm256_fmadd_ps(gate, _mm256_loadu_ps(fa + c * kChunk + i), fc);
                _mm256_storeu_ps(f + c * kChunk + i, _mm256_and_ps(v, ok));
            }
        }
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

    static void combine_gated(const float* O, const float* fa, const float* valid, float bound, float* f) {
        DenseAvx2::combine_gated(O, fa, valid, bound, f);
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
        std::vector<float> scratch(static_cast<std::size_t>(kChunk) * (n_dir + 2 * width + 6 + 9 + 1 + 3));
        float* X = scratch.data();          // n_dir rows
        float* A = X + n_dir * kChunk;      // width rows
        float* B = A + width * kChunk;      // width rows
        float* O = B + width * kChunk;      // 6 rows
        float* D = O + 6 * kChunk;          // wi (3 rows), wo (3 rows), f_a (3 rows)
        float* V = D + 9 * kChunk;          // valid (1 row)
        float* F = V + kChunk;              // f (3 rows)
        const std::vector<float>& bias0 = md.bias0_[m];
        const float bound = md.pre_exp_max_;
        const AnalyticBrdf* brdf = as.analytic ? &md.analytic_[m] : nullptr;
        const float* frames = as.directions == spec::DirectionInputs::Frames ? md.frame_cache_[m].data() : nullptr;

        for (std::size_t start = 0; start < n; start += kChunk) {
            const int cnt = int(std::min<std::size_t>(kChunk, n - start));
            // Directions in SoA; padding lanes get +z (valid, then dropped).
            for (int i = 0; i < kChunk; ++i) {
                const std::size_t r = 3 * (start + (i < cnt ? i : 0));
                for (int c = 0; c < 3; ++c) {
                    D[c * kChunk + i] = i < cnt ? wi_aos[r + c] : float(c == 2);
                    D[(3 + c) * kChunk + i] = i < cnt ? wo_aos[r + c] : float(c == 2);
                }
            }
            normalise_rows(D, V);
            if (brdf) {
                analytic_rows(*brdf, D, D + 6 * kChunk);
                std::copy(D, D + 6 * kChunk, X);
                if (as.directions == spec::DirectionInputs::LocalHalf) half_angle_rows(D, X + 6 * kChunk);
                if (as.extra == spec::ExtraInputs::Log1pFa)
                    for (int c = 0; c < 3; ++c)
                        for (int i = 0; i < kChunk; ++i)
                            X[(as.direction_count + c) * kChunk + i] = std::log1p(D[(6 + c) * kChunk + i]);
            } else {
                // Neural: wi and wo in the material's 3 precomputed frames (t, b, n each).
                for (int side = 0; side < 2; ++side)
                    for (int fr = 0; fr < 3; ++fr)
                        for (int axis = 0; axis < 3; ++axis) {
                            const float* e = frames + 9 * fr + 3 * axis;
                            float* x = X + (9 * side + 3 * fr + axis) * kChunk;
                            const float* w = D + 3 * side * kChunk;
                            // vectorises: neural_frames (tests/python/test_vectorisation.py)
                            for (int i = 0; i < kChunk; ++i)
                                x[i] = e[0] * w[i] + e[1] * w[kChunk + i] + e[2] * w[2 * kChunk + i];
                        }
            }
            // The network: first layer from the varying inputs with the folded bias, then the rest.
            Dense::run(md.w0_dirs_.data(), bias0.data(), n_dir, width, X, A, a, false);
            // Hidden layers 1 .. depth-1, then the output layer (shared, or material m's own).
            const int depth = md.depth_;
            for (int l = 1; l <= depth; ++l) {
                const bool last = l == depth;
                const DenseLayer& L = last ? md.output_layer(m) : md.layers_[l];
                Dense::run(L.weight.data(), L.bias.data(), L.n_in, L.n_out, A, last ? O : B, a, last);
                if (!last) std::swap(A, B);
            }
            // f in three rows, then back to (n, 3).
            const spec::Combine rule = as.combine;
            if (rule == spec::Combine::Gated) {
                Dense::combine_gated(O, D + 6 * kChunk, V, bound, F);
            } else {
                for (int c = 0; c < 3; ++c)
                    for (int i = 0; i < kChunk; ++i) {
                        const float f = detail::combine(rule, O[c * kChunk + i], 0.f, D[(6 + c) * kChunk + i], bound);
                        F[c * kChunk + i] = V[i] > 0.f ? f : 0.f;
                    }
            }
            float* out = f_aos + 3 * start;
            // vectorises: soa_to_aos (tests/python/test_vectorisation.py)
            for (int i = 0; i < cnt; ++i)
                for (int c = 0; c < 3; ++c) out[3 * i + c] = F[c * kChunk + i];
        }
    }

  private:
    // wi and wo (rows 0-5 of D) normalised in place, valid[i] = 1 where both are above the
    // horizon: branch-free per lane, so the compiler vectorises it for the kernel's target.
    HBRDF_KERNEL_INLINE static void normalise_rows(float* __restrict D, float* __restrict valid) {
        // vectorises: normalise_rows (tests/python/test_vectorisation.py)
        for (int i = 0; i < kChunk; ++i) {
            Vec3<float> wi(D[i], D[kChunk + i], D[2 * kChunk + i]);
            Vec3<float> wo(D[3 * kChunk + i], D[4 * kChunk + i], D[5 * kChunk + i]);
            wi = wi * inverse_length_or_zero(wi);
            wo = wo * inverse_length_or_zero(wo);
            valid[i] = (wi.z > 0.f && wo.z > 0.f) ? 1.f : 0.f;
            for (int c = 0; c < 3; ++c) {
                D[c * kChunk + i] = wi[c];
                D[(3 + c) * kChunk + i] = wo[c];
            }
        }
    }

    // cos theta_h and cos theta_d (two rows) of the normalised rows' half vectors, by the
    // functions f_a uses (analytic.hpp's half_vector, cos_theta_d): the hybrid-half network inputs.
    HBRDF_KERNEL_INLINE static void half_angle_rows(const float* __restrict d, float* __restrict x) {
        // vectorises: half_angle_rows (tests/python/test_vectorisation.py)
        for (int i = 0; i < kChunk; ++i) {
            const Vec3<float> wi(d[i], d[kChunk + i], d[2 * kChunk + i]);
            const Vec3<float> wo(d[3 * kChunk + i], d[4 * kChunk + i], d[5 * kChunk + i]);
            const Vec3<float> h = half_vector(wi, wo);
            x[i] = h.z;
            x[kChunk + i] = cos_theta_d(wi, wo, h);
        }
    }

    // f_a of the normalised rows: the loop of batch.cpp's SoA kernel (the BRDF copied into
    // registers, restrict-qualified rows), vectorised the same way.
    HBRDF_KERNEL_INLINE static void analytic_rows(const AnalyticBrdf brdf, const float* __restrict d,
                                                  float* __restrict fa) {
        // vectorises: analytic_rows (tests/python/test_vectorisation.py)
        for (int i = 0; i < kChunk; ++i) {
            const Vec3<float> v = brdf.eval(Vec3<float>(d[i], d[kChunk + i], d[2 * kChunk + i]),
                                            Vec3<float>(d[3 * kChunk + i], d[4 * kChunk + i], d[5 * kChunk + i]));
            fa[i] = v.x;
            fa[kChunk + i] = v.y;
            fa[2 * kChunk + i] = v.z;
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
    return std::min({level, g_model_simd_limit.load(std::memory_order_relaxed), simd_environment_cap()});
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
