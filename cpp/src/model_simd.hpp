// hybridbrdf — the per-lane math of the batched kernels (model_batch.cpp), internal to
// libhybridbrdf: the activations on 8 (AVX2) and 16 (AVX-512) lanes and the gated combine on 8,
// the vector twins of model_math.hpp's activate() and combine(), written from the same contract
// constants (spec/model.json). The portable kernel applies model_math.hpp's functions
// themselves lane by lane, and so do the vector kernels for the combine rules other than
// gated. The kernels call these functions, and so does the contract-table test hook
// (model_contract.cpp), so spec/activation_combine.json is checked against the kernels' code.
#pragma once

#include "model_math.hpp"

#if (defined(__x86_64__) || defined(__i386__)) && defined(__GNUC__)
#define HBRDF_SIMD_X86 1
#include <immintrin.h>
#else
#define HBRDF_SIMD_X86 0
#endif

namespace hbrdf::detail {

/// The kernel HybridModel::eval_batch runs now: 0 baseline, 1 avx2+fma, 2 avx512 (the best the
/// CPU has, capped by limit_model_simd and HBRDF_SIMD; model_simd_path() names it).
int model_kernel_level();

#if HBRDF_SIMD_X86
// GCC 12's own AVX-512 intrinsics (_mm512_undefined_ps) trip -Wmaybe-uninitialized when
// inlined (GCC bug 105593, fixed in GCC 13); the warning is about the header, not this code.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

// activate(a, x) on a vector, in the scalar function's order of operations: hardGeLU is
// x * clamp((x + knee) * (1 / (2 knee)), 0, 1), the sum first. Folding it into one FMA,
// x * (1 / (2 knee)) + 1/2, loses the sum's exactness next to -knee (Sterbenz): there the
// rounding of 1 / (2 knee) is not cancelled and the result is off by over a third
// (spec/activation_combine.json's rows at -knee's neighbours). max(x, 0) returns 0 for NaN,
// like clamp_nan_lo.
#define HBRDF_ACTIVATE_BODY(SET1, ADD, MAX, MIN, MUL)                                              \
    if (a == Activation::Relu) return MAX(x, SET1(0.0f));                                     \
    constexpr float kKnee = float(spec::kHardgeluKnee);                                       \
    const auto t = MUL(ADD(x, SET1(kKnee)), SET1(1.0f / (2.0f * kKnee)));                     \
    return MUL(x, MIN(MAX(t, SET1(0.0f)), SET1(1.0f)));

/// activate(a, x) on 8 lanes (the AVX2 kernel's layers).
__attribute__((target("avx2,fma"))) HBRDF_INLINE __m256 activate8(Activation a, __m256 x) {
    HBRDF_ACTIVATE_BODY(_mm256_set1_ps, _mm256_add_ps, _mm256_max_ps, _mm256_min_ps, _mm256_mul_ps)
}

/// activate(a, x) on 16 lanes (the AVX-512 kernel's layers).
__attribute__((target("avx512f,avx2,fma"))) HBRDF_INLINE __m512 activate16(Activation a, __m512 x) {
    HBRDF_ACTIVATE_BODY(_mm512_set1_ps, _mm512_add_ps, _mm512_max_ps, _mm512_min_ps, _mm512_mul_ps)
}
#undef HBRDF_ACTIVATE_BODY

/// exp(x) on 8 lanes for the combine step, within about 1 ulp of the exact value: Cody-Waite
/// reduction x = n ln2 + r (ln2 split in a 9-bit head and a tail, so n * head is exact),
/// Cephes' degree-6 polynomial for e^r on |r| <= ln2/2, and 2^n applied as two halves so that
/// results in the denormal range (x down to -103.9) and the overflow to +inf (x > 88.72) come
/// out as expf gives them. Inputs are finite (the loader bounds every network value).
__attribute__((target("avx2,fma"))) HBRDF_INLINE __m256 exp8(__m256 x) {
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

/// combine(Gated, o, g, fa, bound) on 8 lanes: exp(min(o, bound)) + sigmoid(g) fa (paper Eq. 1),
/// with exp8 for both exponentials and the product added by one FMA.
__attribute__((target("avx2,fma"))) HBRDF_INLINE __m256 combine_gated8(__m256 o, __m256 g, __m256 fa,
                                                                       __m256 bound) {
    const __m256 one = _mm256_set1_ps(1.0f);
    const __m256 fc = exp8(_mm256_min_ps(o, bound));
    const __m256 gate = _mm256_div_ps(one, _mm256_add_ps(one, exp8(_mm256_sub_ps(_mm256_setzero_ps(), g))));
    return _mm256_fmadd_ps(gate, fa, fc);
}

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#endif  // HBRDF_SIMD_X86

}  // namespace hbrdf::detail
