// hybridbrdf — a test hook over the model contract's per-value math, internal to libhybridbrdf
// (bound as hybridbrdf._core._contract_math for tests/python/test_contract_table_cpp.py, which
// checks spec/activation_combine.json on both inference paths).
#pragma once

#include <cstddef>
#include <string>

namespace hbrdf::detail {

/// Values per row for contract_math's `kind`: 1 (x) for "activation", 4 (o, g, fa, bound) for
/// "combine". Throws std::invalid_argument for another kind.
int contract_math_arity(const std::string& kind);

/// The contract's activation `name` (relu, hardgelu) or combine rule `name` (gated, additive,
/// logmul, exp) on n rows of `in` (contract_math_arity(kind) values each), one result per row
/// in `out`. path "scalar": model_math.hpp's activate() / combine(), as HybridModel::eval runs
/// them; "batched": the per-lane functions the batched kernel model_simd_path() names runs
/// (limit_model_simd caps it), on lanes filled with consecutive rows, the last block padded.
/// Throws std::invalid_argument for an unknown kind, name or path.
void contract_math(const std::string& kind, const std::string& name, const std::string& path, std::size_t n,
                   const float* in, float* out);

}  // namespace hbrdf::detail
