// hybridbrdf renderer — the render settings, defined once.
//
// A scene's top-level settings (spp, max_depth, sampler, ...) are the rows of
// one table, kRenderSettings: name, the RenderSettings member that holds the
// value (its type), bounds and a one-line doc. Everything else derives from
// it: the scene loader reads and checks each row (set_setting), RenderOptions
// inherits RenderSettings (a scene's settings become render options by one
// copy), and the Python bindings export the table, from which
// hybridbrdf.render.tracer takes the overrides it accepts and `hbrdf render` its
// flags. A new setting is one member and one row.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <variant>

#include "hybridbrdf/render/limits.hpp"
#include "hybridbrdf/render/material.hpp"

namespace hbrdf::render {

/// The settings a scene file carries at its top level (docs/RENDERING.md).
/// Defaults here are the defaults of a scene file.
struct RenderSettings {
    int spp = 16;
    int max_depth = 8;
    int neural_max_depth = -1;
    float neural_min_throughput = 0.0f;
    SamplerKind sampler = SamplerKind::Mis;
    int tabulated_resolution_deg = 1;
    bool nee = true;
    int rr_depth = -1;
    std::uint64_t seed = 0;
    int threads = 0;
    bool mip_lod = true;
    int anisotropic = 16;
    bool shadows = true;
    bool pixel_jitter = true;
};

/// The member of RenderSettings a setting lives in; the alternative is its type.
using SettingField = std::variant<int RenderSettings::*, std::uint64_t RenderSettings::*, float RenderSettings::*,
                                  bool RenderSettings::*, SamplerKind RenderSettings::*>;

/// A value of a kind no setting takes (a JSON array or null, a Python list),
/// named for the error message.
struct OtherValue {
    std::string type_name;
    friend bool operator==(const OtherValue& a, const OtherValue& b) { return a.type_name == b.type_name; }
};

/// A setting's value as a scene file or a caller states it, before it is
/// checked: JSON and Python scalars map onto these without conversion, so that
/// nothing is narrowed before the bounds are checked.
using SettingValue = std::variant<bool, std::int64_t, std::uint64_t, double, std::string, OtherValue>;

inline constexpr double kUnbounded = std::numeric_limits<double>::infinity();

struct SettingInfo {
    const char* name;
    SettingField field;
    /// Inclusive bounds of a numeric setting (the member's type bounds it as
    /// well); ignored for booleans and samplers.
    double min, max;
    const char* doc;  ///< one line, for --help and the Python table
};

/// Every setting, in the order of the table in docs/RENDERING.md.
inline constexpr SettingInfo kRenderSettings[] = {
    {"spp", &RenderSettings::spp, 1, kUnbounded, "samples per pixel"},
    {"max_depth", &RenderSettings::max_depth, 0, kUnbounded,
     "surface interactions per path (1 = direct light only, 0 = only the environment seen directly)"},
    {"neural_max_depth", &RenderSettings::neural_max_depth, -1, kUnbounded,
     "the network runs at interactions of depth < this (0 = the surface the camera sees); -1 = max_depth"},
    {"neural_min_throughput", &RenderSettings::neural_min_throughput, 0, kUnbounded,
     "the network runs only while the path throughput's largest component is >= this"},
    {"sampler", &RenderSettings::sampler, 0, 0,
     "importance sampling of every material (chosen when the scene is loaded)"},
    {"tabulated_resolution_deg", &RenderSettings::tabulated_resolution_deg, 1, 90,
     "cell size in degrees of the tabulated sampler's tables (divides 90)"},
    {"nee", &RenderSettings::nee, 0, 0, "next-event estimation toward the environment with MIS; false = BSDF sampling only"},
    {"rr_depth", &RenderSettings::rr_depth, -1, kUnbounded, "Russian roulette from this depth on; -1 = never"},
    {"seed", &RenderSettings::seed, 0, kUnbounded, "random seed"},
    {"threads", &RenderSettings::threads, 0, kMaxThreads, "worker threads; 0 = all hardware threads"},
    {"mip_lod", &RenderSettings::mip_lod, 0, 0,
     "textured materials read their mip chains at the camera ray's footprint (ray cones); false = level 0 only"},
    {"anisotropic", &RenderSettings::anisotropic, 1, 64,
     "most probes of the anisotropic texture lookup over the pixel's footprint (ray differentials); 1 = the ray cone's isotropic lookup"},
    {"shadows", &RenderSettings::shadows, 0, 0,
     "point and directional lights cast shadows; false = their shadow rays are skipped (a raster frame's lighting)"},
    {"pixel_jitter", &RenderSettings::pixel_jitter, 0, 0,
     "camera rays jitter over the pixel (a box filter); false = every ray through the pixel centre"},
};

/// The setting called `name`, or nullptr.
const SettingInfo* find_setting(std::string_view name);

/// "int", "float", "bool" or "str": the type of the setting's values, as
/// Python names it (a sampler is given by name).
const char* setting_type(const SettingInfo& info);

/// The value of `info`'s setting in `s` (a sampler as its name).
SettingValue get_setting(const RenderSettings& s, const SettingInfo& info);

/// Checks `v` and stores it in `s`. Integer settings take integers only,
/// compared with the bounds before any conversion (a JSON 3000000000 for an
/// int is out of range, not wrapped); float settings take any finite number.
/// Returns "" on success, else the problem, e.g. "must be >= 1, got 0" or
/// "expected an integer, got a string"; `s` is then unchanged.
std::string set_setting(RenderSettings& s, const SettingInfo& info, const SettingValue& v);

/// Throws std::invalid_argument "<name>: <problem>" for the first setting of
/// `s` outside its bounds (for callers that fill RenderSettings in code).
void check_settings(const RenderSettings& s);

}  // namespace hbrdf::render
