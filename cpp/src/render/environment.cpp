// hybridbrdf renderer — equirectangular environment light with importance sampling.
#include "hybridbrdf/render/environment.hpp"

#include "hybridbrdf/warp.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "hybridbrdf/render/limits.hpp"

namespace hbrdf::render {

namespace {

constexpr float kTwoPi = 2.0f * kPi<float>;

float luminance(const float* rgb) { return 0.2126f * rgb[0] + 0.7152f * rgb[1] + 0.0722f * rgb[2]; }

}  // namespace

EnvironmentLight::EnvironmentLight(Image radiance, float scale, float rotation_deg) : image_(std::move(radiance)) {
    if (image_.width <= 0 || image_.height <= 0) throw std::invalid_argument("environment image has no pixels");
    const std::string too_big = check_image_size(image_.width, image_.height, kMaxEnvironmentTexels,
                                                 kEnvironmentBytesPerTexel, "with its sampling tables");
    if (!too_big.empty()) throw std::invalid_argument("the environment map is " + too_big);
    if (!(scale >= 0.0f) || !is_finite(scale))
        throw std::invalid_argument("scale: must be a finite number >= 0, got " + format_number(scale));
    // Every texel must be a radiance: finite and >= 0. Zeroing the others (as this did) rendered a
    // map with one +Inf texel (a clipped sun) without its sun, and an all-NaN or all-negative map
    // black, with exit 0; a value cannot be repaired without knowing what it should have been, so
    // the map is refused, naming the first such texel (the loader adds the file's name).
    float brightest = 0.0f;
    const std::size_t texels = std::size_t(image_.width) * std::size_t(image_.height);
    for (std::size_t i = 0; i < texels; ++i) {
        for (int c = 0; c < 3; ++c) {
            const float v = image_.rgb[3 * i + std::size_t(c)];
            if (!is_finite(v) || v < 0.0f) {
                const char* channel = c == 0 ? "R" : c == 1 ? "G" : "B";
                throw std::invalid_argument(
                    "texel (" + std::to_string(i % std::size_t(image_.width)) + ", " +
                    std::to_string(i / std::size_t(image_.width)) + ") " + channel + " = " + format_number(v) +
                    (is_finite(v) ? " is negative" : " is not finite") +
                    "; an environment map's texels must be finite radiances >= 0 (docs/RENDERING.md, \"Environments\")");
            }
            brightest = std::max(brightest, v);
        }
    }
    // A scale that overflows float would make texels infinite (and the image black, where non-finite samples are dropped).
    if (!is_finite(brightest * scale))
        throw std::invalid_argument("scale: " + format_number(scale) + " x the brightest texel (" +
                                    format_number(brightest) + ") overflows float");
    if (brightest * scale > kMaxEnvironmentRadiance)
        throw std::invalid_argument("the brightest texel x scale is " + format_number(brightest * scale) +
                                    ", above the limit " + format_number(kMaxEnvironmentRadiance) +
                                    " (a pixel's samples would overflow float32)");
    brightest_ = brightest * scale;
    for (float& v : image_.rgb) v *= scale;
    const double rot = double(rotation_deg) * 3.14159265358979323846 / 180.0;
    cos_rot_ = float(std::cos(rot));
    sin_rot_ = float(std::sin(rot));
    // Sampling (u, v) uniformly would put too many samples near the poles,
    // where texels cover little solid angle: weigh each row by sin(theta) at
    // its centre, the Jacobian of the equirect map (d omega = 2 pi^2 sin(theta) du dv).
    const int w = image_.width, h = image_.height;
    std::vector<float> weights(std::size_t(w) * std::size_t(h));
    for (int y = 0; y < h; ++y) {
        const float sin_theta = std::sin(kPi<float> * (float(y) + 0.5f) / float(h));
        for (int x = 0; x < w; ++x)
            weights[std::size_t(y) * std::size_t(w) + std::size_t(x)] = luminance(image_.at(x, y)) * sin_theta;
    }
    distribution_ = Distribution2D(weights, w, h);
}

Vec2<float> EnvironmentLight::direction_to_uv(const Vec3f& d) const {
    // World -> map frame: rotate by -rotation about +y.
    const float mx = cos_rot_ * d.x - sin_rot_ * d.z;
    const float mz = sin_rot_ * d.x + cos_rot_ * d.z;
    const float theta = std::acos(std::clamp(d.y, -1.0f, 1.0f));
    float phi = std::atan2(mx, -mz);
    if (phi < 0.0f) phi += kTwoPi;
    return Vec2<float>(std::min(phi / kTwoPi, kOneMinusEps<float>), std::min(theta * kInvPi<float>, kOneMinusEps<float>));
}

Vec3f EnvironmentLight::uv_to_direction(const Vec2<float>& uv) const {
    const float theta = uv.y * kPi<float>, phi = uv.x * kTwoPi;
    const float s = std::sin(theta);
    const float mx = s * std::sin(phi), my = std::cos(theta), mz = -s * std::cos(phi);
    // Map -> world: rotate by +rotation about +y.
    return Vec3f(cos_rot_ * mx + sin_rot_ * mz, my, -sin_rot_ * mx + cos_rot_ * mz);
}

Vec3f EnvironmentLight::eval(const Vec3f& d) const {
    const Vec2<float> uv = direction_to_uv(d);
    const int x = std::min(image_.width - 1, int(uv.x * float(image_.width)));
    const int y = std::min(image_.height - 1, int(uv.y * float(image_.height)));
    const float* p = image_.at(x, y);
    return Vec3f(p[0], p[1], p[2]);
}

LightSample EnvironmentLight::sample(const Vec2<float>& u) const {
    LightSample s;
    float pdf_uv = 0;
    const Vec2<float> uv = distribution_.sample(u, &pdf_uv);
    const float sin_theta = std::sin(uv.y * kPi<float>);
    if (!(pdf_uv > 0.0f) || !(sin_theta > 0.0f)) return s;
    s.wi = uv_to_direction(uv);
    s.pdf = pdf_uv / (2.0f * kPi<float> * kPi<float> * sin_theta);
    s.radiance = eval(s.wi);
    return s;
}

float EnvironmentLight::pdf(const Vec3f& d) const {
    const Vec2<float> uv = direction_to_uv(d);
    // From x and z rather than sqrt(1 - y^2), which cancels near the poles.
    const float sin_theta = std::sqrt(d.x * d.x + d.z * d.z);
    if (!(sin_theta > 0.0f)) return 0.0f;
    return distribution_.pdf(uv) / (2.0f * kPi<float> * kPi<float> * sin_theta);
}

}  // namespace hbrdf::render
