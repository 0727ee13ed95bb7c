// hybridbrdf — the process-wide cap on the batched kernels' instruction set.
//
// HBRDF_SIMD=baseline|avx2+fma|avx512 (unset or avx512: no cap) caps every batched kernel
// (f_a, sampling, the model's layers) for the whole process, below what the CPU offers. It
// exists so that a speed regression test can prove it fails when the vector kernels are
// lost (bench/speed_guard.py), and so that a user can rule the vector kernels in or out
// when chasing a numerical difference, without a rebuild.
#pragma once

namespace hbrdf {

/// 0 baseline, 1 avx2+fma, 2 avx512 (no cap); read once from HBRDF_SIMD. An unknown value is
/// reported on stderr once and ignored.
int simd_environment_cap();

}  // namespace hbrdf
