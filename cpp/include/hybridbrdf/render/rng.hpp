// hybridbrdf renderer — counter-based random numbers.
//
// Every random number the tracer uses is a pure function of
// (seed, pixel, sample, dimension): no generator state travels between
// threads, so an image does not depend on the thread count, the tile order or
// the scheduling, and any single path can be replayed in isolation.
#pragma once

#include <cstdint>

#include "hybridbrdf/math.hpp"

namespace hbrdf::render {

/// Dimensions used per bounce; bounce b uses [b * kDimsPerBounce + 2, ...) after
/// the two camera dimensions (see RandomIndex).
inline constexpr std::uint32_t kDimsPerBounce = 6;

/// What each dimension of a bounce is used for (offsets inside a bounce).
enum Dim : std::uint32_t { kDimLight0 = 0, kDimLight1 = 1, kDimBsdf0 = 2, kDimBsdf1 = 3, kDimRoulette = 4 };

/// A 64-bit finaliser with full avalanche (Stafford's "Mix13" variant of the
/// splitmix64 output function): every input bit flips every output bit with
/// probability ~1/2, which is what a counter-based generator needs.
inline std::uint64_t mix64(std::uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

/// The uniform number in [0, 1) for one (seed, pixel, sample, dimension).
/// The four counters are folded through the mixer one at a time (a sponge), so
/// no two distinct tuples share an input to the final mix unless 64-bit
/// hashes collide.
inline float random_float(std::uint64_t seed, std::uint64_t pixel, std::uint64_t sample, std::uint64_t dim) {
    std::uint64_t h = mix64(seed + 0x9e3779b97f4a7c15ULL);
    h = mix64(h ^ pixel);
    h = mix64(h ^ (sample * 0x9e3779b97f4a7c15ULL));
    h = mix64(h ^ (dim + 0x632be59bd9b4e019ULL));
    // 24 high bits -> exactly representable float in [0, 1).
    return float(h >> 40) * (1.0f / 16777216.0f);
}

/// Binds (seed, pixel, sample) so that a path asks only for dimensions.
struct PathRandom {
    std::uint64_t seed = 0, pixel = 0, sample = 0;
    float camera(int i) const { return random_float(seed, pixel, sample, std::uint64_t(i)); }
    float bounce(int depth, Dim d) const {
        return random_float(seed, pixel, sample, 2 + std::uint64_t(depth) * kDimsPerBounce + d);
    }
};

}  // namespace hbrdf::render
