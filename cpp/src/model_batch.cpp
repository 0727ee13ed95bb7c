// hybridbrdf — vectorised batched inference of fitted models.
//
// Pairs are processed in chunks of kChunk (64) in structure-of-arrays layout. A layer is
// out[j][i] = b[j] + sum_k W[j][k] in[k][i]: the weight is broadcast and the loop over the
// pairs i is a straight FMA stream. Three layer kernels, chosen at run time
// (model_simd_path()):
// - portable: that loop, compiled for the baseline target (one load per FMA);
// - AVX2+FMA: register-blocked intrinsics, blocks of 6 outputs x 16 pairs (two 8-lane
//   vectors each): 12 accumulators, and per input 2 vector loads and 6 broadcasts feed 12
//   FMAs, so the two FMA pipes and not the load ports are the limit (BLIS's Haswell shape);
// - AVX-512: blocks of 4 outputs x 64 pairs (four 16-lane vectors each): 16 accumulators.
// The rest of a chunk's work (normalisation, f_a, the network inputs, the combine) is written
// once and compiled for each kernel's target. The per-lane activation and gated combine of the
// vector kernels are model_simd.hpp's; the portable kernel's, and every kernel's other combine
// rules, are model_math.hpp's, lane by lane.
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
#include "model_simd.hpp"
#include "simd_env.hpp"

#if defined(__GNUC__)
#define HBRDF_KERNEL_INLINE inline __attribute__((always_inline))
#else
#define HBRDF_KERNEL_INLINE inline
#endif

namespace hbrdf {

namespace {
constexpr int kChunk = int(HybridModel::kBatchChunk);

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
            // One loop per activation, so that each is a plain loop over the lanes.
            if (last)
                for (int i = 0; i < kChunk; ++i) o[i] = acc[i];
            else if (a == Activation::Relu)
                for (int i = 0; i < kChunk; ++i) o[i] = activate(Activation::Relu, acc[i]);
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

#if HBRDF_SIMD_X86
// GCC 12's own AVX-512 intrinsics (_mm512_undefined_ps) trip -Wmaybe-uninitialized when
// inlined (GCC bug 105593, fixed in GCC 13); the warning is about the header, not this code.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
using detail::activate16;
using detail::activate8;

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
        for (int r = 0; r < J; ++r)
            for (int h = 0; h < 2; ++h)
                _mm256_storeu_ps(out + r * kChunk + col + 8 * h, last ? acc[r][h] : activate8(a, acc[r][h]));
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

    // The gated combine (detail::combine_gated8) on 8 lanes at a time, 0 where the pair is
    // invalid: rows of kChunk values in, three rows of f out.
    __attribute__((target("avx2,fma"))) static void combine_gated(const float* __restrict O,
                                                                  const float* __restrict fa,
                                                                  const float* __restrict valid, float bound,
                                                                  float* __restrict f) {
        const __m256 vbound = _mm256_set1_ps(bound), zero = _mm256_setzero_ps();
        for (int i = 0; i < kChunk; i += 8) {
            const __m256 ok = _mm256_cmp_ps(_mm256_loadu_ps(valid + i), zero, _CMP_GT_OQ);
            for (int c = 0; c < 3; ++c) {
                const __m256 v = detail::combine_gated8(_mm256_loadu_ps(O + c * kChunk + i),
                                                        _mm256_loadu_ps(O + (3 + c) * kChunk + i),
                                                        _mm256_loadu_ps(fa + c * kChunk + i), vbound);
                _mm256_storeu_ps(f + c * kChunk + i, _mm256_and_ps(v, ok));
            }
        }
    }
};

struct DenseAvx512 {
    // Blocks of 4 outputs x 64 pairs: 16 accumulators + 4 inputs + 1 weight of 32 registers;
    // the 1-3 rows left go to the AVX2 kernel.
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
                for (int v = 0; v < V; ++v)
                    _mm512_storeu_ps(out + (j + r) * kChunk + 16 * v, last ? acc[r][v] : activate16(a, acc[r][v]));
        }
        if (j < n_out) DenseAvx2::run(w + j * n_in, bias + j, n_in, n_out - j, in, out + j * kChunk, a, last);
    }

    // The combine runs once per pair, not per weight: the AVX2 one serves.
    static void combine_gated(const float* O, const float* fa, const float* valid, float bound, float* f) {
        DenseAvx2::combine_gated(O, fa, valid, bound, f);
    }
};
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#endif

}  // namespace

