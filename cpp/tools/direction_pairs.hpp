// hybridbrdf — the input of the native throughput benchmarks (hbrdf_bench and the speed guard's
// driver): cosine-weighted direction pairs, as in fitting and metrics, and uniform 2-D samples,
// drawn from one seeded generator so that both time their kernels on the same data.
#pragma once

#include <cstddef>
#include <random>
#include <vector>

#include "hybridbrdf/hybridbrdf.hpp"

namespace hbrdf::bench {

struct DirectionPairs {
    std::vector<float> wi, wo;  // n x 3 each (array of structures)
    std::vector<float> soa;     // the same pairs as six planes of n: wi.x, wi.y, wi.z, wo.x, wo.y, wo.z
    std::vector<float> u;       // n x 2 uniform samples in [0, 1)
};

inline DirectionPairs cosine_direction_pairs(std::size_t n, unsigned seed = 7) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> uni(0.f, 1.f);
    DirectionPairs d{std::vector<float>(3 * n), std::vector<float>(3 * n), std::vector<float>(6 * n),
                     std::vector<float>(2 * n)};
    for (std::size_t i = 0; i < n; ++i) {
        const auto a = square_to_cosine_hemisphere(Vec2<float>(uni(rng), uni(rng)));
        const auto b = square_to_cosine_hemisphere(Vec2<float>(uni(rng), uni(rng)));
        for (int c = 0; c < 3; ++c) {
            d.wi[3 * i + c] = a[c];
            d.wo[3 * i + c] = b[c];
            d.soa[c * n + i] = a[c];
            d.soa[(3 + c) * n + i] = b[c];
        }
        d.u[2 * i] = uni(rng);
        d.u[2 * i + 1] = uni(rng);
    }
    return d;
}

}  // namespace hbrdf::bench
