// hybridbrdf renderer — the environment light: an equirectangular radiance
// map at infinity, importance-sampled in proportion to luminance x sin(theta).
//
// Mapping (world +y is up): theta = acos(d.y) in [0, pi] from the zenith,
// phi = atan2(d.x, -d.z) in [0, 2 pi), u = phi / (2 pi) across the image,
// v = theta / pi down the image. So the image's top row is the zenith and its
// left/right edge the -z direction, u = 1/4 the +x direction. `rotation_deg`
// turns the map about +y (positive = counter-clockwise seen from above).
//
// Radiance is piecewise constant per texel (nearest lookup), which makes the
// sampling density exactly proportional to luminance where it is non-zero.
#pragma once

#include "hybridbrdf/render/distribution.hpp"
#include "hybridbrdf/render/frame.hpp"
#include "hybridbrdf/render/image.hpp"

namespace hbrdf::render {

/// A direction sampled toward the environment.
struct LightSample {
    Vec3f wi;         ///< world direction toward the light (unit)
    float pdf = 0;    ///< solid-angle density, 0 = no sample
    Vec3f radiance;   ///< L(wi)
};

class EnvironmentLight {
public:
    EnvironmentLight() = default;
    /// `radiance` is multiplied by `scale`; throws std::invalid_argument for an empty image and
    /// for a texel that is not finite or is negative ("texel (x, y) R = inf is not finite; ...").
    EnvironmentLight(Image radiance, float scale = 1.0f, float rotation_deg = 0.0f);

    /// L(d) for a world direction d (unit).
    Vec3f eval(const Vec3f& d) const;
    /// Samples a direction from u in [0, 1)^2.
    LightSample sample(const Vec2<float>& u) const;
    /// Solid-angle density of sample() at world direction d.
    float pdf(const Vec3f& d) const;

    /// Equirect (u, v) of a world direction, and back (d unit).
    Vec2<float> direction_to_uv(const Vec3f& d) const;
    Vec3f uv_to_direction(const Vec2<float>& uv) const;

    const Image& image() const { return image_; }
    /// The brightest texel component after the scale (<= kMaxEnvironmentRadiance).
    float brightest() const { return brightest_; }

private:
    Image image_;
    Distribution2D distribution_;
    float cos_rot_ = 1, sin_rot_ = 0;
    float brightest_ = 0;
};

}  // namespace hbrdf::render
