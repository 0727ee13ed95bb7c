// hybridbrdf renderer — glTF 2.0 assets as scene objects (docs/RENDERING.md, "glTF objects").
//
// The asset is bounded here before assimp reads a byte of it: the GLB container (magic, version,
// length against the file, chunk lengths), the JSON (parsed, nesting bounded), buffers against
// their files or the BIN chunk, buffer views against their buffers, accessors against their views.
// assimp then reads the geometry and the node graph (its node matrices and TRS baked into the
// vertices) from a copy of the asset held in memory whose materials are renamed "hbrdf:<index>"
// and stripped of textures: assimp orders materials by first use, not by index, and names may be
// empty or repeated, so the name is how a primitive finds its glTF material. The materials'
// factors are read from the JSON here (gltf_material_to_fa: the mapping of docs/RENDERING.md).
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <assimp/Importer.hpp>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <sys/stat.h>

#include <glm/vec4.hpp>

#include "hybridbrdf/params.hpp"
#include "hybridbrdf/spec.hpp"
#include "hybridbrdf/text.hpp"
#include "scene_reader.hpp"

namespace hbrdf::render::detail {

namespace {

constexpr std::uint32_t kGlbMagic = 0x46546C67, kChunkJson = 0x4E4F534A, kChunkBin = 0x004E4942;
constexpr const char* kMaterialPrefix = "hbrdf:";

std::uint32_t le32(const unsigned char* p) {
    return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}

// The asset in memory: its JSON and, for a GLB, where the BIN chunk lies in `bytes`.
struct Asset {
    std::string path, folder;
    std::string bytes;
    json doc;
    bool glb = false;
    std::size_t bin_offset = 0, bin_size = 0;
    bool has_bin = false;
    std::vector<std::string> buffers;  // each buffer's bytes (at least byteLength), for the index check
};

json parse_json(const SceneReader& r, const std::string& text, const std::string& what) {
    if (json_depth(text) > spec::kMaxJsonDepth)
        r.fail(what, "JSON nested deeper than " + std::to_string(spec::kMaxJsonDepth) + " levels");
    try {
        json doc = json::parse(text);
        if (!doc.is_object()) r.fail(what, "expected a JSON object at the top level");
        return doc;
    } catch (const json::exception& e) {
        r.fail(what, std::string("invalid JSON: ") + e.what());
    }
}

// GLB 2.0: a 12-byte header (magic "glTF", version 2, the total length), a JSON chunk, an optional
// BIN chunk; every length checked against the bytes present before it is used.
void split_glb(const SceneReader& r, Asset& a) {
    const auto* b = reinterpret_cast<const unsigned char*>(a.bytes.data());
    const std::size_t n = a.bytes.size();
    if (n < 12) r.fail("", "a GLB file of " + std::to_string(n) + " bytes, shorter than its 12-byte header");
    if (le32(b) != kGlbMagic) r.fail("", "not a GLB file (its first 4 bytes are not 'glTF')");
    if (le32(b + 4) != 2) r.fail("", "GLB version " + std::to_string(le32(b + 4)) + "; only glTF 2.0 is read");
    if (le32(b + 8) != n)
        r.fail("", "the GLB header declares " + std::to_string(le32(b + 8)) + " bytes, but the file has " + std::to_string(n));
    std::size_t at = 12;
    for (int chunk = 0; at < n; ++chunk) {
        if (n - at < 8) r.fail("", "chunk " + std::to_string(chunk) + " at byte " + std::to_string(at) + ": its 8-byte header is cut off");
        const std::uint64_t length = le32(b + at), type = le32(b + at + 4);
        if (length > n - at - 8)
            r.fail("", "chunk " + std::to_string(chunk) + " declares " + std::to_string(length) + " bytes, but " +
                           std::to_string(n - at - 8) + " follow its header");
        if (chunk == 0 && type != kChunkJson) r.fail("", "the first chunk is not JSON");
        if (chunk == 0) a.doc = parse_json(r, a.bytes.substr(at + 8, length), "JSON chunk");
        if (chunk == 1 && type == kChunkBin) {
            a.has_bin = true;
            a.bin_offset = at + 8;
            a.bin_size = length;
        }
        at += 8 + length;
    }
    if (a.doc.is_null()) r.fail("", "the GLB file has no JSON chunk");
}

std::uint64_t count_of(const SceneReader& r, const json& obj, const std::string& w, const char* key, bool required) {
    if (!obj.contains(key)) {
        if (required) r.fail(w, std::string("missing key '") + key + "'");
        return 0;
    }
    const json& v = obj.at(key);
    if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<std::int64_t>() >= 0))
        r.fail(w + "." + key, "expected an integer >= 0, got " + v.dump());
    const std::uint64_t x = v.get<std::uint64_t>();
    if (x > (std::uint64_t(1) << 40)) r.fail(w + "." + key, "must be <= 2^40, got " + v.dump());
    return x;
}

