// hybridbrdf renderer — the scene loader's JSON reader (private to cpp/src/render): reads values
// out of a scene's JSON tree, every failure a FileError "<origin>: <JSON path>: <problem>". Shared
// by the parts of the loader that live in their own files (scene_loader.cpp, lights.cpp,
// gltf_scene.cpp), so that every part refuses bad input with the same one-line errors.
#pragma once

#include <nlohmann/json.hpp>

#include <array>
#include <cctype>
#include <cfloat>
#include <climits>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <set>
#include <string>
#include <vector>

#include "hybridbrdf/render/frame.hpp"
#include "hybridbrdf/render/image.hpp"
#include "hybridbrdf/render/limits.hpp"

namespace hbrdf::render::detail {

using json = nlohmann::json;

// Reads values out of the JSON tree; every failure names the origin and the
// JSON path of the offending value.
class SceneReader {
public:
    SceneReader(std::string origin, std::string base_dir) : origin_(std::move(origin)), base_dir_(std::move(base_dir)) {}

    [[noreturn]] void fail(const std::string& where, const std::string& problem) const {
        throw FileError(origin_, where.empty() ? problem : where + ": " + problem);
    }

    // Rejects keys outside `allowed` (typos would otherwise be silently ignored).
    // Keys starting with '_' and "comment" are free text.
    void check_keys(const json& obj, const std::string& where, const std::vector<std::string>& allowed) const {
        if (!obj.is_object()) fail(where, "expected an object");
        const std::set<std::string> ok(allowed.begin(), allowed.end());
        for (const auto& item : obj.items()) {
            const std::string& k = item.key();
            if (k.empty() || k[0] == '_' || k == "comment" || ok.count(k)) continue;
            std::string list;
            for (const std::string& a : allowed) list += (list.empty() ? "" : ", ") + a;
            fail(join(where, k), "unknown key '" + k + "' (expected one of: " + list + ")");
        }
    }
    void check_keys(const json& obj, const std::string& where, std::initializer_list<const char*> allowed) const {
        check_keys(obj, where, std::vector<std::string>(allowed.begin(), allowed.end()));
    }

    static std::string join(const std::string& where, const std::string& key) {
        return where.empty() ? key : where + "." + key;
    }

    const json& require(const json& obj, const std::string& where, const char* key) const {
        if (!obj.contains(key)) fail(where, std::string("missing key '") + key + "'");
        return obj.at(key);
    }

