// Tests of glTF 2.0 objects in the tracer's scenes (docs/RENDERING.md, "glTF objects"). The assets
// are written by the tests (GLB and .gltf, with nlohmann::json and raw little-endian buffers);
// references: the same geometry as the scene format's own plane, node transforms applied by hand
// in double, the metallic-roughness mapping computed in double from the KHR specifications.
#include <doctest/doctest.h>

#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "hybridbrdf/render/render.hpp"

using namespace hbrdf::render;
using json = nlohmann::json;

namespace {

const std::string kGltfSourceDir = HBRDF_SOURCE_DIR;

std::string temp_dir() {
    static const std::string dir = [] {
        char tmpl[] = "/tmp/hbrdf_gltf_XXXXXX";
        REQUIRE(::mkdtemp(tmpl) != nullptr);
        return std::string(tmpl);
    }();
    return dir;
}

// Appends float32 / uint32 values to a little-endian blob; returns the byte offset they start at.
template <typename T> std::size_t append(std::string& blob, const std::vector<T>& values) {
    const std::size_t at = blob.size();
    blob.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
    return at;
}

std::string u32(std::uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); }

std::string glb_bytes(const json& doc, std::string bin) {
    std::string text = doc.dump();
    text.append((4 - text.size() % 4) % 4, ' ');
    bin.append((4 - bin.size() % 4) % 4, '\0');
    std::string body = u32(std::uint32_t(text.size())) + u32(0x4E4F534A) + text;
    if (!bin.empty()) body += u32(std::uint32_t(bin.size())) + u32(0x004E4942) + bin;
    return u32(0x46546C67) + u32(2) + u32(std::uint32_t(12 + body.size())) + body;
}

std::string write_temp(const std::string& name, const std::string& bytes) {
    const std::string path = temp_dir() + "/" + name;
    std::ofstream(path, std::ios::binary) << bytes;
    return path;
}

// One quad primitive: 4 vertices (positions, normals, uvs) and two triangles, accessors 4k..4k+3.
struct Quad {
    std::vector<float> positions, normals, uvs;
    std::vector<std::uint32_t> indices{0, 1, 2, 0, 2, 3};
};

// The scene format's plane of size 4 at the origin facing +y, tangent +x (make_plane's corners,
// uvs and triangles), as a glTF quad.
Quad plane_quad() {
    Quad q;
    q.positions = {-2, 0, 2, 2, 0, 2, 2, 0, -2, -2, 0, -2};
    q.normals = {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0};
    q.uvs = {0, 1, 1, 1, 1, 0, 0, 0};
    return q;
}

// A glTF document holding `quads` (one mesh each, primitive material `materials_of[i]`, -1 none)
// and its binary buffer; the caller adds nodes, scenes and materials.
std::pair<json, std::string> document(const std::vector<Quad>& quads, const std::vector<int>& materials_of) {
    json doc = {{"asset", {{"version", "2.0"}}}, {"meshes", json::array()}, {"accessors", json::array()},
                {"bufferViews", json::array()}};
    std::string bin;
    auto add_view = [&](std::size_t offset, std::size_t length, int count, const char* type, int ctype) {
        doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", length}});
        doc["accessors"].push_back({{"bufferView", doc["bufferViews"].size() - 1}, {"componentType", ctype}, {"count", count}, {"type", type}});
        return doc["accessors"].size() - 1;
    };
    for (std::size_t i = 0; i < quads.size(); ++i) {
        const Quad& q = quads[i];
        float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
        for (std::size_t k = 0; k < q.positions.size(); ++k) {
            lo[k % 3] = std::min(lo[k % 3], q.positions[k]);
            hi[k % 3] = std::max(hi[k % 3], q.positions[k]);
        }
        const auto p = add_view(append(bin, q.positions), q.positions.size() * 4, 4, "VEC3", 5126);
        doc["accessors"][p]["min"] = {lo[0], lo[1], lo[2]};
        doc["accessors"][p]["max"] = {hi[0], hi[1], hi[2]};
        const auto n = add_view(append(bin, q.normals), q.normals.size() * 4, 4, "VEC3", 5126);
        const auto t = add_view(append(bin, q.uvs), q.uvs.size() * 4, 4, "VEC2", 5126);
        const auto x = add_view(append(bin, q.indices), q.indices.size() * 4, 6, "SCALAR", 5125);
        json prim = {{"attributes", {{"POSITION", p}, {"NORMAL", n}, {"TEXCOORD_0", t}}}, {"indices", x}};
        if (materials_of[i] >= 0) prim["material"] = materials_of[i];
        doc["meshes"].push_back({{"primitives", {prim}}});
    }
    doc["buffers"] = {{{"byteLength", bin.size()}}};
    return {doc, bin};
}

