// hybridbrdf renderer — triangle meshes: read from OBJ/PLY (and whatever else
// assimp reads), or built for a plane.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/mat3x3.hpp>

#include "hybridbrdf/render/frame.hpp"

namespace hbrdf::render {

struct TriangleMesh {
    std::vector<Vec3f> positions;
    std::vector<Vec3f> normals;   ///< per vertex shading normals; empty = use the geometric normal
    std::vector<Vec3f> tangents;  ///< per vertex tangents (from UVs); empty = arbitrary frame
    /// per vertex bitangent handedness, -1 or +1 (glTF's TANGENT.w: b = w n x t; -1 on a mirrored
    /// uv island); empty = +1 everywhere, so meshes without mirrored uvs carry nothing
    std::vector<std::int8_t> tangent_signs;
    /// per vertex texture coordinates, (0, 0) the texture's top left (glTF 2.0; docs/SVBRDF.md);
    /// empty = uv (0, 0) everywhere
    std::vector<Vec2<float>> uvs;
    std::vector<std::uint32_t> indices;  ///< 3 per triangle

    std::size_t triangle_count() const { return indices.size() / 3; }
};

/// A 3x3 linear map plus a translation, applied to positions (normals use
/// the inverse transpose, tangents the linear part).
struct Transform {
    glm::mat3 linear{1.0f};
    Vec3f translation{0.0f};

    Vec3f point(const Vec3f& p) const { return linear * p + translation; }
};

/// Applies `xf` to every vertex, normal and tangent (renormalised).
void transform_mesh(TriangleMesh& mesh, const Transform& xf);

/// The index of the first vertex with a non-finite coordinate, or -1.
std::int64_t first_nonfinite_vertex(const TriangleMesh& mesh);

/// Reads every mesh of a model file through assimp (triangulated, vertices
/// joined). With smooth_normals, missing normals are generated smooth;
/// otherwise vertex normals are dropped and the geometric normal shades.
/// Tangents are taken when the file has UVs. Throws FileError("<path>: ...")
/// for files that cannot be read, faces whose indices are out of range and
/// vertices that are not finite.
TriangleMesh load_mesh(const std::string& path, bool smooth_normals = true);

/// A square-cornered rectangle of size (sx, sy) centred at `center`, facing
/// `normal`, its first side along `tangent` (any direction not parallel to
/// the normal; the shading frame's +x). uv: u along the tangent from 0 to 1, v from 0 at the
/// side the bitangent (normal x tangent) points to, to 1: the image upright seen from +normal.
TriangleMesh make_plane(const Vec3f& center, const Vec3f& normal, const Vec3f& tangent, float sx, float sy);

}  // namespace hbrdf::render