    float number(const json& v, const std::string& where) const {
        if (!v.is_number()) fail(where, "expected a number, got " + std::string(v.type_name()));
        const double d = v.get<double>();
        if (!std::isfinite(d)) fail(where, "expected a finite number");
        // Scene numbers are floats: 1e300 would become inf.
        if (std::fabs(d) > double(FLT_MAX)) fail(where, "must be within +-" + format_number(FLT_MAX) + ", got " + v.dump());
        return float(d);
    }
    // A number that must be >= 0 (scales, radiances: no negative light).
    float nonnegative(const json& obj, const std::string& where, const char* key, float def) const {
        const float x = number(obj, where, key, def);
        if (!(x >= 0.0f)) fail(join(where, key), "must be >= 0, got " + format_number(x));
        return x;
    }
    // Each component >= 0; "key[i]" names the one that is not.
    template <int N>
    glm::vec<N, float> nonnegative_vec(const json& obj, const std::string& where, const char* key,
                                       const glm::vec<N, float>& def) const {
        const glm::vec<N, float> v = vec<N>(obj, where, key, def, true);
        for (int i = 0; i < N; ++i)
            if (!(v[i] >= 0.0f)) {
                const bool array = obj.at(key).is_array();
                fail(join(where, key) + (array ? "[" + std::to_string(i) + "]" : ""), "must be >= 0, got " + format_number(v[i]));
            }
        return v;
    }
    // An array of N JSON integers in [lo, INT_MAX] (image resolutions).
    template <int N>
    std::array<int, N> integers(const json& obj, const std::string& where, const char* key, const std::array<int, N>& def,
                                int lo) const {
        if (!obj.contains(key)) return def;
        const json& v = obj.at(key);
        const std::string w = join(where, key);
        if (!v.is_array() || v.size() != std::size_t(N))
            fail(w, "expected an array of " + std::to_string(N) + " integers");
        std::array<int, N> out{};
        for (int i = 0; i < N; ++i) {
            const json& x = v[std::size_t(i)];
            const std::string wi = w + "[" + std::to_string(i) + "]";
            if (!x.is_number_integer()) fail(wi, "expected an integer, got " + (x.is_number() ? x.dump() : std::string(x.type_name())));
            // Bounded before the conversion, as integer() does.
            if (x.is_number_unsigned() ? x.get<std::uint64_t>() > std::uint64_t(INT_MAX) : x.get<std::int64_t>() > INT_MAX)
                fail(wi, "must be <= " + std::to_string(INT_MAX) + ", got " + x.dump());
            if (!x.is_number_unsigned() && x.get<std::int64_t>() < lo)
                fail(wi, "must be >= " + std::to_string(lo) + ", got " + x.dump());
            out[std::size_t(i)] = int(x.get<std::int64_t>());
        }
        return out;
    }
    float number(const json& obj, const std::string& where, const char* key, float def) const {
        return obj.contains(key) ? number(obj.at(key), join(where, key)) : def;
    }
    int integer(const json& obj, const std::string& where, const char* key, int def) const {
        if (!obj.contains(key)) return def;
        const json& v = obj.at(key);
        if (!v.is_number_integer()) fail(join(where, key), "expected an integer, got " + std::string(v.type_name()));
        // Range-checked before the conversion: get<int>() would wrap 3000000000.
        if (v.is_number_unsigned() ? v.get<std::uint64_t>() > std::uint64_t(INT_MAX) : v.get<std::int64_t>() > INT_MAX)
            fail(join(where, key), "must be <= " + std::to_string(INT_MAX) + ", got " + v.dump());
        if (!v.is_number_unsigned() && v.get<std::int64_t>() < INT_MIN)
            fail(join(where, key), "must be >= " + std::to_string(INT_MIN) + ", got " + v.dump());
        return int(v.get<std::int64_t>());
    }
    bool boolean(const json& obj, const std::string& where, const char* key, bool def) const {
        if (!obj.contains(key)) return def;
        if (!obj.at(key).is_boolean()) fail(join(where, key), "expected true or false");
        return obj.at(key).get<bool>();
    }
    std::string string(const json& v, const std::string& where) const {
        if (!v.is_string()) fail(where, "expected a string, got " + std::string(v.type_name()));
        return v.get<std::string>();
    }
    // Fixed-length number array; a single number is broadcast when allowed.
    template <int N> glm::vec<N, float> vec(const json& v, const std::string& where, bool broadcast = false) const {
        glm::vec<N, float> out(0.0f);
        if (broadcast && v.is_number()) return glm::vec<N, float>(number(v, where));
        if (!v.is_array() || v.size() != std::size_t(N))
            fail(where, "expected an array of " + std::to_string(N) + " numbers" + (broadcast ? " or a number" : ""));
        for (int i = 0; i < N; ++i) out[i] = number(v[std::size_t(i)], where + "[" + std::to_string(i) + "]");
        return out;
    }
    template <int N>
    glm::vec<N, float> vec(const json& obj, const std::string& where, const char* key, const glm::vec<N, float>& def,
                           bool broadcast = false) const {
        return obj.contains(key) ? vec<N>(obj.at(key), join(where, key), broadcast) : def;
    }

    // Paths in the scene are relative to its folder; "synthetic:..." is not a path.
    std::string resolve(const std::string& p) const {
        if (p.empty() || p[0] == '/' || p.rfind("synthetic:", 0) == 0 || base_dir_.empty()) return p;
        return base_dir_ + "/" + p;
    }

    const std::string& origin() const { return origin_; }

private:
    std::string origin_, base_dir_;
};

}  // namespace hbrdf::render::detail

// ---- the loader's parts that live in files of their own ---------------------------------------
#include <map>
#include <memory>
#include <optional>

#include "hybridbrdf/params.hpp"
#include "hybridbrdf/render/light.hpp"
#include "hybridbrdf/render/gltf_material.hpp"
#include "hybridbrdf/render/mesh.hpp"