// The scene around one object: a 20x16 camera looking down at the origin, a point light and a
// directional light, no environment, one bounce at pixel centres.
std::string scene_with(const std::string& object, const std::string& materials = R"({"m": {"type": "analytic", "kd": [0.3, 0.5, 0.2], "eta": [1.5, 2, 3], "alpha": [0.15, 0.45]}})") {
    return R"({"camera": {"position": [0.4, 3.0, 2.5], "look_at": [0, 0, 0], "fov_deg": 50, "width": 20, "height": 16},
              "environment": {"type": "constant", "radiance": 0},
              "lights": [{"type": "point", "position": [0.3, 1.5, -0.2], "intensity": [2, 3, 4]},
                         {"type": "directional", "direction": [1, 2, -0.5], "irradiance": [1.5, 0.5, 2]}],
              "materials": )" + materials + R"(, "objects": [)" + object + R"(],
              "max_depth": 1, "spp": 1, "pixel_jitter": false, "threads": 2})";
}

Image draw_gltf(const Scene& scene) {
    RenderOptions o = RenderOptions::from_scene(scene.settings);
    o.quiet = true;
    return render(scene, o);
}

Scene load_gltf(const std::string& text) { return load_scene_json(text, kGltfSourceDir, "s.json"); }

std::string gltf_load_error(const std::string& text) {
    try {
        load_gltf(text);
    } catch (const FileError& e) {
        return e.what();
    }
    return "no error";
}

std::string one_plane_glb(const std::string& name, const json& materials, const json& node = json{{"mesh", 0}}) {
    auto [doc, bin] = document({plane_quad()}, {materials.empty() ? -1 : 0});
    doc["nodes"] = {node};
    doc["scenes"] = {{{"nodes", {0}}}};
    doc["scene"] = 0;
    if (!materials.empty()) doc["materials"] = materials;
    return write_temp(name, glb_bytes(doc, bin));
}

}  // namespace

TEST_CASE("glTF: a plane bound to a scene material renders as the scene format's plane, per pixel") {
    const std::string file = one_plane_glb("plane.glb", json::array({{{"name", "Floor"}}}));
    const Scene gltf = load_gltf(scene_with(R"({"type": "gltf", "file": ")" + file + R"(", "bind": {"Floor": "m"}})"));
    const Scene plane = load_gltf(scene_with(R"({"type": "plane", "center": [0, 0, 0], "normal": [0, 1, 0], "tangent": [1, 0, 0], "size": 4, "material": "m"})"));
    // glTF's uv origin is the texture's top left, the renderer's too (docs/SVBRDF.md): the file's
    // TEXCOORD_0 arrive unflipped, equal to make_plane's.
    REQUIRE(gltf.mesh_count() == 1);
    CHECK(gltf.mesh(0).uvs == plane.mesh(0).uvs);
    CHECK(gltf.mesh(0).tangents.size() == 4);
    const Image a = draw_gltf(gltf), b = draw_gltf(plane);
    int lit = 0;
    for (std::size_t i = 0; i < a.rgb.size(); ++i) {
        CHECK(a.rgb[i] == doctest::Approx(b.rgb[i]).epsilon(1e-5));
        lit += b.rgb[i] > 0.0f;
    }
    CHECK(lit > int(a.rgb.size()) / 2);
}

