// hybridbrdf renderer — meshes from files (assimp) and planes.
#include "hybridbrdf/render/mesh.hpp"

#include <cmath>

#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <assimp/Importer.hpp>
#include <fstream>
#include <string>

#include <glm/matrix.hpp>

#include "hybridbrdf/render/image.hpp"

namespace hbrdf::render {

namespace {

Vec3f normalized_or(const Vec3f& v, const Vec3f& fallback) {
    const float l2 = dot(v, v);
    return (l2 > 0.0f && is_finite(l2)) ? v / std::sqrt(l2) : fallback;
}

}  // namespace

void transform_mesh(TriangleMesh& mesh, const Transform& xf) {
    const glm::mat3 normal_map = glm::transpose(glm::inverse(xf.linear));
    for (Vec3f& p : mesh.positions) p = xf.point(p);
    for (Vec3f& n : mesh.normals) n = normalized_or(normal_map * n, Vec3f(0, 0, 1));
    for (Vec3f& t : mesh.tangents) t = normalized_or(xf.linear * t, Vec3f(0));
    // A mirroring map turns n x t against the mapped bitangent: every vertex's handedness flips.
    if (glm::determinant(xf.linear) < 0.0f && !mesh.tangents.empty()) {
        if (mesh.tangent_signs.empty()) mesh.tangent_signs.assign(mesh.tangents.size(), std::int8_t(1));
        for (std::int8_t& w : mesh.tangent_signs) w = std::int8_t(-w);
    }
}

std::int64_t first_nonfinite_vertex(const TriangleMesh& mesh) {
    for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
        const Vec3f& p = mesh.positions[i];
        if (!(is_finite(p.x) && is_finite(p.y) && is_finite(p.z))) return std::int64_t(i);
    }
    return -1;
}

TriangleMesh load_mesh(const std::string& path, bool smooth_normals) {
    check_input_file(path, "mesh file");  // before opening: a FIFO blocks the open, a device never ends
    if (!std::ifstream(path).good()) throw FileError(path, "cannot open the mesh file");
    Assimp::Importer importer;
    unsigned flags = aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_PreTransformVertices |
                     aiProcess_SortByPType | aiProcess_CalcTangentSpace |
                     aiProcess_ValidateDataStructure;  // first: out-of-range indices would corrupt the later steps
    if (smooth_normals) flags |= aiProcess_GenSmoothNormals;
    const aiScene* scene = importer.ReadFile(path, flags);
    if (!scene || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) || scene->mNumMeshes == 0) {
        std::string problem = scene ? "the file holds no triangle mesh" : importer.GetErrorString();
        // assimp reports a header that declares more elements than fit as the allocation failure.
        if (problem.find("bad_alloc") != std::string::npos) problem = "it declares more data than fits in memory";
        throw FileError(path, "cannot read the mesh: " + problem);
    }
    TriangleMesh mesh;
    bool all_normals = smooth_normals, all_tangents = true, all_uvs = true;
    for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
        const aiMesh* am = scene->mMeshes[m];
        all_normals = all_normals && am->HasNormals();
        all_tangents = all_tangents && am->HasTangentsAndBitangents();
        all_uvs = all_uvs && am->HasTextureCoords(0);
    }
    for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
        const aiMesh* am = scene->mMeshes[m];
        if (!(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;  // points and lines
        const auto base = std::uint32_t(mesh.positions.size());
        for (unsigned v = 0; v < am->mNumVertices; ++v) {
            const aiVector3D& p = am->mVertices[v];
            mesh.positions.emplace_back(p.x, p.y, p.z);
            if (all_normals) {
                const aiVector3D& n = am->mNormals[v];
                mesh.normals.push_back(normalized_or(Vec3f(n.x, n.y, n.z), Vec3f(0, 0, 1)));
            }
            if (all_tangents) {
                const aiVector3D& t = am->mTangents[v];
                mesh.tangents.push_back(normalized_or(Vec3f(t.x, t.y, t.z), Vec3f(0)));
            }
            if (all_uvs) {  // files put v = 0 at the bottom (OpenGL); textures here have it at the top (glTF)
                const aiVector3D& t = am->mTextureCoords[0][v];
                mesh.uvs.emplace_back(std::isfinite(t.x) ? t.x : 0.f, std::isfinite(t.y) ? 1.f - t.y : 0.f);
            }
        }
        for (unsigned f = 0; f < am->mNumFaces; ++f) {
            const aiFace& face = am->mFaces[f];
            if (face.mNumIndices != 3) continue;
            for (int k = 0; k < 3; ++k) {
                if (face.mIndices[k] >= am->mNumVertices)  // a malformed file; Embree would read out of bounds
                    throw FileError(path, "face " + std::to_string(f) + " refers to vertex " + std::to_string(face.mIndices[k]) +
                                              ", but the mesh has " + std::to_string(am->mNumVertices));
                mesh.indices.push_back(base + face.mIndices[k]);
            }
        }
    }
    if (mesh.indices.empty()) throw FileError(path, "the mesh has no triangles");
    if (const std::int64_t v = first_nonfinite_vertex(mesh); v >= 0)
        throw FileError(path, "vertex " + std::to_string(v) + " is not finite");
    return mesh;
}

TriangleMesh make_plane(const Vec3f& center, const Vec3f& normal, const Vec3f& tangent, float sx, float sy) {
    const Vec3f n = normalized_or(normal, Vec3f(0, 1, 0));
    const Frame frame = Frame::from_normal_tangent(n, tangent);
    const Vec3f a = frame.t * (0.5f * sx), b = frame.b * (0.5f * sy);
    TriangleMesh mesh;
    mesh.positions = {center - a - b, center + a - b, center + a + b, center - a + b};
    mesh.normals.assign(4, n);
    mesh.tangents.assign(4, frame.t);
    mesh.uvs = {Vec2<float>(0, 1), Vec2<float>(1, 1), Vec2<float>(1, 0), Vec2<float>(0, 0)};
    mesh.indices = {0, 1, 2, 0, 2, 3};  // counter-clockwise seen from +n
    return mesh;
}

}  // namespace hbrdf::render
