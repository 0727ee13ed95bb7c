// hbrdf_fma_peak — prints one core's single-precision FMA peak per instruction set and the
// larger one (fma_peak.hpp says how it is measured).
//
//   hbrdf_fma_peak [seconds-per-test]
#include <cstdio>
#include <cstdlib>

#include "fma_peak.hpp"

int main(int argc, char** argv) {
    const double seconds = argc > 1 ? std::atof(argv[1]) : 1.0;
    const hbrdf::fma_peak::Peak p = hbrdf::fma_peak::measure(seconds);
    if (p.avx2_fma > 0.0) std::printf("avx2_fma_gflops %.2f\n", p.avx2_fma);
    if (p.avx512 > 0.0) std::printf("avx512_fma_gflops %.2f\n", p.avx512);
    std::printf("peak_gflops %.2f\n", p.peak());
    return p.peak() > 0.0 ? 0 : 1;
}