struct ModelBatchKernels {
    // f_t for pairs [0, n) of material m, chunk by chunk: directions to SoA and normalised, the
    // network's inputs, its layers with the kernel `Dense`, the combine, f back to AoS.
    template <class Dense>
    HBRDF_KERNEL_INLINE static void run(const HybridModel& md, int m, std::size_t n, const float* wi_aos,
                                        const float* wo_aos, float* f_aos) {
        const int width = md.width_;
        const int n_dir = md.n_dir_inputs_;
        std::vector<float> scratch(static_cast<std::size_t>(kChunk) * (n_dir + 2 * width + 6 + 9 + 1 + 3));
        Rows rows;
        rows.X = scratch.data();            // n_dir rows
        rows.A = rows.X + n_dir * kChunk;   // width rows
        rows.B = rows.A + width * kChunk;   // width rows
        rows.O = rows.B + width * kChunk;   // 6 rows
        rows.D = rows.O + 6 * kChunk;       // wi (3 rows), wo (3 rows), f_a (3 rows)
        rows.V = rows.D + 9 * kChunk;       // valid (1 row)
        rows.F = rows.V + kChunk;           // f (3 rows)
        for (std::size_t start = 0; start < n; start += kChunk) {
            const int cnt = int(std::min<std::size_t>(kChunk, n - start));
            directions_to_rows(wi_aos + 3 * start, wo_aos + 3 * start, cnt, rows.D);
            normalise_rows(rows.D, rows.V);
            network_inputs(md, m, rows);
            run_network<Dense>(md, m, rows);
            combine<Dense>(md, rows);
            if (md.energy_bound_ == EnergyBound::AlbedoTable) energy_bound_rows(md.materials_[m].energy_bound, rows);
            float* out = f_aos + 3 * start;
            const float* F = rows.F;
            // vectorises: soa_to_aos (tests/python/test_vectorisation.py)
            for (int i = 0; i < cnt; ++i)
                for (int c = 0; c < 3; ++c) out[3 * i + c] = F[c * kChunk + i];
        }
    }

    // f of texel layers (HybridModel::eval_batch_layers): entries [0, n), each with its own material,
    // p and z; runs of one material chunk by chunk, as run() does, except that f_a comes from each
    // lane's own parameters and the latent code is a row of the first layer's input (the full W0)
    // instead of being folded into its bias.
    template <class Dense>
    HBRDF_KERNEL_INLINE static void run_layers(const HybridModel& md, std::size_t n, const float* wi_aos,
                                               const float* wo_aos, const TexelLayer* layers, float* f_aos) {
        const int width = md.width_, n_in = md.n_in_, latent = md.latent_;
        const spec::ArchSpec& as = md.arch();
        std::vector<float> scratch(static_cast<std::size_t>(kChunk) * (n_in + 2 * width + 6 + 9 + 1 + 3 + 8));
        Rows rows;
        float* P = scratch.data() + std::size_t(kChunk) * (n_in + 2 * width + 6 + 9 + 1 + 3);  // kd, eta, alpha rows
        rows.X = scratch.data();            // n_in rows: direction inputs, latent code, extra inputs
        rows.A = rows.X + n_in * kChunk;
        rows.B = rows.A + width * kChunk;
        rows.O = rows.B + width * kChunk;
        rows.D = rows.O + 6 * kChunk;
        rows.V = rows.D + 9 * kChunk;
        rows.F = rows.V + kChunk;
        const DenseLayer& L0 = md.layers_[0];
        std::size_t start = 0;
        while (start < n) {
            const int m = layers[start].material;
            int cnt = 1;
            while (cnt < kChunk && start + std::size_t(cnt) < n && layers[start + std::size_t(cnt)].material == m) ++cnt;
            directions_to_rows(wi_aos + 3 * start, wo_aos + 3 * start, cnt, rows.D);
            normalise_rows(rows.D, rows.V);
            float* fa = rows.D + 6 * kChunk;
            for (int i = 0; i < kChunk; ++i) {  // each lane's p in rows (padding lanes repeat the first)
                const AnalyticParams& p = layers[start + std::size_t(i < cnt ? i : 0)].params;
                for (int c = 0; c < 3; ++c) P[c * kChunk + i] = p.kd[c], P[(3 + c) * kChunk + i] = p.eta[c];
                P[6 * kChunk + i] = p.alpha.x, P[7 * kChunk + i] = p.alpha.y;
            }
            analytic_rows_per_lane(P, rows.D, fa);
            float* X = rows.X;
            if (as.directions == spec::DirectionInputs::Reciprocal) {
                reciprocal_rows(rows.D, X);
            } else {
                std::copy(rows.D, rows.D + 6 * kChunk, X);
                if (as.directions == spec::DirectionInputs::LocalHalf) half_angle_rows(rows.D, X + 6 * kChunk);
            }
            for (int k = 0; k < latent; ++k)
                for (int i = 0; i < kChunk; ++i)
                    X[(as.direction_count + k) * kChunk + i] = layers[start + std::size_t(i < cnt ? i : 0)].latent[k];
            if (as.extra == spec::ExtraInputs::Log1pFa)
                for (int c = 0; c < 3; ++c)
                    for (int i = 0; i < kChunk; ++i) X[(as.direction_count + latent + c) * kChunk + i] = std::log1p(fa[c * kChunk + i]);
            float* A = rows.A;
            float* B = rows.B;
            Dense::run(L0.weight.data(), L0.bias.data(), n_in, width, X, A, md.activation_, false);
            for (int l = 1; l <= md.depth_; ++l) {
                const bool last = l == md.depth_;
                const DenseLayer& L = last ? md.output_layer(m) : md.layers_[l];
                Dense::run(L.weight.data(), L.bias.data(), L.n_in, L.n_out, A, last ? rows.O : B, md.activation_, last);
                if (!last) std::swap(A, B);
            }
            combine<Dense>(md, rows);
            if (md.energy_bound_ == EnergyBound::AlbedoTable) energy_bound_rows(md.materials_[m].energy_bound, rows);
            float* out = f_aos + 3 * start;
            for (int i = 0; i < cnt; ++i)
                for (int c = 0; c < 3; ++c) out[3 * i + c] = rows.F[c * kChunk + i];
            start += std::size_t(cnt);
        }
    }