TEST_CASE("glTF: node transforms (TRS, a matrix, a parent) and the object's transform place the vertices") {
    Quad q = plane_quad();
    auto [doc, bin] = document({q}, {-1});
    // Parent: translation (1, 2, 3), scale 2. Child: a column-major matrix rotating 90 degrees
    // about +y then translating by (0, 0, -1). World = parent * child.
    doc["nodes"] = {{{"translation", {1, 2, 3}}, {"scale", {2, 2, 2}}, {"children", {1}}},
                    {{"mesh", 0}, {"matrix", {0, 0, -1, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0, -1, 1}}}};
    doc["scenes"] = {{{"nodes", {0}}}};
    doc["scene"] = 0;
    const std::string file = write_temp("nodes.glb", glb_bytes(doc, bin));
    const Scene s = load_gltf(scene_with(R"({"type": "gltf", "file": ")" + file + R"(", "transform": {"translate": [0, -5, 0]}})"));
    REQUIRE(s.mesh_count() == 1);
    const TriangleMesh& mesh = s.mesh(0);
    REQUIRE(mesh.positions.size() == 4);
    for (int v = 0; v < 4; ++v) {
        const double x = q.positions[3 * v], y = q.positions[3 * v + 1], z = q.positions[3 * v + 2];
        // child: rotation about +y by 90 degrees maps (x, y, z) -> (z, y, -x); then + (0, 0, -1)
        const double cx = z, cy = y, cz = -x - 1.0;
        // parent: scale 2, translate (1, 2, 3); then the object's translate (0, -5, 0)
        const double wx = 2 * cx + 1, wy = 2 * cy + 2 - 5, wz = 2 * cz + 3;
        bool found = false;  // assimp may reorder the vertices
        for (const auto& p : mesh.positions)
            found = found || (std::fabs(p.x - wx) < 1e-5 && std::fabs(p.y - wy) < 1e-5 && std::fabs(p.z - wz) < 1e-5);
        CHECK_MESSAGE(found, "vertex " << v << " expected at (" << wx << ", " << wy << ", " << wz << ")");
    }
}

TEST_CASE("glTF: a material bound to MODEL#MATERIAL renders as that model's material") {
    const std::string model = kGltfSourceDir + "/results/rgl54_hybrid_32x2.safetensors";
    if (!std::ifstream(model).good()) return;  // the fitted model is part of the repository
    const std::string file = one_plane_glb("bound.glb", json::array({{{"name", "Paint"}, {"pbrMetallicRoughness", {{"metallicFactor", 0}}}}}));
    const std::string mat = R"({"type": "model", "file": "results/rgl54_hybrid_32x2.safetensors", "material": "cc_ibiza_sunset_rgb.rgl"})";
    const Scene gltf = load_gltf(scene_with(R"({"type": "gltf", "file": ")" + file +
                                       R"(", "bind": {"Paint": "results/rgl54_hybrid_32x2.safetensors#cc_ibiza_sunset_rgb.rgl"}})"));
    const Scene plane = load_gltf(scene_with(R"({"type": "plane", "center": [0, 0, 0], "normal": [0, 1, 0], "tangent": [1, 0, 0], "size": 4, "material": "m"})",
                                        R"({"m": )" + mat + "}"));
    REQUIRE(gltf.materials.size() == 2);  // the scene's "m", then the bound one
    CHECK(std::string(gltf.materials[1]->type()) == "model");
    const Image a = draw_gltf(gltf), b = draw_gltf(plane);
    for (std::size_t i = 0; i < a.rgb.size(); ++i) CHECK(a.rgb[i] == doctest::Approx(b.rgb[i]).epsilon(1e-5));
}

