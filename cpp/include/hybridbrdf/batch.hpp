// hybridbrdf — batched (array in, array out) evaluation and sampling.
//
// Two layouts:
//   * structure of arrays (SoA): separate x, y, z (or r, g, b) arrays; the
//     fast path, vectorised (AVX2+FMA when the CPU has it, chosen at run time).
//   * array of structures (AoS): (n, 3) row-major float arrays as NumPy and
//     PyTorch hold them; transposed in cache-sized chunks into the SoA kernel.
// All functions are single-threaded and thread-safe (no shared state);
// callers split large batches across threads.
#pragma once

#include <cstddef>

#include "hybridbrdf/params.hpp"
#include "hybridbrdf/sampling.hpp"

namespace hbrdf {

/// Three float arrays of equal length, read-only.
struct ConstSoA3 {
    const float* x;
    const float* y;
    const float* z;
};
/// Three float arrays of equal length, written.
struct SoA3 {
    float* x;
    float* y;
    float* z;
};

/// f_a for n direction pairs in SoA layout. Output channels are r, g, b in
/// f.x, f.y, f.z. Output may not alias input.
void eval_analytic_soa(const AnalyticParams& params, std::size_t n, ConstSoA3 wi, ConstSoA3 wo, SoA3 f);

/// f_a for n direction pairs, wi and wo as (n, 3) row-major arrays, f (n, 3).
void eval_analytic_aos(const AnalyticParams& params, std::size_t n, const float* wi, const float* wo, float* f);

/// Samples n directions: wo (n, 3), u (n, 2) in; wi (n, 3), pdf (n), weight (n, 3) out.
void sample_aos(Strategy strategy, const AnalyticParams& params, std::size_t n, const float* wo, const float* u,
                float* wi, float* pdf, float* weight);

/// Density of `strategy` for n pairs: wi, wo (n, 3) in, pdf (n) out.
void pdf_aos(Strategy strategy, const AnalyticParams& params, std::size_t n, const float* wi, const float* wo,
             float* pdf);

/// Name of the instruction set the batched kernels run with on this CPU:
/// "avx2+fma" or "baseline". The environment variable HBRDF_SIMD (baseline, avx2+fma or
/// avx512, read once per process) caps it and model_simd_path() below what the CPU offers.
const char* simd_path();

/// Forces the baseline (non-AVX2) kernels, for tests and benchmarks that
/// compare the two paths. Not thread-safe with concurrent batch calls.
void force_baseline_simd(bool force);

}  // namespace hbrdf
