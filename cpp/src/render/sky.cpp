// hybridbrdf renderer — the procedural sky of sky.hpp, baked to an equirect image.
#include "hybridbrdf/render/sky.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace hbrdf::render {

namespace {

constexpr float kDeg = 3.14159265358979323846f / 180.0f;

Vec3f mix(const Vec3f& a, const Vec3f& b, float t) { return a + (b - a) * t; }

// Same mapping as EnvironmentLight::uv_to_direction without rotation.
Vec3f equirect_direction(float u, float v) {
    const float theta = v * kPi<float>, phi = u * 2.0f * kPi<float>;
    const float s = std::sin(theta);
    return Vec3f(s * std::sin(phi), std::cos(theta), -s * std::cos(phi));
}

}  // namespace

Vec3f SkyParams::sun_direction() const {
    const float el = sun_elevation_deg * kDeg, az = sun_azimuth_deg * kDeg;
    // Azimuth measured like the equirect phi: 0 = -z, 90 deg = +x.
    return Vec3f(std::cos(el) * std::sin(az), std::sin(el), -std::cos(el) * std::cos(az));
}

Image make_sky_image(const SkyParams& p) {
    if (p.width < 4 || p.height < 2) throw std::invalid_argument("sky resolution must be at least 4 x 2");
    if (!(p.turbidity >= 1.0f && p.turbidity <= 10.0f)) throw std::invalid_argument("sky turbidity must be in [1, 10]");
    if (!(p.sun_size_deg > 0.0f && p.sun_size_deg < 90.0f))
        throw std::invalid_argument("sun_size_deg must be in (0, 90)");
    if (!(p.sky_intensity >= 0.0f)) throw std::invalid_argument("sky_intensity must be >= 0");
    for (int c = 0; c < 3; ++c)
        if (!(p.sun_irradiance[c] >= 0.0f)) throw std::invalid_argument("sun irradiance must be >= 0");

    const float haze = (p.turbidity - 1.0f) / 9.0f;
    const Vec3f white(0.9f), zenith = mix(Vec3f(0.20f, 0.40f, 0.90f), white, haze),
                horizon = mix(Vec3f(0.75f, 0.85f, 1.00f), white, haze);
    const Vec3f ground = p.ground_albedo * horizon * 0.5f;
    const Vec3f sun = p.sun_direction();
    const float radius = 0.5f * p.sun_size_deg * kDeg;
    const float cos_radius = std::cos(radius);
    const float solid_angle = 2.0f * kPi<float> * (1.0f - cos_radius);
    const Vec3f sun_radiance = p.sun_irradiance / solid_angle;

    // Radiance without the disk; the disk is added by coverage below.
    auto sky = [&](const Vec3f& d) -> Vec3f {
        if (d.y < 0.0f) return ground * p.sky_intensity;
        const float angle = std::acos(std::clamp(dot(d, sun), -1.0f, 1.0f));
        const Vec3f base = mix(horizon, zenith, std::sqrt(d.y));
        const Vec3f aureole = Vec3f(1.0f, 0.9f, 0.7f) * (haze * 2.0f * std::exp(-angle / 0.2f));
        return (base + aureole) * p.sky_intensity;
    };

    Image img(p.width, p.height);
    // Texels within this angle of the sun centre may touch the disk.
    const float texel_angle = 2.0f * kPi<float> / float(p.width) + kPi<float> / float(p.height);
    const float cos_near = std::cos(std::min(kPi<float>, radius + 2.0f * texel_angle));
    constexpr int kSuper = 8;
    for (int y = 0; y < p.height; ++y)
        for (int x = 0; x < p.width; ++x) {
            const Vec3f centre = equirect_direction((float(x) + 0.5f) / float(p.width), (float(y) + 0.5f) / float(p.height));
            Vec3f L = sky(centre);
            if (dot(centre, sun) > cos_near) {
                // Fraction of the texel's solid angle the disk covers, by
                // sin(theta)-weighted supersampling inside the texel.
                double covered = 0, total = 0;
                for (int j = 0; j < kSuper; ++j)
                    for (int i = 0; i < kSuper; ++i) {
                        const float v = (float(y) + (float(j) + 0.5f) / kSuper) / float(p.height);
                        const float u = (float(x) + (float(i) + 0.5f) / kSuper) / float(p.width);
                        const Vec3f d = equirect_direction(u, v);
                        const double w = std::sin(double(v) * 3.14159265358979323846);
                        total += w;
                        if (dot(d, sun) >= cos_radius) covered += w;
                    }
                if (total > 0) L += sun_radiance * float(covered / total);
            }
            float* out = img.at(x, y);
            out[0] = L.x;
            out[1] = L.y;
            out[2] = L.z;
        }
    return img;
}

}  // namespace hbrdf::render