TEST_CASE("glTF: the metallic-roughness mapping onto f_a (computed in double from the KHR specifications)") {
    const json materials = json::array({
        {{"name", "plastic"}, {"pbrMetallicRoughness", {{"baseColorFactor", {0.8, 0.4, 0.2, 1}}, {"metallicFactor", 0.0}, {"roughnessFactor", 0.5}}}},
        {{"name", "gold"}, {"pbrMetallicRoughness", {{"baseColorFactor", {1.0, 0.766, 0.336, 1}}, {"metallicFactor", 1.0}, {"roughnessFactor", 0.3}}}},
        {{"name", "mixed"},
         {"pbrMetallicRoughness", {{"baseColorFactor", {0.5, 0.6, 0.7, 1}}, {"metallicFactor", 0.25}, {"roughnessFactor", 0.6}}},
         {"extensions",
          {{"KHR_materials_ior", {{"ior", 1.8}}},
           {"KHR_materials_specular", {{"specularFactor", 0.7}, {"specularColorFactor", {20.0, 0.5, 3.0}}}},
           {"KHR_materials_anisotropy", {{"anisotropyStrength", 0.6}, {"anisotropyRotation", 1.5707963267948966}}}}}},
        {{"name", "mirror"}, {"pbrMetallicRoughness", {{"roughnessFactor", 0.0}}}},
    });
    // Four quads, one material each, side by side.
    std::vector<Quad> quads(4, plane_quad());
    auto [doc, bin] = document(quads, {0, 1, 2, 3});
    doc["materials"] = materials;
    doc["nodes"] = json::array();
    for (int i = 0; i < 4; ++i) doc["nodes"].push_back({{"mesh", i}, {"translation", {5.0 * i, 0, 0}}});
    doc["scenes"] = {{{"nodes", {0, 1, 2, 3}}}};
    const std::string file = write_temp("materials.glb", glb_bytes(doc, bin));
    const Scene s = load_gltf(scene_with(R"({"type": "gltf", "file": ")" + file + R"("})"));
    REQUIRE(s.materials.size() == 5);  // the scene's "m" and the asset's four
    auto params_of = [&](const std::string& suffix) -> hbrdf::AnalyticParams {
        for (const auto& m : s.materials)
            if (m->name() == "objects[0]:" + suffix) return dynamic_cast<const AnalyticMaterial&>(*m).params();
        FAIL("no material " << suffix);
        return {};
    };
    auto eta_of = [](double f0) { return std::min(10.0, (1 + std::sqrt(f0)) / (1 - std::sqrt(f0))); };
    const hbrdf::AnalyticParams plastic = params_of("plastic"), gold = params_of("gold"), mixed = params_of("mixed"), mirror = params_of("mirror");
    for (int c = 0; c < 3; ++c) {
        const double base_p[3] = {0.8, 0.4, 0.2}, base_g[3] = {1.0, 0.766, 0.336}, base_m[3] = {0.5, 0.6, 0.7};
        CHECK(plastic.kd[c] == doctest::Approx(base_p[c]));
        CHECK(plastic.eta[c] == doctest::Approx(1.5));  // F0 0.04 <-> ior 1.5
        CHECK(gold.kd[c] == 0.0f);
        CHECK(gold.eta[c] == doctest::Approx(eta_of(base_g[c])));  // 1.0 and 0.766 above 0.669: clamped to 10
        const double spec_color[3] = {20.0, 0.5, 3.0};  // 20 x 0.082 > 1: the clamp of KHR_materials_specular
        const double f0_ior = (0.8 / 2.8) * (0.8 / 2.8);
        const double dielectric = std::min(f0_ior * spec_color[c], 1.0) * 0.7;
        CHECK(mixed.kd[c] == doctest::Approx(base_m[c] * 0.75));
        CHECK(mixed.eta[c] == doctest::Approx(eta_of(0.75 * dielectric + 0.25 * base_m[c])));
        CHECK(mirror.kd[c] == 0.0f);
        CHECK(mirror.eta[c] == 10.0f);
    }
    CHECK(gold.eta[0] == 10.0f);
    CHECK(gold.eta[1] == 10.0f);
    CHECK(plastic.alpha.x == doctest::Approx(0.25));
    CHECK(plastic.alpha.y == doctest::Approx(0.25));
    CHECK(gold.alpha.x == doctest::Approx(0.09));
    CHECK(mixed.alpha.x == doctest::Approx(0.36 + (1 - 0.36) * 0.36));  // mix(alpha, 1, s^2)
    CHECK(mixed.alpha.y == doctest::Approx(0.36));
    CHECK(mirror.alpha.x == doctest::Approx(hbrdf::kAlphaMin));  // roughness 0: alpha clamped to kAlphaMin
    // anisotropyRotation pi/2 turns the tangent of the mixed quad from +x to n x t = (0, 0, -1).
    bool rotated = false;
    for (std::size_t i = 0; i < s.mesh_count(); ++i)
        if (s.materials[std::size_t(s.mesh_material(i))]->name() == "objects[0]:mixed")
            for (const auto& t : s.mesh(i).tangents) rotated = std::fabs(t.x) < 1e-6 && std::fabs(t.z + 1) < 1e-6;
    CHECK(rotated);
}

TEST_CASE("glTF: the asset's TANGENTs are used; without them, tangents follow the uvs") {
    auto [doc, bin] = document({plane_quad()}, {-1});
    // The uvs' u runs along +x; the file's tangents say +z (a different, still orthogonal frame).
    const std::vector<float> tangents = {0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1};
    doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", append(bin, tangents)}, {"byteLength", 64}});
    doc["accessors"].push_back({{"bufferView", doc["bufferViews"].size() - 1}, {"componentType", 5126}, {"count", 4}, {"type", "VEC4"}});
    doc["buffers"][0]["byteLength"] = bin.size();
    doc["nodes"] = {{{"mesh", 0}}};
    doc["scenes"] = {{{"nodes", {0}}}};
    const Scene from_uvs = load_gltf(scene_with(R"({"type": "gltf", "file": ")" + write_temp("uvt.glb", glb_bytes(doc, bin)) + R"("})"));
    doc["meshes"][0]["primitives"][0]["attributes"]["TANGENT"] = doc["accessors"].size() - 1;
    const Scene given = load_gltf(scene_with(R"({"type": "gltf", "file": ")" + write_temp("tangents.glb", glb_bytes(doc, bin)) + R"("})"));
    for (const auto& t : from_uvs.mesh(0).tangents) CHECK((std::fabs(t.x - 1) < 1e-6 && std::fabs(t.z) < 1e-6));
    for (const auto& t : given.mesh(0).tangents) CHECK((std::fabs(t.z - 1) < 1e-6 && std::fabs(t.x) < 1e-6));
}

