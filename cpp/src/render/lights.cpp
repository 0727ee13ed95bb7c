// hybridbrdf renderer — the scene file's delta lights (light.hpp; docs/RENDERING.md, "Lights").
#include <cmath>
#include <string>

#include "scene_reader.hpp"

namespace hbrdf::render::detail {

namespace {

// Every light costs a shadow ray and a BRDF evaluation at every surface interaction: a scene of
// an engine's handful of lights renders, one of a million would take hours for no picture.
constexpr std::size_t kMaxDeltaLights = 1024;

PointLight read_point(const SceneReader& r, const json& l, const std::string& w) {
    r.check_keys(l, w, {"type", "position", "intensity"});
    PointLight p;
    p.position = r.vec<3>(r.require(l, w, "position"), w + ".position");
    // The shadow ray and 1 / d^2 are formed in float: keep the light where geometry may be.
    for (int i = 0; i < 3; ++i)
        if (!(std::fabs(p.position[i]) <= float(kMaxCoordinate)))
            r.fail(w + ".position[" + std::to_string(i) + "]", "must be within +-" + format_number(kMaxCoordinate) +
                                                                  " (limits.hpp, kMaxCoordinate), got " + format_number(p.position[i]));
    r.require(l, w, "intensity");
    p.intensity = r.nonnegative_vec<3>(l, w, "intensity", Vec3f(0.0f));
    return p;
}

DirectionalLight read_directional(const SceneReader& r, const json& l, const std::string& w) {
    r.check_keys(l, w, {"type", "direction", "irradiance"});
    const Vec3f d = r.vec<3>(r.require(l, w, "direction"), w + ".direction");
    // In double: a direction of 1e-30 components is a direction, and its float square underflows.
    const double len = std::sqrt(double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z);
    if (!(len > 0.0)) r.fail(w + ".direction", "must not be zero (it points from the scene toward the light)");
    DirectionalLight dl;
    dl.direction = Vec3f(float(d.x / len), float(d.y / len), float(d.z / len));
    r.require(l, w, "irradiance");
    dl.irradiance = r.nonnegative_vec<3>(l, w, "irradiance", Vec3f(0.0f));
    return dl;
}

}  // namespace

DeltaLights read_lights(const SceneReader& r, const json& lights) {
    if (!lights.is_array()) r.fail("lights", "expected an array of lights");
    if (lights.size() > kMaxDeltaLights)
        r.fail("lights", std::to_string(lights.size()) + " lights, above the limit of " + std::to_string(kMaxDeltaLights) +
                             " (each costs a shadow ray and a BRDF evaluation at every surface interaction)");
    DeltaLights out;
    for (std::size_t i = 0; i < lights.size(); ++i) {
        const std::string w = "lights[" + std::to_string(i) + "]";
        const json& l = lights[i];
        if (!l.is_object()) r.fail(w, "expected an object");
        const std::string type = r.string(r.require(l, w, "type"), w + ".type");
        if (type == "point") out.points.push_back(read_point(r, l, w));
        else if (type == "directional") out.directionals.push_back(read_directional(r, l, w));
        else r.fail(w + ".type", "unknown light type '" + type + "'; expected point or directional");
    }
    return out;
}

}  // namespace hbrdf::render::detail
