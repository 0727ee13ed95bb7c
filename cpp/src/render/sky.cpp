// hybridbrdf renderer — the procedural sky of sky.hpp, baked to an equirect image.
#include "hybridbrdf/render/sky.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "hybridbrdf/render/limits.hpp"

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

// 2 pi (1 - cos r) as 4 pi sin^2(r / 2): 1 - cos r cancels to 0 in float for
// disks under ~0.03 degrees, and the sun's radiance would be infinite.
float sun_solid_angle(float size_deg) {
    const double s = std::sin(0.25 * double(size_deg) * 3.14159265358979323846 / 180.0);
    return float(4.0 * 3.14159265358979323846 * s * s);
}

}  // namespace

Vec3f SkyParams::sun_direction() const {
    const float el = sun_elevation_deg * kDeg, az = sun_azimuth_deg * kDeg;
    // Azimuth measured like the equirect phi: 0 = -z, 90 deg = +x.
    return Vec3f(std::cos(el) * std::sin(az), std::sin(el), -std::cos(el) * std::cos(az));
}

SkyProblem check_sky(const SkyParams& p) {
    auto got = [](float x) { return ", got " + format_number(x); };
    if (p.width < 4 || p.height < 2)
        return {"resolution", "must be at least 4 x 2, got " + std::to_string(p.width) + " x " + std::to_string(p.height)};
    const std::string too_big = check_image_size(p.width, p.height, kMaxEnvironmentTexels, kEnvironmentBytesPerTexel,
                                                 "with its sampling tables");
    if (!too_big.empty()) return {"resolution", too_big};
    // Angles only need to be finite; a sun below the horizon is a valid (dark) sky.
    if (!is_finite(p.sun_elevation_deg)) return {"sun_elevation_deg", "must be finite" + got(p.sun_elevation_deg)};
    if (!is_finite(p.sun_azimuth_deg)) return {"sun_azimuth_deg", "must be finite" + got(p.sun_azimuth_deg)};
    if (!(p.turbidity >= 1.0f && p.turbidity <= 10.0f)) return {"turbidity", "must be in [1, 10]" + got(p.turbidity)};
    if (!(p.sun_size_deg > 0.0f && p.sun_size_deg < 90.0f))
        return {"sun_size_deg", "must be in (0, 90)" + got(p.sun_size_deg)};
    if (!(p.sky_intensity >= 0.0f && is_finite(p.sky_intensity)))
        return {"sky_intensity", "must be a finite number >= 0" + got(p.sky_intensity)};
    for (int c = 0; c < 3; ++c) {
        const std::string i = "[" + std::to_string(c) + "]";
        if (!(p.sun_irradiance[c] >= 0.0f && is_finite(p.sun_irradiance[c])))
            return {"sun_irradiance" + i, "must be a finite number >= 0" + got(p.sun_irradiance[c])};
        if (!(p.ground_albedo[c] >= 0.0f && is_finite(p.ground_albedo[c])))
            return {"ground_albedo" + i, "must be a finite number >= 0" + got(p.ground_albedo[c])};
        if (!is_finite(p.sun_irradiance[c] / sun_solid_angle(p.sun_size_deg)))
            return {"sun_size_deg", "is too small for sun_irradiance: the disk's radiance overflows float" +
                                        got(p.sun_size_deg)};
    }
    return {};
}

Image make_sky_image(const SkyParams& p) {
    const SkyProblem problem = check_sky(p);
    if (!problem.key.empty()) throw std::invalid_argument(problem.key + ": " + problem.problem);

    const float haze = (p.turbidity - 1.0f) / 9.0f;
    const Vec3f white(0.9f), zenith = mix(Vec3f(0.20f, 0.40f, 0.90f), white, haze),
                horizon = mix(Vec3f(0.75f, 0.85f, 1.00f), white, haze);
    const Vec3f ground = p.ground_albedo * horizon * 0.5f;
    const Vec3f sun = p.sun_direction();
    const float radius = 0.5f * p.sun_size_deg * kDeg;
    const float cos_radius = std::cos(radius);
    const float solid_angle = sun_solid_angle(p.sun_size_deg);
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