// The index `key` of obj (into the array `array` of the document), checked.
std::int64_t index_of(const SceneReader& r, const Asset& a, const json& obj, const std::string& w, const char* key,
                      const char* array, bool required) {
    if (!obj.contains(key) && !required) return -1;
    const std::uint64_t i = count_of(r, obj, w, key, true);
    const std::size_t size = a.doc.contains(array) && a.doc.at(array).is_array() ? a.doc.at(array).size() : 0;
    if (i >= size) r.fail(w + "." + key, std::to_string(i) + " is out of range (the asset has " + std::to_string(size) + " " + array + ")");
    return std::int64_t(i);
}

const json& array_of(const SceneReader& r, const json& doc, const char* key) {
    static const json empty = json::array();
    if (!doc.contains(key)) return empty;
    if (!doc.at(key).is_array()) r.fail(key, "expected an array");
    return doc.at(key);
}

std::uint64_t file_size(const std::string& path) {
    struct stat st {};
    return ::stat(path.c_str(), &st) == 0 ? std::uint64_t(st.st_size) : 0;
}

// Buffers: the GLB's BIN chunk, a data: URI, or a file beside the asset (no network location, no
// absolute path, no '..'), each at least byteLength long. A file's URI is made absolute for assimp,
// which reads the asset from memory.
void check_buffers(const SceneReader& r, Asset& a, std::vector<std::uint64_t>& lengths) {
    json& buffers = a.doc["buffers"];
    if (!buffers.is_array()) r.fail("buffers", "expected an array");
    std::uint64_t external = 0;
    for (std::size_t i = 0; i < buffers.size(); ++i) {
        const std::string w = "buffers[" + std::to_string(i) + "]";
        json& b = buffers[i];
        if (!b.is_object()) r.fail(w, "expected an object");
        const std::uint64_t length = count_of(r, b, w, "byteLength", true);
        lengths.push_back(length);
        if (!b.contains("uri")) {
            if (!(a.glb && i == 0 && a.has_bin)) r.fail(w, "no uri, and it is not a GLB file's BIN chunk");
            if (length > a.bin_size)
                r.fail(w + ".byteLength", std::to_string(length) + " bytes, but the BIN chunk holds " + std::to_string(a.bin_size));
            a.buffers.push_back(a.bytes.substr(a.bin_offset, a.bin_size));
            continue;
        }
        const std::string uri = r.string(b.at("uri"), w + ".uri");
        if (ascii_lower(uri.substr(0, 5)) == "data:") {
            const std::size_t comma = uri.find(',');
            if (comma == std::string::npos || uri.rfind(";base64", comma) == std::string::npos)
                r.fail(w + ".uri", "a data: URI must be base64");
            a.buffers.push_back(base64_decode(uri.substr(comma + 1)));
            if (a.buffers.back().size() < length)
                r.fail(w + ".uri", "the data: URI holds " + std::to_string(a.buffers.back().size()) + " bytes, fewer than byteLength = " +
                                       std::to_string(length));
            continue;
        }
        if (uri.find(':') != std::string::npos || uri.empty() || uri[0] == '/' || uri.find('\\') != std::string::npos ||
            ("/" + uri + "/").find("/../") != std::string::npos || uri.find('%') != std::string::npos)
            r.fail(w + ".uri", "'" + uri + "': a buffer must lie in the asset's folder (no scheme, absolute path, '..' or escapes)");
        const std::string file = a.folder + "/" + uri;
        try {
            check_input_file(file, "glTF buffer");
        } catch (const FileError& e) {
            r.fail(w + ".uri", e.what());
        }
        if (file_size(file) < length)
            r.fail(w + ".uri", file + " has " + std::to_string(file_size(file)) + " bytes, fewer than byteLength = " + std::to_string(length));
        external += length;
        if (external > kMaxGltfBytes)
            r.fail(w, "the asset's buffer files hold more than " + std::to_string(kMaxGltfBytes) + " bytes together");
        std::ifstream in(file, std::ios::binary);
        std::string bytes(length, '\0');
        if (!in.read(bytes.data(), std::streamsize(length))) r.fail(w + ".uri", file + ": cannot read " + std::to_string(length) + " bytes");
        a.buffers.push_back(std::move(bytes));
        b["uri"] = file;
    }
}

