// hybridbrdf — the contract-table test hook (model_contract.hpp): the activations and combine
// rules through the scalar path's functions and through the batched kernels' own per-lane
// functions, at the kernel level eval_batch would run.
#include "model_contract.hpp"

#include <algorithm>
#include <stdexcept>

#include "model_math.hpp"
#include "model_simd.hpp"

namespace hbrdf::detail {
namespace {

template <class Enum, std::size_t N>
Enum named(const char* const (&names)[N], const std::string& name, const char* what) {
    std::string all;
    for (std::size_t i = 0; i < N; ++i) {
        if (name == names[i]) return static_cast<Enum>(i);
        all += std::string(i ? ", " : "") + names[i];
    }
    throw std::invalid_argument(std::string("contract_math: unknown ") + what + " '" + name + "' (expected " + all + ")");
}

// One row of the combine table: (o, g, fa, bound).
HBRDF_INLINE float combine_row(spec::Combine rule, const float* r) { return combine(rule, r[0], r[1], r[2], r[3]); }

// The portable kernel's math, and the scalar path's: model_math.hpp's functions, lane by lane.
void activation_rows(Activation a, std::size_t n, const float* x, float* y) {
    for (std::size_t i = 0; i < n; ++i) y[i] = activate(a, x[i]);
}
void combine_rows(spec::Combine rule, std::size_t n, const float* in, float* out) {
    for (std::size_t i = 0; i < n; ++i) out[i] = combine_row(rule, in + 4 * i);
}

#if HBRDF_SIMD_X86
// Rows [s, s + W) of an arity-k table as W lanes per column (padding lanes 0).
template <int W>
void gather_lanes(const float* in, int k, std::size_t n, std::size_t s, float (*lanes)[W]) {
    for (int c = 0; c < k; ++c)
        for (int l = 0; l < W; ++l) lanes[c][l] = s + l < n ? in[(s + l) * k + c] : 0.f;
}

__attribute__((target("avx2,fma"))) void activation_rows_avx2(Activation a, std::size_t n, const float* x, float* y) {
    for (std::size_t s = 0; s < n; s += 8) {
        float lanes[1][8];
        gather_lanes<8>(x, 1, n, s, lanes);
        _mm256_storeu_ps(lanes[0], activate8(a, _mm256_loadu_ps(lanes[0])));
        std::copy(lanes[0], lanes[0] + std::min<std::size_t>(8, n - s), y + s);
    }
}

__attribute__((target("avx512f,avx2,fma"))) void activation_rows_avx512(Activation a, std::size_t n, const float* x,
                                                                         float* y) {
    for (std::size_t s = 0; s < n; s += 16) {
        float lanes[1][16];
        gather_lanes<16>(x, 1, n, s, lanes);
        _mm512_storeu_ps(lanes[0], activate16(a, _mm512_loadu_ps(lanes[0])));
        std::copy(lanes[0], lanes[0] + std::min<std::size_t>(16, n - s), y + s);
    }
}

// Both vector kernels combine as DenseAvx2 does: the gated rule with combine_gated8, the
// others with model_math.hpp's combine() lane by lane, compiled for the kernel's target.
__attribute__((target("avx2,fma"))) void combine_rows_avx2(spec::Combine rule, std::size_t n, const float* in,
                                                           float* out) {
    if (rule != spec::Combine::Gated) {
        for (std::size_t i = 0; i < n; ++i) out[i] = combine_row(rule, in + 4 * i);
        return;
    }
    for (std::size_t s = 0; s < n; s += 8) {
        float lanes[4][8];
        gather_lanes<8>(in, 4, n, s, lanes);
        const __m256 f = combine_gated8(_mm256_loadu_ps(lanes[0]), _mm256_loadu_ps(lanes[1]),
                                        _mm256_loadu_ps(lanes[2]), _mm256_loadu_ps(lanes[3]));
        _mm256_storeu_ps(lanes[0], f);
        std::copy(lanes[0], lanes[0] + std::min<std::size_t>(8, n - s), out + s);
    }
}
#endif

}  // namespace

int contract_math_arity(const std::string& kind) {
    if (kind == "activation") return 1;
    if (kind == "combine") return 4;
    throw std::invalid_argument("contract_math: unknown kind '" + kind + "' (expected activation, combine)");
}

void contract_math(const std::string& kind, const std::string& name, const std::string& path, std::size_t n,
                   const float* in, float* out) {
    const bool activation = contract_math_arity(kind) == 1;
    if (path != "scalar" && path != "batched")
        throw std::invalid_argument("contract_math: unknown path '" + path + "' (expected scalar, batched)");
    const int level = path == "scalar" ? 0 : model_kernel_level();
    if (activation) {
        const Activation a = named<Activation>(spec::kActivationNames, name, "activation");
#if HBRDF_SIMD_X86
        if (level == 2) return activation_rows_avx512(a, n, in, out);
        if (level == 1) return activation_rows_avx2(a, n, in, out);
#endif
        return activation_rows(a, n, in, out);
    }
    const spec::Combine rule = named<spec::Combine>(spec::kCombineNames, name, "combine rule");
#if HBRDF_SIMD_X86
    if (level >= 1) return combine_rows_avx2(rule, n, in, out);
#endif
    (void)level;
    combine_rows(rule, n, in, out);
}

}  // namespace hbrdf::detail
