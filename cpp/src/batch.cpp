// hybridbrdf — batched kernels with run-time instruction-set dispatch.
//
// Each kernel body is written once as a force-inlined template and
// instantiated twice: for the baseline x86-64 target and for AVX2+FMA
// (function-level target attribute, so the rest of the library and the
// headers stay baseline and there is no ODR hazard). The CPU is asked once.
#include "hybridbrdf/batch.hpp"

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "simd_env.hpp"

#if defined(__GNUC__)
#define HBRDF_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define HBRDF_ALWAYS_INLINE inline
#endif

#if (defined(__x86_64__) || defined(__i386__)) && defined(__GNUC__)
#define HBRDF_HAVE_AVX2_PATH 1
#define HBRDF_TARGET_AVX2 __attribute__((target("avx2,fma")))
#else
#define HBRDF_HAVE_AVX2_PATH 0
#endif

namespace hbrdf {
namespace {

// ---- kernel bodies ---------------------------------------------------------

// The loop body only calls inline, branch-free functions, so GCC and Clang
// vectorise it across i; GGX lobe constants are hoisted out by construction.
// restrict-qualified parameters tell the compiler no store to f changes an
// input, so it vectorises without run-time alias checks (GCC ignores restrict
// on local variables); the BRDF constants are copied into registers.
HBRDF_ALWAYS_INLINE void eval_soa_kernel(const AnalyticBrdf brdf, std::size_t n, const float* __restrict ix,
                                         const float* __restrict iy, const float* __restrict iz,
                                         const float* __restrict ox, const float* __restrict oy,
                                         const float* __restrict oz, float* __restrict fr, float* __restrict fg,
                                         float* __restrict fb) {
    // vectorises: eval_soa (tests/python/test_vectorisation.py)
    for (std::size_t i = 0; i < n; ++i) {
        const Vec3<float> v = brdf.eval(Vec3<float>(ix[i], iy[i], iz[i]), Vec3<float>(ox[i], oy[i], oz[i]));
        fr[i] = v.x;
        fg[i] = v.y;
        fb[i] = v.z;
    }
}

HBRDF_ALWAYS_INLINE void eval_soa_body(const AnalyticBrdf& brdf, std::size_t n, ConstSoA3 wi, ConstSoA3 wo, SoA3 f) {
    eval_soa_kernel(brdf, n, wi.x, wi.y, wi.z, wo.x, wo.y, wo.z, f.x, f.y, f.z);
}

// AoS in, AoS out: transpose a chunk into stack SoA buffers, run the SoA
// body, transpose back. 256 pairs = 9 KiB of buffers, well inside L1.
constexpr std::size_t kPairChunk = 256;

// m (wi, wo) pairs of (m, 3) rows into buf[0..2] (wi's x, y, z) and buf[3..5] (wo's).
HBRDF_ALWAYS_INLINE void pairs_to_soa(const float* a, const float* b, std::size_t m, float (*buf)[kPairChunk]) {
    // vectorises: aos_to_soa (tests/python/test_vectorisation.py)
    for (std::size_t i = 0; i < m; ++i) {
        buf[0][i] = a[3 * i + 0];
        buf[1][i] = a[3 * i + 1];
        buf[2][i] = a[3 * i + 2];
        buf[3][i] = b[3 * i + 0];
        buf[4][i] = b[3 * i + 1];
        buf[5][i] = b[3 * i + 2];
    }
}

HBRDF_ALWAYS_INLINE void eval_aos_body(const AnalyticBrdf& brdf, std::size_t n, const float* wi, const float* wo,
                                       float* f) {
    alignas(64) float buf[9][kPairChunk];
    for (std::size_t start = 0; start < n; start += kPairChunk) {
        const std::size_t m = std::min(kPairChunk, n - start);
        pairs_to_soa(wi + 3 * start, wo + 3 * start, m, buf);
        eval_soa_body(brdf, m, ConstSoA3{buf[0], buf[1], buf[2]}, ConstSoA3{buf[3], buf[4], buf[5]},
                      SoA3{buf[6], buf[7], buf[8]});
        float* out = f + 3 * start;
        // vectorises: soa_to_aos (tests/python/test_vectorisation.py)
        for (std::size_t i = 0; i < m; ++i) {
            out[3 * i + 0] = buf[6][i];
            out[3 * i + 1] = buf[7][i];
            out[3 * i + 2] = buf[8][i];
        }
    }
}

// ---- sampling ------------------------------------------------------------------
//
// sample<S>() (sampling.hpp) is the reference; the batched kernels below compute the same
// sample per lane without its two obstacles to vectorisation: the branch between the two
// warps and the libm sin/cos calls (GCC has no vector sinf/cosf without -ffast-math's libmvec).
// Both warps end in sin and cos of one angle (2 pi u.x for the visible normals, the
// concentric map's angle in [-pi/4, 3 pi/4] for the cosine lobe), so each lane picks its angle
// first, takes one polynomial sincos and builds both candidates from it; the lobe is a select.
// Everything else (lobe probability, u rescaling, pdf, f, weight) is the reference's own
// inline code. The results differ from sample<S>() only by sincos_reduced()'s rounding (and, on
// the AVX2 path, by FMA contraction, as f_a's kernels do); tests/cpp/test_sampling.cpp bounds
// the difference and docs/BENCHMARKS.md states it.

// sin and cos of x for |x| <= 2 pi (any |x| < 2^21 stays finite but loses accuracy), branch-
// free so that it vectorises; x = k pi/2 + r with |r| <= pi/4 (three-part Cody-Waite pi/2,
// so r is exact to a float ulp for these k), the Cephes minimax polynomials of sinf and
// cosf on r, and the quadrant k mod 4 swaps and negates them. Cephes states about 1 float ulp
// for these polynomials on |r| <= pi/4; no test measures sincos_reduced() alone:
// tests/cpp/test_sampling.cpp bounds its effect, the sampled directions against sample<S>().
HBRDF_ALWAYS_INLINE void sincos_reduced(float x, float& sin_x, float& cos_x) {
    // Round-to-nearest by adding and removing 1.5 * 2^23: vectorises on SSE2, unlike nearbyintf.
    constexpr float kRound = 12582912.0f;
    const float k = (x * 0.636619772367581343f + kRound) - kRound;  // x * 2/pi
    // pi/2 in three parts; the first two have few enough bits that k * part is exact.
    const float r = ((x - k * 1.5703125f) - k * 4.83751296997070312e-4f) - k * 7.54978995489188216e-8f;
    const float r2 = r * r;
    const float sin_r = r + r * r2 * (-1.6666654611e-1f + r2 * (8.3321608736e-3f + r2 * -1.9515295891e-4f));
    const float cos_r =
        1.0f - 0.5f * r2 + r2 * r2 * (4.166664568298827e-2f + r2 * (-1.388731625493765e-3f + r2 * 2.443315711809948e-5f));
    const int q = static_cast<int>(k);
    // sin x: sin r, cos r, -sin r, -cos r in quadrants 0..3; cos x: cos r, -sin r, -cos r, sin r.
    const float s0 = (q & 1) ? cos_r : sin_r;
    const float c0 = (q & 1) ? sin_r : cos_r;
    sin_x = (q & 2) ? -s0 : s0;
    cos_x = ((q + 1) & 2) ? -c0 : c0;
}

// One sample per i; wo and u as SoA arrays in, wi, pdf and weight as SoA arrays out.
template <Strategy S>
HBRDF_ALWAYS_INLINE void sample_soa_kernel(const AnalyticBrdf brdf, std::size_t n, const float* __restrict ox,
                                           const float* __restrict oy, const float* __restrict oz,
                                           const float* __restrict ux, const float* __restrict uy,
                                           float* __restrict ix, float* __restrict iy, float* __restrict iz,
                                           float* __restrict pdf_out, float* __restrict wr, float* __restrict wg,
                                           float* __restrict wb) {
    const GgxAlpha<float> a = brdf.alpha();
    // vectorises: sample_soa (tests/python/test_vectorisation.py)
    for (std::size_t i = 0; i < n; ++i) {
        const Vec3<float> wo_in(ox[i], oy[i], oz[i]);
        const float inv_len_o = inverse_length_or_zero(wo_in);
        const bool valid = wo_in.z * inv_len_o > 0.0f;  // false for NaN
        const Vec3<float> wo(valid ? wo_in.x * inv_len_o : 0.0f, valid ? wo_in.y * inv_len_o : 0.0f,
                             valid ? wo_in.z * inv_len_o : 1.0f);
        const Vec2<float> u0 = clamp_unit_square(Vec2<float>(ux[i], uy[i]));
        float u_x = u0.x;
        const float u_y = u0.y;

        // One bool per lane, set once: GCC 12 does not vectorise a bool that a constexpr branch reassigns.
        float p_ggx = S == Strategy::Ggx ? 2.0f : -1.0f;  // the lobe is fixed: u_x < p_ggx always / never
        if constexpr (S == Strategy::Mis) p_ggx = ggx_lobe_probability(brdf, wo);
        const bool use_ggx = u_x < p_ggx;
        if constexpr (S == Strategy::Mis) {
            u_x = use_ggx ? u_x / p_ggx : (u_x - p_ggx) / (1.0f - p_ggx);
            u_x = clamp_nan_lo(u_x, 0.0f, kOneMinusEps<float>);
        }

        // Cosine lobe: the concentric map's radius and angle (square_to_concentric_disk).
        const float da = 2.0f * u_x - 1.0f;
        const float db = 2.0f * u_y - 1.0f;
        const bool a_major = da * da > db * db;
        const float radius = a_major ? da : db;
        const float minor = a_major ? db : da;
        const float ratio = radius != 0.0f ? minor / radius : 0.0f;
        const float phi_disk =
            a_major ? (kPi<float> / 4.0f) * ratio : (kPi<float> / 2.0f) - (kPi<float> / 4.0f) * ratio;
        // GGX lobe: the spherical cap's azimuth (sample_ggx_vndf).
        const float phi_cap = 2.0f * kPi<float> * u_x;

        float sin_phi, cos_phi;
        sincos_reduced(use_ggx ? phi_cap : phi_disk, sin_phi, cos_phi);

        // The visible normal and its reflection, as sample_ggx_vndf and sample<S>() build them.
        const Vec3<float> wo_stretched(wo.x * a.ax, wo.y * a.ay, wo.z);
        const Vec3<float> wo_std = wo_stretched * inverse_length_or_zero(wo_stretched);
        const float z = (1.0f - u_y) * (1.0f + wo_std.z) - wo_std.z;
        const float sin_theta = safe_sqrt(1.0f - z * z);
        const Vec3<float> h_std(sin_theta * cos_phi + wo_std.x, sin_theta * sin_phi + wo_std.y, z + wo_std.z);
        const Vec3<float> h_raw(h_std.x * a.ax, h_std.y * a.ay, max0(h_std.z));
        const float inv_len_h = inverse_length_or_zero(h_raw);
        // inv_len_h = 0 (h_std = 0, reachable only at u.y = 1) gives +z, as in sample_ggx_vndf.
        const Vec3<float> h(h_raw.x * inv_len_h, h_raw.y * inv_len_h,
                            inv_len_h > 0.0f ? h_raw.z * inv_len_h : 1.0f);
        const float two_wo_h = 2.0f * dot(wo, h);
        // The cosine-weighted direction (square_to_cosine_hemisphere).
        const float dx = radius * cos_phi;
        const float dy = radius * sin_phi;
        const float dz = safe_sqrt(1.0f - dx * dx - dy * dy);
        // Per-component selects (not a select of vectors) keep these SIMD blends.
        const Vec3<float> wi(use_ggx ? two_wo_h * h.x - wo.x : dx, use_ggx ? two_wo_h * h.y - wo.y : dy,
                             use_ggx ? two_wo_h * h.z - wo.z : dz);

        // pdf and f get wo before the +z substitution: equal to wo where the lane is valid (the
        // rest is masked below), and comparisons of a select's result, which pdf() and eval()
        // make on wo.z, stop GCC 12 from vectorising the loop.
        const Vec3<float> wo_unit = wo_in * inv_len_o;
        const float p = pdf<S>(brdf, wi, wo_unit);
        const float p_valid = valid ? p : 0.0f;  // a select, not "valid && p > 0" (see pdf())
        const bool ok = p_valid > 0.0f;
        const Vec3<float> f = brdf.eval(wi, wo_unit);
        const float cos_over_pdf = ok ? max0(wi.z) / p : 0.0f;
        ix[i] = ok ? wi.x : 0.0f;
        iy[i] = ok ? wi.y : 0.0f;
        iz[i] = ok ? wi.z : 1.0f;
        pdf_out[i] = ok ? p : 0.0f;
        wr[i] = ok ? f.x * cos_over_pdf : 0.0f;
        wg[i] = ok ? f.y * cos_over_pdf : 0.0f;
        wb[i] = ok ? f.z * cos_over_pdf : 0.0f;
    }
}

// AoS in, AoS out through SoA chunks in L1, as eval_aos_body.
template <Strategy S>
HBRDF_ALWAYS_INLINE void sample_body(const AnalyticBrdf& brdf, std::size_t n, const float* wo, const float* u,
                                     float* wi, float* pdf_out, float* weight) {
    alignas(64) float buf[11][kPairChunk];
    for (std::size_t start = 0; start < n; start += kPairChunk) {
        const std::size_t m = std::min(kPairChunk, n - start);
        const float* b = wo + 3 * start;
        const float* v = u + 2 * start;
        // vectorises: sample_aos_to_soa (tests/python/test_vectorisation.py)
        for (std::size_t i = 0; i < m; ++i) {
            buf[0][i] = b[3 * i + 0];
            buf[1][i] = b[3 * i + 1];
            buf[2][i] = b[3 * i + 2];
            buf[3][i] = v[2 * i + 0];
            buf[4][i] = v[2 * i + 1];
        }
        sample_soa_kernel<S>(brdf, m, buf[0], buf[1], buf[2], buf[3], buf[4], buf[5], buf[6], buf[7],
                             pdf_out + start, buf[8], buf[9], buf[10]);
        float* wi_out = wi + 3 * start;
        float* w_out = weight + 3 * start;
        // vectorises: sample_soa_to_aos (tests/python/test_vectorisation.py)
        for (std::size_t i = 0; i < m; ++i) {
            wi_out[3 * i + 0] = buf[5][i];
            wi_out[3 * i + 1] = buf[6][i];
            wi_out[3 * i + 2] = buf[7][i];
            w_out[3 * i + 0] = buf[8][i];
            w_out[3 * i + 1] = buf[9][i];
            w_out[3 * i + 2] = buf[10][i];
        }
    }
}

template <Strategy S>
HBRDF_ALWAYS_INLINE void pdf_soa_kernel(const AnalyticBrdf brdf, std::size_t n, const float* __restrict ix,
                                        const float* __restrict iy, const float* __restrict iz,
                                        const float* __restrict ox, const float* __restrict oy,
                                        const float* __restrict oz, float* __restrict pdf_out) {
    // vectorises: pdf_soa (tests/python/test_vectorisation.py)
    for (std::size_t i = 0; i < n; ++i)
        pdf_out[i] = pdf<S>(brdf, Vec3<float>(ix[i], iy[i], iz[i]), Vec3<float>(ox[i], oy[i], oz[i]));
}

template <Strategy S>
HBRDF_ALWAYS_INLINE void pdf_body(const AnalyticBrdf& brdf, std::size_t n, const float* wi, const float* wo,
                                  float* pdf_out) {
    alignas(64) float buf[6][kPairChunk];
    for (std::size_t start = 0; start < n; start += kPairChunk) {
        const std::size_t m = std::min(kPairChunk, n - start);
        pairs_to_soa(wi + 3 * start, wo + 3 * start, m, buf);
        pdf_soa_kernel<S>(brdf, m, buf[0], buf[1], buf[2], buf[3], buf[4], buf[5], pdf_out + start);
    }
}

// ---- instantiations per target ---------------------------------------------

#define HBRDF_DEFINE_KERNELS(SUFFIX, ATTR)                                                                           \
    ATTR void eval_soa_##SUFFIX(const AnalyticBrdf& b, std::size_t n, ConstSoA3 wi, ConstSoA3 wo, SoA3 f) {         \
        eval_soa_body(b, n, wi, wo, f);                                                                            \
    }                                                                                                              \
    ATTR void eval_aos_##SUFFIX(const AnalyticBrdf& b, std::size_t n, const float* wi, const float* wo, float* f) { \
        eval_aos_body(b, n, wi, wo, f);                                                                            \
    }                                                                                                              \
    ATTR void sample_##SUFFIX(Strategy s, const AnalyticBrdf& b, std::size_t n, const float* wo, const float* u,    \
                              float* wi, float* p, float* w) {                                                     \
        switch (s) {                                                                                               \
            case Strategy::Cosine: sample_body<Strategy::Cosine>(b, n, wo, u, wi, p, w); break;                    \
            case Strategy::Ggx: sample_body<Strategy::Ggx>(b, n, wo, u, wi, p, w); break;                          \
            default: sample_body<Strategy::Mis>(b, n, wo, u, wi, p, w); break;                                    \
        }                                                                                                          \
    }                                                                                                              \
    ATTR void pdf_##SUFFIX(Strategy s, const AnalyticBrdf& b, std::size_t n, const float* wi, const float* wo,      \
                           float* p) {                                                                             \
        switch (s) {                                                                                               \
            case Strategy::Cosine: pdf_body<Strategy::Cosine>(b, n, wi, wo, p); break;                             \
            case Strategy::Ggx: pdf_body<Strategy::Ggx>(b, n, wi, wo, p); break;                                   \
            default: pdf_body<Strategy::Mis>(b, n, wi, wo, p); break;                                              \
        }                                                                                                          \
    }