// Buffer views within their buffers, accessors within their views; sparse accessors are refused.
void check_views_and_accessors(const SceneReader& r, const Asset& a, const std::vector<std::uint64_t>& buffer_lengths) {
    const json& views = array_of(r, a.doc, "bufferViews");
    std::vector<std::uint64_t> view_lengths;
    for (std::size_t i = 0; i < views.size(); ++i) {
        const std::string w = "bufferViews[" + std::to_string(i) + "]";
        const std::int64_t b = index_of(r, a, views[i], w, "buffer", "buffers", true);
        const std::uint64_t offset = count_of(r, views[i], w, "byteOffset", false), length = count_of(r, views[i], w, "byteLength", true);
        if (offset + length > buffer_lengths[std::size_t(b)])
            r.fail(w, "bytes " + std::to_string(offset) + " + " + std::to_string(length) + " run past its buffer's " +
                          std::to_string(buffer_lengths[std::size_t(b)]));
        view_lengths.push_back(length);
    }
    static const std::map<std::string, int> kComponents = {{"SCALAR", 1}, {"VEC2", 2}, {"VEC3", 3}, {"VEC4", 4},
                                                           {"MAT2", 4},   {"MAT3", 9}, {"MAT4", 16}};
    static const std::map<int, int> kBytes = {{5120, 1}, {5121, 1}, {5122, 2}, {5123, 2}, {5125, 4}, {5126, 4}};
    const json& accessors = array_of(r, a.doc, "accessors");
    for (std::size_t i = 0; i < accessors.size(); ++i) {
        const std::string w = "accessors[" + std::to_string(i) + "]";
        const json& acc = accessors[i];
        if (!acc.is_object()) r.fail(w, "expected an object");
        if (acc.contains("sparse")) r.fail(w + ".sparse", "sparse accessors are not read");
        const std::uint64_t count = count_of(r, acc, w, "count", true);
        const std::string type = acc.contains("type") ? r.string(acc.at("type"), w + ".type") : "";
        const int ctype = acc.contains("componentType") && acc.at("componentType").is_number_integer() ? acc.at("componentType").get<int>() : 0;
        if (!kComponents.count(type)) r.fail(w + ".type", "expected SCALAR, VEC2, VEC3, VEC4, MAT2, MAT3 or MAT4");
        if (!kBytes.count(ctype)) r.fail(w + ".componentType", "expected 5120, 5121, 5122, 5123, 5125 or 5126");
        const std::int64_t v = index_of(r, a, acc, w, "bufferView", "bufferViews", false);
        if (v < 0 || count == 0) continue;
        const std::uint64_t element = std::uint64_t(kComponents.at(type)) * std::uint64_t(kBytes.at(ctype));
        const std::string wv = "bufferViews[" + std::to_string(v) + "]";
        const std::uint64_t byte_stride = count_of(r, views[std::size_t(v)], wv, "byteStride", false);
        if (byte_stride > 252) r.fail(wv + ".byteStride", "must be <= 252, got " + std::to_string(byte_stride));  // glTF's bound
        const std::uint64_t stride = std::max(element, byte_stride);
        const std::uint64_t end = count_of(r, acc, w, "byteOffset", false) + (count - 1) * stride + element;
        if (end > view_lengths[std::size_t(v)])
            r.fail(w, std::to_string(count) + " elements of " + std::to_string(element) + " bytes (stride " + std::to_string(stride) +
                          ") end at byte " + std::to_string(end) + ", past its buffer view's " + std::to_string(view_lengths[std::size_t(v)]));
    }
}

