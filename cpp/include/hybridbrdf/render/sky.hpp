// hybridbrdf renderer — a procedural HDR sky baked into an equirectangular
// image, so that it is lit and importance-sampled by the same code as a
// captured environment map (environment.hpp), and a demo needs no file.
//
// The model is deliberately simple and fully specified here (it is a test
// light, not a physical atmosphere):
//   sky(d)    = sky_intensity * mix(horizon, zenith, sqrt(max(d.y, 0)))         above the horizon
//               + sky_intensity * haze * aureole * exp(-angle(d, sun) / 0.2)      (a glow around the sun)
//   ground(d) = sky_intensity * ground_albedo * horizon * 0.5                   below the horizon
//   sun(d)    = sun_irradiance / Omega_sun inside a disk of angular diameter sun_size_deg
// where haze = (turbidity - 1) / 9 turns the zenith colour (0.20, 0.40, 0.90)
// and the horizon colour (0.75, 0.85, 1.00) toward white (0.9, 0.9, 0.9).
// `sun_irradiance` is the irradiance the disk delivers to a surface facing it
// (RGB, W m^-2 in arbitrary units): texels the disk covers partly are
// supersampled 8 x 8, so the baked image reproduces it to within ~1%.
#pragma once

#include <string>

#include "hybridbrdf/render/image.hpp"
#include "hybridbrdf/render/frame.hpp"

namespace hbrdf::render {

struct SkyParams {
    float sun_elevation_deg = 35.0f;   ///< above the horizon
    float sun_azimuth_deg = 60.0f;     ///< from -z toward +x (the equirect u axis)
    Vec3f sun_irradiance{30.0f, 28.0f, 25.0f};
    float sun_size_deg = 2.0f;         ///< angular diameter of the disk
    float sky_intensity = 1.0f;
    float turbidity = 3.0f;            ///< [1, 10]: 1 = deep blue, 10 = white haze
    Vec3f ground_albedo{0.3f, 0.3f, 0.3f};
    int width = 1024, height = 512;

    /// Unit world direction toward the sun centre.
    Vec3f sun_direction() const;
};

/// The first parameter of a sky that is out of range: `key` is its name in a
/// scene file ("turbidity", "sun_irradiance[1]", "resolution"), `problem` the
/// reason ("must be in [1, 10], got 12"). Both empty when all are in range.
/// The resolution must be at least 4 x 2 and at most kMaxEnvironmentTexels
/// (limits.hpp), radiances and albedos >= 0, every number finite.
struct SkyProblem {
    std::string key, problem;
};
SkyProblem check_sky(const SkyParams& params);

/// Bakes the sky into an equirect image with the mapping of EnvironmentLight
/// (before any rotation). Throws std::invalid_argument "<key>: <problem>"
/// (check_sky) for out-of-range parameters, before allocating the image.
Image make_sky_image(const SkyParams& params);

}  // namespace hbrdf::render
