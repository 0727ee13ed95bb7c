// hybridbrdf renderer — the wavefront path tracer.
//
// Unidirectional path tracing with next-event estimation toward the
// environment light and multiple importance sampling (power heuristic) between
// light and BSDF sampling. Wavefront, not one path at a time: a worker takes a
// tile of pixels and advances all of its paths (pixels x samples of a pass)
// together, one bounce at a time:
//
//     intersect all rays -> (escaped: add environment, MIS-weighted)
//     -> sample light + BSDF directions per path -> trace shadow rays
//     -> sort the hits by (material, evaluation mode) with a counting sort
//     -> evaluate every (wi, wo) pair of a material and mode in one batch
//     -> accumulate NEE, update throughputs -> next bounce
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
#include "hybridbrdf/render/limits.hpp"
#include "hybridbrdf/render/scene.hpp"

namespace hbrdf::render {

/// What render() does: the scene's settings (settings.hpp, one definition
/// with the scene format; see there for each member) and options no scene
/// file sets. Selective neural evaluation: the network runs at an interaction
/// when depth < neural_max_depth (rule 1; -1 = max_depth) and the path
/// throughput's largest component is >= neural_min_throughput (rule 2); both
/// must allow it. `sampler` and `tabulated_resolution_deg` act when a scene is
/// loaded (the materials get their samplers then); render() does not read them.
struct RenderOptions : RenderSettings {
    bool quiet = false;                  ///< no progress bar
    int tile_size = 16;                  ///< tile edge in pixels
    int max_paths_per_wave = 4096;       ///< paths a tile advances together
    /// Set by another thread to stop the render (Ctrl-C): render() checks it
    /// before every tile and every wave of a tile, then throws Cancelled.
    CancelFlag cancel = nullptr;

    /// The options a scene was saved with (its settings, the defaults otherwise).
    static RenderOptions from_scene(const RenderSettings& s);
    /// Throws std::invalid_argument naming the first bad option ("spp: must be >= 1, got 0").
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
/// failing Python callable) stop the render and are rethrown here; so is
/// Cancelled, within one wave of options.cancel being set (a wave is at most
/// max_paths_per_wave paths of one tile).
Image render(const Scene& scene, const RenderOptions& options, RenderStats* stats = nullptr);

/// "" when every value of a rendered `image` is finite, else the problem, naming the light that
/// is to blame where the scene has one that bright: "the rendered image holds 256 values that are
/// not finite (the first at pixel (0, 0)): the light along its paths overflows float32 (the
/// environment's brightest radiance is 1e+20)". render() throws it (std::invalid_argument)
/// rather than return such an image, so no output is ever written from it.
std::string film_problem(const Image& image, const Scene& scene);

}  // namespace hbrdf::render
