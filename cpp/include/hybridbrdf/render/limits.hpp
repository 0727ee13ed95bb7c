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

/// Geometry is traced in float32 (Embree) while a scene's numbers may be any float, so a scene
/// is refused when float32 cannot place its points to the precision its camera frames them at
/// (a plane of size 3e10 rendered black, one of 1e20 and a sphere of radius 1e20 vanished, with
/// exit 0). With d the camera's distance to its look_at point (the scale of what it frames):
///  - every coordinate of a sphere's bounds (|center| + radius), a plane's corners and a mesh's
///    vertices (after its transform) is at most kMaxExtentOverCameraDistance x d: a coordinate
///    of magnitude M is stored to M 2^-24, and a triangle's hit point sums three such terms, so
///    at 5e4 d a hit point is off by up to 3 x 5e4 x 6e-8 ~ 1% of d (bench/render_float_limits.py:
///    a plane of half-size 4.7e4 d renders 0.46% off one of 120 d; 1e7 / 4.2 d was 7.5% off);
///  - the camera's position is at most kMaxCameraOffsetOverDistance x d from the origin: the
///    tracer starts each bounce 2e-5 |p| off its surface (Scene::offset_origin), so at 500 d from
///    the origin that offset reaches 1% of d (measured: a scene translated by 471 d renders 1.3%
///    off, by 2400 d 4%);
///  - and no coordinate (camera included) exceeds kMaxCoordinate, whatever d: Embree's robust
///    triangle test forms products of three coordinate differences in float, which overflow
///    beyond ~3e12, and it drops primitives beyond +-1.8e18 (its FLT_LARGE) silently.
inline constexpr double kMaxExtentOverCameraDistance = 5e4;
inline constexpr double kMaxCameraOffsetOverDistance = 500.0;
inline constexpr double kMaxCoordinate = 1e12;

/// "" when a point whose largest coordinate magnitude is `extent` fits the limits above for a
/// camera at `camera_distance` from its look_at point, else the problem: "<what> has a coordinate
/// of magnitude 1e+20, above the limit 212132 = 50000 x the camera's distance to its look_at point
/// (4.24264); ...". `what` names the point ("vertex 3 (1e+20, 0, 0)").
std::string check_extent(const std::string& what, double extent, double camera_distance);

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
