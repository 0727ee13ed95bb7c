// hybridbrdf — one core's single-precision FMA peak, the denominator of the "fraction of FMA
// peak" figures in docs/BENCHMARKS.md and of the speed guard's efficiency ratio.
//
// Twelve independent accumulators of 8-wide (AVX2) or 16-wide (AVX-512) FMAs: enough chains
// to cover FMA latency x pipes on current x86 cores (4 cycles x 2 pipes needs >= 8), no loads,
// so the loop runs at the FMA issue rate. GFLOP/s counts 2 flops per lane per FMA; the peak is
// the larger of the two (a core whose AVX-512 runs on 256-bit pipes gains nothing from it).
//
// Header-only so that the hbrdf_fma_peak tool, the speed guard's driver and the Python module
// (hybridbrdf._core.fma_peak_gflops: benchmarks run from an installed package) measure the
// same loops. x86-64 with GCC or Clang only.
#pragma once

#include <immintrin.h>

#include <chrono>

// GCC 12's intrinsics headers trip -Wmaybe-uninitialized when inlined (GCC bug 105593).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

namespace hbrdf::fma_peak {

inline constexpr int kChains = 12;
inline constexpr long kIters = 1 << 20;
inline volatile float g_sink;

/// Best GFLOP/s of repeated calls of `body` (flops_per_call each) within `seconds`: the best
/// call is the one least disturbed by other processes.
template <class Body> double best_gflops(Body body, double flops_per_call, double seconds) {
    using clock = std::chrono::steady_clock;
    double best = 0.0;
    const auto end = clock::now() + std::chrono::duration<double>(seconds);
    while (clock::now() < end) {
        const auto t0 = clock::now();
        body();
        const double dt = std::chrono::duration<double>(clock::now() - t0).count();
        const double rate = flops_per_call / dt / 1e9;
        if (rate > best) best = rate;
    }
    return best;
}

__attribute__((target("avx2,fma"))) inline void fma_avx2() {
    __m256 acc[kChains];
    for (int c = 0; c < kChains; ++c) acc[c] = _mm256_set1_ps(float(c) * 1e-3f);
    const __m256 a = _mm256_set1_ps(0.999999f), b = _mm256_set1_ps(1e-7f);
    for (long i = 0; i < kIters; ++i) {
        // Fully unrolled so that the accumulators live in registers, not memory.
#pragma GCC unroll 12
        for (int c = 0; c < kChains; ++c) acc[c] = _mm256_fmadd_ps(acc[c], a, b);
    }
    __m256 s = acc[0];
    for (int c = 1; c < kChains; ++c) s = _mm256_add_ps(s, acc[c]);
    g_sink = _mm256_cvtss_f32(s);
}

__attribute__((target("avx512f"))) inline void fma_avx512() {
    __m512 acc[kChains];
    for (int c = 0; c < kChains; ++c) acc[c] = _mm512_set1_ps(float(c) * 1e-3f);
    const __m512 a = _mm512_set1_ps(0.999999f), b = _mm512_set1_ps(1e-7f);
    for (long i = 0; i < kIters; ++i) {
#pragma GCC unroll 12
        for (int c = 0; c < kChains; ++c) acc[c] = _mm512_fmadd_ps(acc[c], a, b);
    }
    __m512 s = acc[0];
    for (int c = 1; c < kChains; ++c) s = _mm512_add_ps(s, acc[c]);
    alignas(64) float lanes[16];
    _mm512_store_ps(lanes, s);
    g_sink = lanes[0] + lanes[15];
}

/// One core's FMA peak in GFLOP/s per instruction set the CPU has (0 where it has not), each
/// measured for `seconds`, and the larger of the two.
struct Peak {
    double avx2_fma = 0.0, avx512 = 0.0;
    double peak() const { return avx2_fma > avx512 ? avx2_fma : avx512; }
};

inline Peak measure(double seconds) {
    __builtin_cpu_init();
    Peak p;
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"))
        p.avx2_fma = best_gflops(fma_avx2, 2.0 * 8 * kChains * double(kIters), seconds);
    if (__builtin_cpu_supports("avx512f"))
        p.avx512 = best_gflops(fma_avx512, 2.0 * 16 * kChains * double(kIters), seconds);
    return p;
}

}  // namespace hbrdf::fma_peak

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