// Every index of a triangle primitive below its POSITION count: assimp drops a face with an index
// past the vertices without an error, which would render the asset with holes.
void check_indices(const SceneReader& r, const Asset& a) {
    const json& meshes = array_of(r, a.doc, "meshes");
    const json& accessors = array_of(r, a.doc, "accessors");
    const json& views = array_of(r, a.doc, "bufferViews");
    for (std::size_t m = 0; m < meshes.size(); ++m) {
        const std::string wm = "meshes[" + std::to_string(m) + "]";
        if (!meshes[m].is_object() || !meshes[m].contains("primitives") || !meshes[m].at("primitives").is_array())
            r.fail(wm + ".primitives", "expected an array");
        const json& prims = meshes[m].at("primitives");
        for (std::size_t p = 0; p < prims.size(); ++p) {
            const std::string w = wm + ".primitives[" + std::to_string(p) + "]";
            const json& prim = prims[p];
            if (!prim.is_object() || !prim.contains("attributes") || !prim.at("attributes").is_object())
                r.fail(w + ".attributes", "expected an object");
            const json& attributes = prim.at("attributes");
            if (!attributes.contains("POSITION")) r.fail(w + ".attributes", "missing key 'POSITION'");
            const std::int64_t pos = index_of(r, a, attributes, w + ".attributes", "POSITION", "accessors", true);
            const std::int64_t idx = index_of(r, a, prim, w, "indices", "accessors", false);
            if (idx < 0) continue;
            const json& acc = accessors[std::size_t(idx)];
            const std::uint64_t vertices = acc.is_object() ? count_of(r, accessors[std::size_t(pos)], "accessors", "count", true) : 0;
            if (!acc.contains("bufferView")) continue;  // all zeros
            const int ctype = acc.at("componentType").get<int>();
            if (ctype != 5121 && ctype != 5123 && ctype != 5125)
                r.fail("accessors[" + std::to_string(idx) + "].componentType", "indices must be 5121, 5123 or 5125, got " + std::to_string(ctype));
            const std::uint64_t size = ctype == 5125 ? 4 : ctype == 5123 ? 2 : 1;
            const json& view = views[acc.at("bufferView").get<std::size_t>()];
            const std::string& buf = a.buffers[view.at("buffer").get<std::size_t>()];
            const std::uint64_t stride = std::max(size, count_of(r, view, "bufferView", "byteStride", false));
            const std::uint64_t base = count_of(r, view, "bufferView", "byteOffset", false) + count_of(r, acc, "accessor", "byteOffset", false);
            const std::uint64_t count = count_of(r, acc, "accessor", "count", true);
            for (std::uint64_t i = 0; i < count; ++i) {
                const auto* q = reinterpret_cast<const unsigned char*>(buf.data() + base + i * stride);  // bounded by check_views_and_accessors
                const std::uint64_t v = size == 4 ? le32(q) : size == 2 ? std::uint64_t(q[0] | q[1] << 8) : q[0];
                if (v >= vertices)
                    r.fail(w + ".indices", "index " + std::to_string(v) + " (element " + std::to_string(i) + ") is out of range: POSITION has " +
                                               std::to_string(vertices) + " vertices");
            }
        }
    }
}

// The copy assimp reads: materials renamed by index and without textures (the tracer reads the
// factors; assimp would otherwise decode every image), no images, textures or samplers.
std::string assimp_copy(const Asset& a) {
    json doc = a.doc;
    if (doc.contains("materials") && doc["materials"].is_array())
        for (std::size_t i = 0; i < doc["materials"].size(); ++i) doc["materials"][i] = json{{"name", kMaterialPrefix + std::to_string(i)}};
    for (const char* key : {"images", "textures", "samplers"}) doc.erase(key);
    for (const char* key : {"extensionsUsed", "extensionsRequired"}) {
        if (!doc.contains(key) || !doc[key].is_array()) continue;
        json kept = json::array();
        for (const json& e : doc[key])
            if (!(e.is_string() && (e.get<std::string>().rfind("KHR_materials_", 0) == 0 || e.get<std::string>() == "KHR_texture_transform")))
                kept.push_back(e);
        doc[key] = kept;
    }
    std::string text = doc.dump();
    if (!a.glb) return text;
    text.append((4 - text.size() % 4) % 4, ' ');
    std::string out(12, '\0');
    auto put = [&out](std::uint32_t v) {
        for (int k = 0; k < 4; ++k) out.push_back(char((v >> (8 * k)) & 0xFF));
    };
    put(std::uint32_t(text.size()));
    put(kChunkJson);
    out += text;
    if (a.has_bin) {
        put(std::uint32_t(a.bin_size));
        put(kChunkBin);
        out.append(a.bytes, a.bin_offset, a.bin_size);
        out.append((4 - a.bin_size % 4) % 4, '\0');
    }
    const std::uint32_t header[3] = {kGlbMagic, 2, std::uint32_t(out.size())};
    std::memcpy(out.data(), header, 12);  // little-endian hosts (x86-64, aarch64)
    return out;
}

