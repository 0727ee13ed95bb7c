// hybridbrdf renderer — delta lights: point and directional lights, the lights
// an engine's forward or deferred pass evaluates per pixel (issue 59). They sit
// beside the environment light; a path reaches them only by next-event
// estimation (a delta distribution is never hit by a sampled direction).
//
// Units follow pbrt-v4's PointLight / DistantLight:
//   point        radiant intensity I (per colour channel, W/sr): the radiance a
//                surface at distance d reflects is f(wo, wi) I cos(theta_i) / d^2
//   directional  irradiance E on a surface facing the light: the reflected
//                radiance is f(wo, wi) E cos(theta_i), wi the same everywhere
// Scene file: "lights": [{"type": "point", "position": [x, y, z], "intensity": [r, g, b]},
//                        {"type": "directional", "direction": [x, y, z], "irradiance": [r, g, b]}]
// with "direction" pointing from the scene TOWARD the light (normalised on load).
#pragma once

#include <vector>

#include "hybridbrdf/render/frame.hpp"

namespace hbrdf::render {

struct PointLight {
    Vec3f position{0.0f};
    Vec3f intensity{0.0f};  ///< radiant intensity, W/sr per channel
};

struct DirectionalLight {
    Vec3f direction{0.0f, 1.0f, 0.0f};  ///< unit, from the scene toward the light
    Vec3f irradiance{0.0f};            ///< on a surface facing the light, per channel
};

/// The scene's delta lights.
struct DeltaLights {
    std::vector<PointLight> points;
    std::vector<DirectionalLight> directionals;

    bool empty() const { return points.empty() && directionals.empty(); }
};

}  // namespace hbrdf::render