TEST_CASE("glTF: a .gltf with its buffer in a file beside it, and data: URIs") {
    auto [doc, bin] = document({plane_quad()}, {-1});
    doc["nodes"] = {{{"mesh", 0}}};
    doc["scenes"] = {{{"nodes", {0}}}};
    write_temp("side.bin", bin);
    doc["buffers"][0]["uri"] = "side.bin";
    const std::string file = write_temp("side.gltf", doc.dump());
    const Scene s = load_gltf(scene_with(R"({"type": "gltf", "file": ")" + file + R"("})"));
    REQUIRE(s.mesh_count() == 1);
    CHECK(s.mesh(0).positions.size() == 4);
    // glTF's default material: metallic 1, roughness 1, base colour 1 -> kd 0, eta 10, alpha 1.
    REQUIRE(s.materials.size() == 2);
    CHECK(s.materials[1]->name() == "objects[0]:default");
    const auto& p = dynamic_cast<const AnalyticMaterial&>(*s.materials[1]).params();
    CHECK(p.kd.x == 0.0f);
    CHECK(p.eta.x == 10.0f);
    CHECK(p.alpha.x == 1.0f);
    // The same buffer as a data: URI (base64), read into the same vertices.
    static const char* kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string b64;
    for (std::size_t i = 0; i < bin.size(); i += 3) {
        std::uint32_t v = std::uint32_t(std::uint8_t(bin[i])) << 16;
        if (i + 1 < bin.size()) v |= std::uint32_t(std::uint8_t(bin[i + 1])) << 8;
        if (i + 2 < bin.size()) v |= std::uint32_t(std::uint8_t(bin[i + 2]));
        const std::size_t present = std::min<std::size_t>(3, bin.size() - i);  // bytes in this group: 1 to 3
        for (std::size_t k = 0; k < 4; ++k) b64 += k <= present ? kAlphabet[(v >> (18 - 6 * k)) & 63] : '=';
    }
    doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + b64;
    const Scene d = load_gltf(scene_with(R"({"type": "gltf", "file": ")" + write_temp("data.gltf", doc.dump()) + R"("})"));
    REQUIRE(d.mesh_count() == 1);
    CHECK(d.mesh(0).positions == s.mesh(0).positions);
    doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + b64.substr(0, 40);
    CHECK(gltf_load_error(scene_with(R"({"type": "gltf", "file": ")" + write_temp("short.gltf", doc.dump()) + R"("})"))
              .find("buffers[0].uri: the data: URI holds 30 bytes, fewer than byteLength = 152") != std::string::npos);
}