  private:
    // A chunk's scratch rows, kChunk values each.
    struct Rows {
        float *X, *A, *B, *O, *D, *V, *F;
    };

    // `cnt` pairs of wi, wo (AoS) into rows 0-5 of D; padding lanes get +z (valid, then dropped).
    HBRDF_KERNEL_INLINE static void directions_to_rows(const float* wi, const float* wo, int cnt, float* D) {
        for (int i = 0; i < kChunk; ++i) {
            const int r = 3 * (i < cnt ? i : 0);
            for (int c = 0; c < 3; ++c) {
                D[c * kChunk + i] = i < cnt ? wi[r + c] : float(c == 2);
                D[(3 + c) * kChunk + i] = i < cnt ? wo[r + c] : float(c == 2);
            }
        }
    }

    // The rows of X the network reads (spec/model.json's input layout, the latent code folded
    // into the first bias): the directions, the half-angle inputs and log1p(f_a) for the hybrid
    // kinds (f_a into rows 6-8 of D), or wi and wo in the material's frames for the neural one.
    HBRDF_KERNEL_INLINE static void network_inputs(const HybridModel& md, int m, const Rows& rows) {
        const spec::ArchSpec& as = md.arch();
        float* X = rows.X;
        const float* D = rows.D;
        if (as.analytic) {
            analytic_rows(md.analytic_[m], D, rows.D + 6 * kChunk);
            if (as.directions == spec::DirectionInputs::Reciprocal) {
                reciprocal_rows(D, X);
            } else {
                std::copy(D, D + 6 * kChunk, X);
                if (as.directions == spec::DirectionInputs::LocalHalf) half_angle_rows(D, X + 6 * kChunk);
            }
            if (as.extra == spec::ExtraInputs::Log1pFa)
                for (int c = 0; c < 3; ++c)
                    for (int i = 0; i < kChunk; ++i)
                        X[(as.direction_count + c) * kChunk + i] = std::log1p(D[(6 + c) * kChunk + i]);
            return;
        }
        // Neural: wi and wo in the material's 3 precomputed frames (t, b, n each).
        const float* frames = md.frame_cache_[m].data();
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

    // The first layer from the varying inputs X with the folded bias, hidden layers
    // 1 .. depth-1 between A and B, then the output layer (shared, or material m's own) into O.
    template <class Dense>
    HBRDF_KERNEL_INLINE static void run_network(const HybridModel& md, int m, const Rows& rows) {
        const Activation a = md.activation_;
        float* A = rows.A;
        float* B = rows.B;
        Dense::run(md.w0_dirs_.data(), md.bias0_[m].data(), md.n_dir_inputs_, md.width_, rows.X, A, a, false);
        for (int l = 1; l <= md.depth_; ++l) {
            const bool last = l == md.depth_;
            const DenseLayer& L = last ? md.output_layer(m) : md.layers_[l];
            Dense::run(L.weight.data(), L.bias.data(), L.n_in, L.n_out, A, last ? rows.O : B, a, last);
            if (!last) std::swap(A, B);
        }
    }

    // f *= k(wi.z) k(wo.z) (spec/model.json, energy_bounds): energy_bound_scale's hat-function sum,
    // node by node over the whole chunk so that it vectorises, in the scalar path's order.
    HBRDF_KERNEL_INLINE static void energy_bound_rows(const std::vector<float>& table, const Rows& rows) {
        alignas(64) float ti[kChunk], to[kChunk], ki[kChunk], ko[kChunk];
        const float scale = float(table.size() - 1);
        const float* wiz = rows.D + 2 * kChunk;
        const float* woz = rows.D + 5 * kChunk;
        for (int i = 0; i < kChunk; ++i) ti[i] = wiz[i] * scale, to[i] = woz[i] * scale, ki[i] = 0.f, ko[i] = 0.f;
        float node = 0.f;
        for (float kj : table) {
            for (int i = 0; i < kChunk; ++i) {
                ki[i] += kj * std::max(0.f, 1.f - std::fabs(ti[i] - node));
                ko[i] += kj * std::max(0.f, 1.f - std::fabs(to[i] - node));
            }
            node += 1.f;
        }
        for (int c = 0; c < 3; ++c)
            for (int i = 0; i < kChunk; ++i) rows.F[c * kChunk + i] *= ki[i] * ko[i];
    }

    // f in three rows of F from the outputs O and f_a (rows 6-8 of D), 0 where the pair is invalid.
    template <class Dense>
    HBRDF_KERNEL_INLINE static void combine(const HybridModel& md, const Rows& rows) {
        const spec::Combine rule = md.arch().combine;
        const float bound = md.pre_exp_max_;
        if (rule == spec::Combine::Gated) return Dense::combine_gated(rows.O, rows.D + 6 * kChunk, rows.V, bound, rows.F);
        for (int c = 0; c < 3; ++c)
            for (int i = 0; i < kChunk; ++i) {
                const float f = detail::combine(rule, rows.O[c * kChunk + i], 0.f, rows.D[(6 + c) * kChunk + i], bound);
                rows.F[c * kChunk + i] = rows.V[i] > 0.f ? f : 0.f;
            }
    }

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

    // The hybrid-reciprocal inputs (nine rows of x) of the normalised rows, by the scalar path's
    // function (model_math.hpp): s = wi + wo and the products of d = wi - wo.
    HBRDF_KERNEL_INLINE static void reciprocal_rows(const float* __restrict d, float* __restrict x) {
        // vectorises: reciprocal_rows (tests/python/test_vectorisation.py)
        for (int i = 0; i < kChunk; ++i) {
            const Vec3<float> wi(d[i], d[kChunk + i], d[2 * kChunk + i]);
            const Vec3<float> wo(d[3 * kChunk + i], d[4 * kChunk + i], d[5 * kChunk + i]);
            detail::reciprocal_inputs(wi, wo, x + i, kChunk);
        }
    }

    // f_a of the normalised rows with each lane's own parameters (rows of P: kd, eta, alpha_x,
    // alpha_y), the BRDF built per lane: the texel path's twin of analytic_rows.
    HBRDF_KERNEL_INLINE static void analytic_rows_per_lane(const float* __restrict P, const float* __restrict d,
                                                           float* __restrict fa) {
        for (int i = 0; i < kChunk; ++i) {
            AnalyticParams p;
            p.kd = Vec3<float>(P[i], P[kChunk + i], P[2 * kChunk + i]);
            p.eta = Vec3<float>(P[3 * kChunk + i], P[4 * kChunk + i], P[5 * kChunk + i]);
            p.alpha = Vec2<float>(P[6 * kChunk + i], P[7 * kChunk + i]);
            const Vec3<float> v = AnalyticBrdf(p).eval(Vec3<float>(d[i], d[kChunk + i], d[2 * kChunk + i]),
                                                       Vec3<float>(d[3 * kChunk + i], d[4 * kChunk + i], d[5 * kChunk + i]));
            fa[i] = v.x;
            fa[kChunk + i] = v.y;
            fa[2 * kChunk + i] = v.z;
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
#if HBRDF_SIMD_X86
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

void run_layers_baseline(const HybridModel& md, std::size_t n, const float* wi, const float* wo, const TexelLayer* t,
                         float* f) {
    ModelBatchKernels::run_layers<DensePortable>(md, n, wi, wo, t, f);
}
#if HBRDF_SIMD_X86
__attribute__((target("avx2,fma"))) void run_layers_avx2(const HybridModel& md, std::size_t n, const float* wi,
                                                         const float* wo, const TexelLayer* t, float* f) {
    ModelBatchKernels::run_layers<DenseAvx2>(md, n, wi, wo, t, f);
}
__attribute__((target("avx512f,avx2,fma"))) void run_layers_avx512(const HybridModel& md, std::size_t n, const float* wi,
                                                                   const float* wo, const TexelLayer* t, float* f) {
    ModelBatchKernels::run_layers<DenseAvx512>(md, n, wi, wo, t, f);
}
#endif

std::atomic<int> g_model_simd_limit{2};  // 0 baseline, 1 avx2+fma, 2 avx512 (the best the CPU has)
}  // namespace

// 2 avx512, 1 avx2+fma, 0 baseline: the best kernel the CPU runs, capped by the limit.
int detail::model_kernel_level() {
    int level = 0;
#if HBRDF_SIMD_X86
    if (std::string_view(simd_path()) == "avx2+fma") level = cpu_has_avx512() ? 2 : 1;  // "baseline" when forced
#endif
    return std::min({level, g_model_simd_limit.load(std::memory_order_relaxed), simd_environment_cap()});
}

const char* model_simd_path() {
    static const char* const kNames[] = {"baseline", "avx2+fma", "avx512"};
    return kNames[detail::model_kernel_level()];
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
#if HBRDF_SIMD_X86
    switch (detail::model_kernel_level()) {
        case 2: return run_avx512(*this, m, n, wi, wo, f);
        case 1: return run_avx2(*this, m, n, wi, wo, f);
        default: break;
    }
#endif
    run_baseline(*this, m, n, wi, wo, f);
}

void HybridModel::eval_batch_layers(std::size_t n, const float* wi, const float* wo, const TexelLayer* layers,
                                    float* f) const {
    if (kind_ == ModelKind::Neural) throw std::logic_error("textured materials need a hybrid model (f_a per texel)");
    int previous = -1;
    for (std::size_t i = 0; i < n; ++i) {  // a material is checked once per run of it
        if (layers[i].material != previous) check_material(previous = layers[i].material);
        if (!layers[i].latent) throw std::invalid_argument("texel layer has no latent code");
    }
#if HBRDF_SIMD_X86
    switch (detail::model_kernel_level()) {
        case 2: return run_layers_avx512(*this, n, wi, wo, layers, f);
        case 1: return run_layers_avx2(*this, n, wi, wo, layers, f);
        default: break;
    }
#endif
    run_layers_baseline(*this, n, wi, wo, layers, f);
}

void HybridModel::prepare_batch() {
    // Inputs that vary per pair: the direction inputs and the extra inputs. The latent
    // inputs are constant per material, so W0[:, z] z is added to the first bias once,
    // here, in double.
    const int z_start = arch().direction_count;
    n_dir_inputs_ = n_in_ - latent_;
    const DenseLayer& L0 = layers_[0];
    w0_dirs_.assign(static_cast<std::size_t>(width_) * n_dir_inputs_, 0.f);
    for (int j = 0; j < width_; ++j) {
        int c = 0;
        for (int k = 0; k < n_in_; ++k)
            if (k < z_start || k >= z_start + latent_) w0_dirs_[j * n_dir_inputs_ + c++] = L0.weight[j * n_in_ + k];
    }
    bias0_.clear();
    frame_cache_.clear();
    for (const ModelMaterial& mat : materials_) {
        std::vector<float> b(width_);
        for (int j = 0; j < width_; ++j) {
            double acc = L0.bias[j];
            for (int k = 0; k < latent_; ++k) acc += double(L0.weight[j * n_in_ + z_start + k]) * mat.latent[k];
            b[j] = float(acc);
        }
        bias0_.push_back(std::move(b));
        if (arch().directions == spec::DirectionInputs::Frames) {
            std::vector<float> fr(9 * spec::kNeuralFrames);
            detail::neural_frames(frames_, mat.latent.data(), fr.data());
            frame_cache_.push_back(std::move(fr));
        }
    }
}

}  // namespace hbrdf
