// hybridbrdf renderer — the scene: geometry in an Embree 3 BVH, materials, the
// environment light, the camera and the render settings it was saved with.
//
// Geometry: triangle meshes (Embree triangles) and analytic spheres (Embree
// user geometry: exact normals and tangents, no tessellation error, which is
// what a reference needs). Every surface is two-sided: a ray that hits a face
// from behind sees it with flipped normals.
//
// Shading frames (+z = shading normal, +x = tangent = the GGX alpha_x axis):
//   sphere  tangent along d p / d phi for phi about the world +y axis
//           (horizontal circles); at the poles any frame.
//   mesh    interpolated vertex normals (geometric normal when the mesh has
//           none); tangent from the file's UVs (assimp's tangent space) made
//           orthogonal to the normal, else Frame::from_normal (arbitrary
//           azimuth: anisotropic materials on UV-less meshes have no
//           meaningful orientation).
//   plane   the normal and the "tangent" given in the scene.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "hybridbrdf/render/camera.hpp"
#include "hybridbrdf/render/environment.hpp"
#include "hybridbrdf/render/light.hpp"
#include "hybridbrdf/render/material.hpp"
#include "hybridbrdf/render/mesh.hpp"
#include "hybridbrdf/render/ray_cone.hpp"
#include "hybridbrdf/render/settings.hpp"

// Embree's handles, without its header.
typedef struct RTCDeviceTy* RTCDevice;
typedef struct RTCSceneTy* RTCScene;

namespace hbrdf::render {

struct Sphere {
    Vec3f center{0.0f};
    float radius = 1.0f;
};

/// A surface point seen by a ray.
struct SurfaceHit {
    float t = 0;
    Vec3f p;       ///< position
    Vec3f ng;      ///< geometric normal, facing the incoming ray
    Frame shading; ///< shading frame, its normal on the same side as ng
    /// texture coordinates (docs/SVBRDF.md): spheres u = phi / 2 pi about +y (along the tangent),
    /// v = theta / pi from the +y pole; meshes their interpolated vertex uvs (0 without); planes
    /// 0 to 1 across (make_plane)
    Vec2<float> uv{0.0f};
    /// log2 of uv units per world unit here, 0.5 log2(uv area / world area) (ray_cone.hpp): of the
    /// triangle hit, or of the sphere's uv map at the point; kPointFootprint where uv does not vary
    float uv_scale_log2 = kPointFootprint;
    /// the gradients of u and v along the surface (world vectors: du = du_dp . dp for dp in the
    /// tangent plane; ray_cone.hpp), zero where uv does not vary: the anisotropic footprint's
    Vec3f du_dp{0.0f}, dv_dp{0.0f};
    int material = -1;
};

class Scene {
public:
    Scene();
    ~Scene();
    Scene(const Scene&) = delete;
    Scene& operator=(const Scene&) = delete;
    Scene(Scene&&) noexcept;
    Scene& operator=(Scene&&) noexcept;

    /// Adds a material; returns its index.
    int add_material(std::unique_ptr<Material> material);
    /// add_mesh and add_sphere throw std::invalid_argument for geometry Embree cannot trace
    /// correctly: non-finite vertices, indices out of range, and coordinates beyond the float32
    /// limits of limits.hpp (check_extent) at the scale of `camera`: set the camera first.
    void add_mesh(TriangleMesh mesh, int material);
    void add_sphere(const Sphere& sphere, int material);
    /// Builds the BVH; call once after the last add_*. Throws std::runtime_error on Embree errors.
    void commit();

    /// Closest hit along origin + t dir, t in (0, t_max). Thread-safe after commit().
    bool intersect(const Vec3f& origin, const Vec3f& dir, SurfaceHit* hit, float t_max = 1e30f) const;
    /// True when anything lies along origin + t dir, t in (0, t_max).
    bool occluded(const Vec3f& origin, const Vec3f& dir, float t_max = 1e30f) const;

    /// A ray origin just off the surface on the side of direction `dir`
    /// (offset along the geometric normal, scaled with the distance from the
    /// origin of the world, so that the new ray does not hit its own surface).
    static Vec3f offset_origin(const SurfaceHit& hit, const Vec3f& dir);

    std::vector<std::unique_ptr<Material>> materials;
    EnvironmentLight environment;
    /// Point and directional lights (light.hpp), reached by next-event estimation only.
    DeltaLights lights;
    PinholeCamera camera;
    /// The settings the scene was saved with (settings.hpp). render() takes
    /// them as RenderOptions, so that callers can override any of them; the
    /// sampler is applied to the materials when the scene is loaded.
    RenderSettings settings;

    std::size_t mesh_count() const { return meshes_.size(); }
    std::size_t sphere_count() const { return spheres_.size(); }
    /// The geometry as added (world space), for tools that draw the same scene another way (the
    /// raster frame, issue 59): mesh i and its material, sphere i and its material, in the order
    /// add_mesh / add_sphere were called.
    const TriangleMesh& mesh(std::size_t i) const { return *meshes_.at(i); }
    int mesh_material(std::size_t i) const;
    const Sphere& sphere(std::size_t i) const { return *spheres_.at(i); }
    int sphere_material(std::size_t i) const;

private:
    struct Geometry {
        bool is_sphere = false;
        int index = 0;     ///< into meshes_ or spheres_
        int material = 0;
    };
    RTCDevice device_ = nullptr;
    RTCScene scene_ = nullptr;
    std::vector<Geometry> geometries_;  ///< by Embree geometry id
    std::vector<std::unique_ptr<TriangleMesh>> meshes_;
    std::vector<std::unique_ptr<Sphere>> spheres_;
    bool committed_ = false;
};

}  // namespace hbrdf::render