TEST_CASE("glTF: malformed assets are refused with one line naming the file and the problem") {
    const std::string good = glb_bytes(document({plane_quad()}, {-1}).first, document({plane_quad()}, {-1}).second);
    auto error_of = [](const std::string& name, const std::string& bytes, const std::string& bind = "") {
        const std::string path = write_temp(name, bytes);
        const std::string msg = gltf_load_error(scene_with(R"({"type": "gltf", "file": ")" + path + "\"" + bind + "}"));
        const std::string prefix = "s.json: objects[0].file: " + path + ": ";
        if (msg.rfind(prefix, 0) != 0) return "unexpected: " + msg;
        return msg.substr(prefix.size());
    };
    CHECK(error_of("short.glb", "glTF") == "a GLB file of 4 bytes, shorter than its 12-byte header");
    CHECK(error_of("magic.glb", "GLTF" + good.substr(4)) == "not a GLB file (its first 4 bytes are not 'glTF')");
    CHECK(error_of("version.glb", good.substr(0, 4) + u32(1) + good.substr(8)) == "GLB version 1; only glTF 2.0 is read");
    CHECK(error_of("cut.glb", good.substr(0, good.size() - 8)) ==
          "the GLB header declares " + std::to_string(good.size()) + " bytes, but the file has " + std::to_string(good.size() - 8));
    {
        std::string big = good;
        const std::string len = u32(std::uint32_t(good.size()));  // chunk 0 claims the whole file
        big.replace(12, 4, len);
        CHECK(error_of("chunk.glb", big) == "chunk 0 declares " + std::to_string(good.size()) + " bytes, but " +
                                                std::to_string(good.size() - 20) + " follow its header");
    }
    {
        std::string notjson = good;
        notjson.replace(16, 4, u32(0x004E4942));
        CHECK(error_of("notjson.glb", notjson) == "the first chunk is not JSON");
    }
    {
        const std::string text = "{\"asset\": ";  // 10 bytes, padded to 12
        CHECK(error_of("badjson.glb", u32(0x46546C67) + u32(2) + u32(32) + u32(12) + u32(0x4E4F534A) + text + "  ")
                  .rfind("JSON chunk: invalid JSON: ", 0) == 0);
    }
    auto with = [](auto edit) {
        auto [doc, bin] = document({plane_quad()}, {-1});
        doc["nodes"] = {{{"mesh", 0}}};
        doc["scenes"] = {{{"nodes", {0}}}};
        edit(doc, bin);
        return glb_bytes(doc, bin);
    };
    CHECK(error_of("buffer.glb", with([](json& d, std::string& b) { d["buffers"][0]["byteLength"] = b.size() + 100; })) ==
          "buffers[0].byteLength: " + std::to_string(document({plane_quad()}, {-1}).second.size() + 100) + " bytes, but the BIN chunk holds " +
              std::to_string(document({plane_quad()}, {-1}).second.size()));
    CHECK(error_of("view.glb", with([](json& d, std::string&) { d["bufferViews"][0]["byteLength"] = 4096; })) ==
          "bufferViews[0]: bytes 0 + 4096 run past its buffer's 152");
    CHECK(error_of("accessor.glb", with([](json& d, std::string&) { d["accessors"][0]["count"] = 5; })) ==
          "accessors[0]: 5 elements of 12 bytes (stride 12) end at byte 60, past its buffer view's 48");
    CHECK(error_of("index.glb", with([](json& d, std::string&) { d["accessors"][0]["bufferView"] = 17; })) ==
          "accessors[0].bufferView: 17 is out of range (the asset has 4 bufferViews)");
    CHECK(error_of("up.glb", with([](json& d, std::string&) { d["buffers"].push_back({{"byteLength", 4}, {"uri", "../etc/passwd"}}); })) ==
          "buffers[1].uri: '../etc/passwd': a buffer must lie in the asset's folder (no scheme, absolute path, '..' or escapes)");
    CHECK(error_of("net.glb", with([](json& d, std::string&) { d["buffers"].push_back({{"byteLength", 4}, {"uri", "https://example.com/b.bin"}}); }))
              .rfind("buffers[1].uri: 'https://example.com/b.bin': a buffer must lie", 0) == 0);
    CHECK(error_of("version2.glb", with([](json& d, std::string&) { d["asset"]["version"] = "1.0"; })) ==
          "asset.version: expected \"2.0\" (only glTF 2.0 is read)");
    CHECK(error_of("metal.glb", with([](json& d, std::string&) { d["materials"] = {{{"pbrMetallicRoughness", {{"metallicFactor", 2}}}}}; })) ==
          "materials[0].pbrMetallicRoughness.metallicFactor: must be in [0, 1], got 2");
    // An index past the vertices (assimp would drop the face without a word).
    CHECK(error_of("vertex.glb", with([](json&, std::string& b) {
              const std::uint32_t bad = 9;
              std::memcpy(&b[b.size() - 4], &bad, 4);
          })) == "meshes[0].primitives[0].indices: index 9 (element 5) is out of range: POSITION has 4 vertices");
    // assimp's own refusal, in the loader's one-line form: a node cycle.
    const std::string assimp = error_of("cycle.glb", with([](json& d, std::string&) {
        d["nodes"] = {{{"mesh", 0}, {"children", {1}}}, {{"children", {0}}}};
    }));
    CHECK_MESSAGE(assimp.rfind("cannot read the asset: ", 0) == 0, assimp);
    MESSAGE(assimp);
    CHECK(assimp.find('\n') == std::string::npos);
    // A bind that names no material of the asset.
    CHECK(gltf_load_error(scene_with(R"({"type": "gltf", "file": ")" + one_plane_glb("named.glb", json::array({{{"name", "A"}}})) +
                                R"(", "bind": {"B": "m"}})")) == "s.json: objects[0].bind.B: the asset has no material named 'B' (it has 'A')");
}
