// hybridbrdf renderer — the size limits of what a scene may ask for, and
// cancellation.
//
// A scene file is input, and input can be hostile or simply mistyped: a
// 100000 x 100000 camera or a [100000, 50000] sky would otherwise end in
// std::bad_alloc deep inside the renderer, after the operating system has
// been asked for 120 GB. Every size a scene controls that allocates is checked
// against these limits *before* anything is allocated, with an estimate of
// the memory it would take in the error (docs/RENDERING.md, "Limits"). The
// limits are far above real scenes: the film cap admits 16384 x 8192 (8K UHD
// is a quarter of it), the environment cap the largest published HDR maps.
#pragma once

#include <atomic>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace hbrdf::render {

/// Most pixels a camera may have: 2^27 (16384 x 8192), 1.6 GB of float RGB film.
inline constexpr std::uint64_t kMaxFilmPixels = std::uint64_t(1) << 27;
/// Bytes per film pixel: float RGB.
inline constexpr double kFilmBytesPerPixel = 12.0;

/// Most texels an environment map (a file or the baked sky) may have: 2^27
/// (16384 x 8192), about 3.8 GB with its sampling tables.
inline constexpr std::uint64_t kMaxEnvironmentTexels = std::uint64_t(1) << 27;
/// Bytes per environment texel: float RGB, the luminance weights and the
/// sampling distribution (a float and a double per texel).
inline constexpr double kEnvironmentBytesPerTexel = 28.0;

/// Brightest radiance an environment map may hold once scaled (texel x scale): far above any
/// real sky (the sun's disc is ~1e9 in these units), and 1.7e18 below FLT_MAX, the headroom for
/// what a path's throughput and the sum of a pixel's samples multiply it by. Above it, a pixel
/// that sums spp such samples in float32 can reach +Inf (1.69e38 x 16 spp did, with exit 0).
inline constexpr float kMaxEnvironmentRadiance = 1e20f;

/// Most bytes the tabulated sampler's tables of all a scene's materials may take together
/// (`"sampler": "tabulated"` builds one per material, at scene load): 1 GiB. At the default
/// 1-degree resolution a table is 2.9 MB (isotropic) or 210 MB (anisotropic), so a scene may hold
/// 5 anisotropic or ~360 isotropic tabulated materials; without the budget a 763-byte scene of
/// 100 anisotropic materials would ask for ~21 GB and half an hour of building. Checked, from the
/// sizes TabulatedSampler::table_bytes() computes, before any table is built.
inline constexpr std::uint64_t kMaxTabulatedSamplerBytes = std::uint64_t(1) << 30;

/// Most worker threads a render may start (also the settings table's bound).
inline constexpr int kMaxThreads = 1024;

/// "120 GB", "3.2 GB", "805 MB": a byte count to two or three significant
/// digits in decimal units, for error messages.
std::string format_bytes(double bytes);

/// A number for an error message, "%g" with up to 6 significant digits ("-1", "1e+30").
std::string format_number(double x);

/// "" when a width x height image fits `max_pixels`, else the problem, e.g.
/// "100000 x 100000 = 10000000000 pixels need ~120 GB of film (limit
/// 134217728 pixels, e.g. 16384 x 8192)", where `what` is "of film". Width
/// and height are 64-bit so that the product of two ints cannot overflow.
std::string check_image_size(std::int64_t width, std::int64_t height, std::uint64_t max_pixels, double bytes_per_pixel,
                             const char* what);

/// Thrown by render() and load_scene() when their cancellation flag was set
/// (Ctrl-C in the Python front end): nothing more is computed or written.
class Cancelled : public std::runtime_error {
public:
    Cancelled() : std::runtime_error("cancelled") {}
};

/// A flag that another thread sets to stop a render; nullptr = never.
using CancelFlag = const std::atomic<bool>*;

/// Throws Cancelled when `flag` is set.
inline void throw_if_cancelled(CancelFlag flag) {
    if (flag && flag->load(std::memory_order_relaxed)) throw Cancelled();
}

}  // namespace hbrdf::render