HBRDF_DEFINE_KERNELS(baseline, )
#if HBRDF_HAVE_AVX2_PATH
HBRDF_DEFINE_KERNELS(avx2, HBRDF_TARGET_AVX2)
#endif

std::atomic<bool> g_force_baseline{false};

}  // namespace

int simd_environment_cap() {
    static const int cap = [] {
        const char* v = std::getenv("HBRDF_SIMD");
        if (v == nullptr || *v == '\0' || std::strcmp(v, "avx512") == 0) return 2;
        if (std::strcmp(v, "avx2+fma") == 0) return 1;
        if (std::strcmp(v, "baseline") == 0) return 0;
        // Read lazily inside the kernels' dispatch, where throwing would surprise every caller:
        // one line on stderr, and the variable is ignored.
        std::fprintf(stderr, "hybridbrdf: HBRDF_SIMD='%.40s' is not avx512, avx2+fma or baseline; ignored\n", v);
        return 2;
    }();
    return cap;
}

namespace {

bool use_avx2() {
#if HBRDF_HAVE_AVX2_PATH
    static const bool has = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    return has && simd_environment_cap() >= 1 && !g_force_baseline.load(std::memory_order_relaxed);
#else
    return false;
#endif
}

}  // namespace

#if HBRDF_HAVE_AVX2_PATH
#define HBRDF_DISPATCH(NAME, ...) (use_avx2() ? NAME##_avx2(__VA_ARGS__) : NAME##_baseline(__VA_ARGS__))
#else
#define HBRDF_DISPATCH(NAME, ...) NAME##_baseline(__VA_ARGS__)
#endif