Vec3f unit_or(const aiVector3D& v, const Vec3f& fallback) {
    const Vec3f u(v.x, v.y, v.z);
    const float l2 = dot(u, u);
    return l2 > 0.0f && std::isfinite(l2) ? u / std::sqrt(l2) : fallback;
}

// The bitangent's handedness w at vertex v (glTF 2.0: b = w n x t, w = -1 on a mirrored uv
// island), read off assimp's bitangent. Its glTF reader stores the asset's b = w (n x t); its
// CalcTangentSpace (no TANGENT) stores b along dP/dv' in its bottom-up v' = 1 - v, the image's
// top, with t = dP/du: b is n x t where the uvs keep the orientation and -(n x t) where they are
// mirrored (the uv Jacobian's determinant negative), the same convention. Seen on a quad both
// ways with both (test_gltf_textures.py).
std::int8_t tangent_sign(const aiMesh* am, unsigned v) {
    if (!am->mBitangents || !am->HasNormals()) return 1;
    const aiVector3D& n = am->mNormals[v];
    const aiVector3D& t = am->mTangents[v];
    const aiVector3D& b = am->mBitangents[v];
    const float s = (n ^ t) * b;  // assimp: ^ the cross product, * the dot product
    return s < 0.0f ? std::int8_t(-1) : std::int8_t(1);
}

// One part per assimp mesh (PreTransformVertices: one per material, node transforms applied).
std::vector<GltfPart> read_parts(const SceneReader& r, const Asset& a) {
    const std::string data = assimp_copy(a);
    Assimp::Importer importer;
    const unsigned flags = aiProcess_ValidateDataStructure | aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                           aiProcess_PreTransformVertices | aiProcess_SortByPType | aiProcess_CalcTangentSpace;
    const aiScene* scene = importer.ReadFileFromMemory(data.data(), data.size(), flags, a.glb ? "glb" : "gltf");
    if (!scene || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) || scene->mNumMeshes == 0)
        r.fail("", "cannot read the asset: " + one_line_text(scene ? "it holds no triangle mesh" : importer.GetErrorString()));
    std::vector<GltfPart> parts;
    for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
        const aiMesh* am = scene->mMeshes[m];
        if (!(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE) || am->mNumFaces == 0) continue;
        GltfPart part;
        aiString name;
        if (am->mMaterialIndex < scene->mNumMaterials)
            scene->mMaterials[am->mMaterialIndex]->Get(AI_MATKEY_NAME, name);
        const std::string n = name.C_Str();
        if (n.rfind(kMaterialPrefix, 0) == 0) part.material = std::stoi(n.substr(std::strlen(kMaterialPrefix)));
        TriangleMesh& mesh = part.mesh;
        for (unsigned v = 0; v < am->mNumVertices; ++v) {
            mesh.positions.emplace_back(am->mVertices[v].x, am->mVertices[v].y, am->mVertices[v].z);
            if (am->HasNormals()) mesh.normals.push_back(unit_or(am->mNormals[v], Vec3f(0, 0, 1)));
            if (am->HasTangentsAndBitangents()) {
                mesh.tangents.push_back(unit_or(am->mTangents[v], Vec3f(0)));
                mesh.tangent_signs.push_back(tangent_sign(am, v));
            }
            if (am->HasTextureCoords(0)) {  // assimp flips v to OpenGL's bottom-up; glTF's v = 0 is the top, as here
                const aiVector3D& t = am->mTextureCoords[0][v];
                mesh.uvs.emplace_back(std::isfinite(t.x) ? t.x : 0.0f, std::isfinite(t.y) ? 1.0f - t.y : 0.0f);
            }
        }
        for (unsigned f = 0; f < am->mNumFaces; ++f) {
            const aiFace& face = am->mFaces[f];
            if (face.mNumIndices != 3) continue;
            for (int k = 0; k < 3; ++k) mesh.indices.push_back(face.mIndices[k]);  // ValidateDataStructure checked them
        }
        if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size()) mesh.normals.clear();
        if (std::find(mesh.tangent_signs.begin(), mesh.tangent_signs.end(), -1) == mesh.tangent_signs.end())
            std::vector<std::int8_t>().swap(mesh.tangent_signs);  // no mirrored vertex: nothing carried
        parts.push_back(std::move(part));
    }
    if (parts.empty()) r.fail("", "the asset has no triangles");
    return parts;
}

