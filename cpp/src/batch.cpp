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
constexpr std::size_t kChunk = 256;

HBRDF_ALWAYS_INLINE void eval_aos_body(const AnalyticBrdf& brdf, std::size_t n, const float* wi, const float* wo,
                                       float* f) {
    alignas(64) float buf[9][kChunk];
    for (std::size_t start = 0; start < n; start += kChunk) {
        const std::size_t m = std::min(kChunk, n - start);
        const float* a = wi + 3 * start;
        const float* b = wo + 3 * start;
        // vectorises: aos_to_soa (tests/python/test_vectorisation.py)
        for (std::size_t i = 0; i < m; ++i) {
            buf[0][i] = a[3 * i + 0];
            buf[1][i] = a[3 * i + 1];
            buf[2][i] = a[3 * i + 2];
            buf[3][i] = b[3 * i + 0];
            buf[4][i] = b[3 * i + 1];
            buf[5][i] = b[3 * i + 2];
        }
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

template <Strategy S>
HBRDF_ALWAYS_INLINE void sample_body(const AnalyticBrdf& brdf, std::size_t n, const float* wo, const float* u,
                                     float* wi, float* pdf_out, float* weight) {
    for (std::size_t i = 0; i < n; ++i) {
        const BrdfSample s = sample<S>(brdf, Vec3<float>(wo[3 * i], wo[3 * i + 1], wo[3 * i + 2]),
                                       Vec2<float>(u[2 * i], u[2 * i + 1]));
        wi[3 * i + 0] = s.wi.x;
        wi[3 * i + 1] = s.wi.y;
        wi[3 * i + 2] = s.wi.z;
        pdf_out[i] = s.pdf;
        weight[3 * i + 0] = s.weight.x;
        weight[3 * i + 1] = s.weight.y;
        weight[3 * i + 2] = s.weight.z;
    }
}

template <Strategy S>
HBRDF_ALWAYS_INLINE void pdf_body(const AnalyticBrdf& brdf, std::size_t n, const float* wi, const float* wo,
                                  float* pdf_out) {
    for (std::size_t i = 0; i < n; ++i)
        pdf_out[i] = pdf<S>(brdf, Vec3<float>(wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]),
                            Vec3<float>(wo[3 * i], wo[3 * i + 1], wo[3 * i + 2]));
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