void eval_analytic_soa(const AnalyticParams& params, std::size_t n, ConstSoA3 wi, ConstSoA3 wo, SoA3 f) {
    const AnalyticBrdf brdf(params);
    HBRDF_DISPATCH(eval_soa, brdf, n, wi, wo, f);
}

void eval_analytic_aos(const AnalyticParams& params, std::size_t n, const float* wi, const float* wo, float* f) {
    const AnalyticBrdf brdf(params);
    HBRDF_DISPATCH(eval_aos, brdf, n, wi, wo, f);
}

void sample_aos(Strategy strategy, const AnalyticParams& params, std::size_t n, const float* wo, const float* u,
                float* wi, float* pdf_out, float* weight) {
    const AnalyticBrdf brdf(params);
    HBRDF_DISPATCH(sample, strategy, brdf, n, wo, u, wi, pdf_out, weight);
}

void pdf_aos(Strategy strategy, const AnalyticParams& params, std::size_t n, const float* wi, const float* wo,
             float* pdf_out) {
    const AnalyticBrdf brdf(params);
    HBRDF_DISPATCH(pdf, strategy, brdf, n, wi, wo, pdf_out);
}

const char* simd_path() { return use_avx2() ? "avx2+fma" : "baseline"; }

void force_baseline_simd(bool force) { g_force_baseline.store(force, std::memory_order_relaxed); }

}  // namespace hbrdf