float factor(const SceneReader& r, const json& obj, const std::string& w, const char* key, float def) {
    return obj.is_object() ? r.number(obj, w, key, def) : def;
}

}  // namespace

std::string base64_decode(const std::string& text) {
    std::string out;
    unsigned bits = 0;
    int count = 0;
    for (char ch : text) {
        int v;
        if (ch >= 'A' && ch <= 'Z') v = ch - 'A';
        else if (ch >= 'a' && ch <= 'z') v = ch - 'a' + 26;
        else if (ch >= '0' && ch <= '9') v = ch - '0' + 52;
        else if (ch == '+' || ch == '-') v = 62;
        else if (ch == '/' || ch == '_') v = 63;
        else continue;  // '=' padding, whitespace
        bits = (bits << 6) | unsigned(v);
        if ((count += 6) >= 8) {
            count -= 8;
            out.push_back(char((bits >> count) & 0xFF));
        }
    }
    return out;
}

GltfFa gltf_material_to_fa(const SceneReader& r, const json& m, const std::string& w) {
    if (!m.is_object()) r.fail(w, "expected an object");
    const json none = json::object();
    const json& pbr = m.contains("pbrMetallicRoughness") ? m.at("pbrMetallicRoughness") : none;
    const json& ext = m.contains("extensions") && m.at("extensions").is_object() ? m.at("extensions") : none;
    const json& ior_ext = ext.contains("KHR_materials_ior") ? ext.at("KHR_materials_ior") : none;
    const json& spec_ext = ext.contains("KHR_materials_specular") ? ext.at("KHR_materials_specular") : none;
    const json& aniso_ext = ext.contains("KHR_materials_anisotropy") ? ext.at("KHR_materials_anisotropy") : none;
    const std::string wp = w + ".pbrMetallicRoughness", we = w + ".extensions.";
    const glm::vec4 base4 = pbr.is_object() ? r.vec<4>(pbr, wp, "baseColorFactor", glm::vec4(1.0f)) : glm::vec4(1.0f);
    auto unit_interval = [&](float x, const std::string& where) {
        if (!(x >= 0.0f && x <= 1.0f)) r.fail(where, "must be in [0, 1], got " + format_number(x));
        return x;
    };
    Vec3f base(base4.x, base4.y, base4.z);
    for (int c = 0; c < 3; ++c) unit_interval(base[c], wp + ".baseColorFactor[" + std::to_string(c) + "]");
    const float metallic = unit_interval(factor(r, pbr, wp, "metallicFactor", 1.0f), wp + ".metallicFactor");
    const float roughness = unit_interval(factor(r, pbr, wp, "roughnessFactor", 1.0f), wp + ".roughnessFactor");
    const float ior = factor(r, ior_ext, we + "KHR_materials_ior", "ior", 1.5f);
    if (!(ior == 0.0f || ior >= 1.0f)) r.fail(we + "KHR_materials_ior.ior", "must be >= 1 or 0, got " + format_number(ior));
    const float specular = unit_interval(factor(r, spec_ext, we + "KHR_materials_specular", "specularFactor", 1.0f),
                                         we + "KHR_materials_specular.specularFactor");
    const Vec3f spec_color = spec_ext.is_object() ? r.nonnegative_vec<3>(spec_ext, we + "KHR_materials_specular", "specularColorFactor", Vec3f(1.0f)) : Vec3f(1.0f);
    const float strength = unit_interval(factor(r, aniso_ext, we + "KHR_materials_anisotropy", "anisotropyStrength", 0.0f),
                                         we + "KHR_materials_anisotropy.anisotropyStrength");
    GltfFa out;
    out.rotation = factor(r, aniso_ext, we + "KHR_materials_anisotropy", "anisotropyRotation", 0.0f);
    const double f0_ior = ior == 0.0f ? 1.0 : ((double(ior) - 1.0) / (double(ior) + 1.0)) * ((double(ior) - 1.0) / (double(ior) + 1.0));
    GltfFactors& k = out.factors;
    for (int c = 0; c < 3; ++c) {
        k.base[c] = base[c];
        k.dielectric_f0[c] = std::min(f0_ior * double(spec_color[c]), 1.0) * double(specular);  // KHR_materials_specular's clamp
    }
    k.metallic = metallic, k.roughness = roughness, k.anisotropy = strength;
    out.params = gltf_fa(k.base, k.metallic, k.roughness, k.dielectric_f0, k.anisotropy);
    return out;
}