namespace hbrdf::render::detail {

/// The scene's top-level "lights" array (light.hpp; lights.cpp), every value checked with
/// `r`'s one-line errors ("lights[1].intensity[2]: must be >= 0, got -1").
DeltaLights read_lights(const SceneReader& r, const json& lights);

/// A glTF material as f_a (gltf_scene.cpp; the mapping of docs/GLTF.md): its factors' f_a and,
/// when it has them, its textures (gltf_material.hpp).
struct GltfFa {
    std::string name;        ///< the glTF material's name ("" when it has none)
    AnalyticParams params;   ///< the factors' f_a
    GltfFactors factors;
    float rotation = 0.0f;   ///< KHR_materials_anisotropy's anisotropyRotation, radians
    std::optional<GltfTexture> base_color, metallic_roughness;
    std::optional<GltfNormalTexture> normal;
    bool textured() const { return base_color || metallic_roughness || normal; }
};

/// The triangles of one glTF material, node transforms applied (world = the asset's root space).
struct GltfPart {
    TriangleMesh mesh;
    int material = -1;  ///< index into GltfAsset::materials; -1 = glTF's default material
};

struct GltfAsset {
    std::vector<GltfFa> materials;  ///< in the asset's order
    std::vector<GltfPart> parts;
};

/// A glTF asset larger than this is refused before it is read (it is held in memory twice).
inline constexpr std::uint64_t kMaxGltfBytes = std::uint64_t(1) << 30;
/// A glTF image's bounds, checked from its header before it is decoded (the Python reader's).
inline constexpr int kMaxGltfImageSide = 16384;
inline constexpr std::uint64_t kMaxGltfImageTexels = std::uint64_t(1) << 26;
/// The longest data: URI read (characters).
inline constexpr std::size_t kMaxGltfDataUri = std::size_t(16) << 20;

/// RFC 4648 base64 (and its URL-safe alphabet); padding and whitespace skipped.
std::string base64_decode(const std::string& text);

/// A glTF asset's images and textures as its materials' slots read them (gltf_textures.cpp): each
/// image bounded from its header, then decoded once. Errors are `r`'s one line at the JSON path.
class GltfImages {
public:
    /// `buffers`: each buffer's bytes (checked: every buffer view lies inside its buffer).
    GltfImages(const SceneReader& r, const json& doc, const std::vector<std::string>& buffers, std::string folder);
    /// The texture of textureInfo `owner[key]` (at `w_owner`), nullopt when absent; `srgb` for
    /// baseColorTexture. Refuses texCoord other than 0 and KHR_texture_transform.
    std::optional<GltfTexture> texture(const json& owner, const char* key, const std::string& w_owner, bool srgb);

private:
    const SceneReader& r_;
    const json& doc_;
    const std::vector<std::string>& buffers_;
    std::string folder_;
    std::map<std::uint64_t, std::shared_ptr<const GltfImage>> cache_;
    // Mip chains by (image, sRGB): one image may serve an sRGB and a linear slot.
    std::map<std::pair<std::uint64_t, bool>, std::shared_ptr<const std::vector<GltfImage>>> chains_;
    std::string encoded(const json& image, const std::string& w, std::string& type) const;
    std::shared_ptr<const GltfImage> image(std::uint64_t index, const std::string& w_source);
};

/// The glTF material `m` (JSON, at `w` for errors) mapped onto f_a.
GltfFa gltf_material_to_fa(const SceneReader& r, const json& m, const std::string& w);

/// Reads a .gltf or .glb file, bounded before assimp sees it. Throws FileError "<path>: <JSON
/// path>: <problem>" (one line).
GltfAsset read_gltf(const std::string& path);

/// Turns `mesh`'s tangents by `angle` about their vertex normals, toward the bitangent w n x t. False (the mesh
/// unchanged) when it has no tangents or no vertex normals.
bool rotate_tangents(TriangleMesh& mesh, float angle);

/// `s` with its ASCII letters in lower case (glTF's URI schemes and file extensions are
/// case-insensitive).
inline std::string ascii_lower(std::string s) {
    for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

}  // namespace hbrdf::render::detail
