// hybridbrdf renderer — the wavefront path tracer.
//
// Unidirectional path tracing with next-event estimation toward the
// environment light and multiple importance sampling (power heuristic) between
// light and BSDF sampling. Wavefront, not one path at a time: a worker takes a
// tile of pixels and advances all of its paths (pixels x samples of a pass)
// together, one bounce at a time:
//
//     intersect all rays -> (escaped: add environment, MIS-weighted)
//     -> sort hits by material -> sample light + BSDF directions per path
//     -> trace shadow rays -> evaluate every (wi, wo) pair of a material in
//        one batch -> accumulate NEE, update throughputs -> next bounce
//
// so that a material's BRDF is evaluated in batches of hundreds to thousands
// of pairs: the vectorised network (HybridModel::eval_batch) and Python
// callables (measured references, one GIL acquisition per batch) both need
// that to be fast. See docs/RENDERING.md.
//
// Deterministic: random numbers are a hash of (seed, pixel, sample,
// dimension) (rng.hpp), each tile's work does not depend on which thread runs
// it, and every pixel sums its contributions in a fixed order, so images are
// bit-identical for any thread count.
#pragma once

#include <cstdint>

#include "hybridbrdf/render/image.hpp"
#include "hybridbrdf/render/scene.hpp"

namespace hbrdf::render {

struct RenderOptions {
    int spp = 16;                        ///< samples per pixel
    int max_depth = 8;                   ///< surface interactions per path (1 = direct light only)
    /// Selective neural evaluation, rule 1: the network runs at interactions
    /// with depth < neural_max_depth (depth 0 = the surface the camera sees);
    /// deeper ones use f_a. -1 = max_depth (always the network).
    int neural_max_depth = -1;
    /// Rule 2: the network runs only while the path throughput's largest
    /// component is >= this (0 = always). Both rules must allow it.
    float neural_min_throughput = 0.0f;
    int rr_depth = -1;                   ///< Russian roulette from this depth on; -1 = never
    bool nee = true;                     ///< next-event estimation (+ MIS); false = BSDF sampling only
    std::uint64_t seed = 0;
    int threads = 0;                     ///< 0 = all hardware threads
    bool quiet = false;                  ///< no progress bar
    int tile_size = 16;                  ///< tile edge in pixels
    int max_paths_per_wave = 4096;       ///< paths a tile advances together

    /// The options a scene was saved with.
    static RenderOptions from_scene(const SceneSettings& s);
    /// Throws std::invalid_argument naming the first bad option.
    void validate() const;
};

struct RenderStats {
    double seconds = 0;             ///< wall time of render()
    double samples_per_second = 0;  ///< camera samples (pixels x spp) per second
    std::uint64_t rays = 0;         ///< camera + extension rays
    std::uint64_t shadow_rays = 0;
    std::uint64_t brdf_evals = 0;   ///< (wi, wo) pairs evaluated
    std::uint64_t network_evals = 0;  ///< of those, pairs that ran a network
    int threads = 0;
    int tiles = 0;
};

/// Whether the network runs at an interaction of `depth` reached with path
/// throughput `throughput` (the two rules of RenderOptions).
bool use_network(const RenderOptions& options, int depth, const Vec3f& throughput);

/// Renders `scene` (committed) with `options`: the mean radiance per pixel
/// over options.spp samples, linear RGB. Exceptions from materials (e.g. a
/// failing Python callable) stop the render and are rethrown here.
Image render(const Scene& scene, const RenderOptions& options, RenderStats* stats = nullptr);

}  // namespace hbrdf::render