GltfAsset read_gltf(const std::string& path) {
    const SceneReader r(path, "");
    check_input_file(path, "glTF file");
    Asset a;
    a.path = path;
    const auto slash = path.find_last_of('/');
    a.folder = slash == std::string::npos ? "." : path.substr(0, slash);
    const std::uint64_t size = file_size(path);
    if (size > kMaxGltfBytes)
        r.fail("", std::to_string(size) + " bytes, above the limit of " + std::to_string(kMaxGltfBytes) + " for a glTF asset");
    {
        std::ifstream in(path, std::ios::binary);
        if (!in) r.fail("", "cannot open the file");
        a.bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    a.glb = a.bytes.size() >= 4 && le32(reinterpret_cast<const unsigned char*>(a.bytes.data())) == kGlbMagic;
    if (a.glb || ascii_lower(path.substr(path.size() >= 4 ? path.size() - 4 : 0)) == ".glb") {
        a.glb = true;
        split_glb(r, a);
    } else {
        a.doc = parse_json(r, a.bytes, "");
    }
    const json& asset = a.doc.contains("asset") ? a.doc.at("asset") : json();
    if (!asset.is_object() || !asset.contains("version") || !asset.at("version").is_string() ||
        asset.at("version").get<std::string>().rfind("2.", 0) != 0)
        r.fail("asset.version", "expected \"2.0\" (only glTF 2.0 is read)");
    std::vector<std::uint64_t> buffer_lengths;
    if (a.doc.contains("buffers")) check_buffers(r, a, buffer_lengths);
    check_views_and_accessors(r, a, buffer_lengths);
    check_indices(r, a);
    GltfAsset out;
    const json& materials = array_of(r, a.doc, "materials");
    GltfImages images(r, a.doc, a.buffers, a.folder);
    for (std::size_t i = 0; i < materials.size(); ++i) {
        const std::string w = "materials[" + std::to_string(i) + "]";
        GltfFa fa = gltf_material_to_fa(r, materials[i], w);
        fa.name = materials[i].contains("name") ? r.string(materials[i].at("name"), w + ".name") : "";
        // Its textures, decoded (bounded from their headers first): unbound materials read all
        // three, bound ones the normalTexture (scene_loader.cpp).
        const json& m = materials[i];
        const json none = json::object();
        const json& pbr = m.contains("pbrMetallicRoughness") ? m.at("pbrMetallicRoughness") : none;
        fa.base_color = images.texture(pbr, "baseColorTexture", w + ".pbrMetallicRoughness", true);
        fa.metallic_roughness = images.texture(pbr, "metallicRoughnessTexture", w + ".pbrMetallicRoughness", false);
        if (std::optional<GltfTexture> t = images.texture(m, "normalTexture", w, false)) {
            GltfNormalTexture n;
            n.texture = std::move(*t);
            n.scale = factor(r, m.at("normalTexture"), w + ".normalTexture", "scale", 1.0f);
            fa.normal = std::move(n);
        }
        out.materials.push_back(std::move(fa));
    }
    out.parts = read_parts(r, a);
    return out;
}

bool rotate_tangents(TriangleMesh& mesh, float angle) {
    if (angle == 0.0f) return true;
    if (mesh.tangents.empty() || mesh.normals.size() != mesh.tangents.size()) return false;
    const float c = std::cos(angle), s = std::sin(angle);
    for (std::size_t v = 0; v < mesh.tangents.size(); ++v) {
        Vec3f& t = mesh.tangents[v];
        // counter-clockwise toward glTF's bitangent w n x t
        const float w = mesh.tangent_signs.empty() ? 1.0f : float(mesh.tangent_signs[v]);
        t = c * t + (s * w) * glm::cross(mesh.normals[v], t);
    }
    return true;
}

}  // namespace hbrdf::render::detail
