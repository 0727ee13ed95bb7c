// hbrdf_raster — a tracer scene as the arrays a raster frame draws: vertices, indices and one draw
// per object, the material table, the lights and the camera's projection (no Vulkan here).
//
// Spheres are tessellated on a (phi, theta) grid with the tracer's exact per-vertex frame
// (scene.hpp): normal (p - c) / r, tangent d p / d phi about +y, uv (phi / 2 pi + 1/2, theta / pi);
// `max_sphere_gap` reports how far the flat triangles lie inside the true sphere.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "hybridbrdf/render/gltf_material.hpp"
#include "hybridbrdf/render/scene.hpp"

namespace hbrdf::raster {

/// One vertex as the vertex shader reads it (glsl/raster.vert, locations 0-3).
struct Vertex {
    float p[3];   ///< world position
    float n[3];   ///< shading normal (0: use the triangle's geometric normal, as the tracer)
    float t[3];   ///< tangent (0: the Duff et al. frame of the normal, as the tracer)
    float uv[2];
    float w;      ///< the bitangent's handedness, b = w n x t (glTF TANGENT.w; a triangle takes its first vertex's)
};

/// One indexed draw: an object of the scene and its scene material.
struct Draw {
    uint32_t first_index = 0, index_count = 0;
    int32_t vertex_offset = 0;
    int32_t material = 0;  ///< index into the material table (the push constant)
};

/// A material as the fragment shader reads it (std430, 64 bytes). kind.x is the shader's case:
/// 0 = f_a with the parameters kd, eta, alpha given here; k >= 1 = the k-th --model-material,
/// a constant of the generated code; kGltfCase = a glTF material with textures, f_a of the
/// mapping (docs/GLTF.md) per pixel: kd.xyz its baseColorFactor, eta.xyz its dielectric F0,
/// alpha.xyz its metallic and roughness factors and anisotropy strength. kind.y, kind.z, kind.w:
/// the glTF texture slots (FrameScene::gltf_textures) of its baseColor, metallicRoughness and
/// normal textures, or -1; a normal slot (also on any other row: a bound material keeping the
/// asset's normal map) with its scale in alpha.w.
struct GpuMaterial {
    float kd[4];
    float eta[4];
    float alpha[4];
    int32_t kind[4];
};

inline constexpr int32_t kGltfCase = -2;

struct FrameScene {
    std::vector<Vertex> vertices;
    std::vector<uint32_t> indices;
    std::vector<Draw> draws;
    std::vector<GpuMaterial> materials;  ///< one per scene material, in the scene's order
    /// std430: uvec4(point count, directional count, 0, 0), then per light two vec4: points
    /// (position, intensity), then directionals (direction toward the light, irradiance).
    std::vector<float> lights;
    /// std140 uniform: mat4 view_proj (column-major), vec4 camera position.
    float camera[20] = {};
    double max_sphere_gap = 0;  ///< the largest distance from a sphere's triangles to the sphere, in world units
    /// The glTF textures the rows' slots name, in slot order (each slot one texture and its sampler).
    std::vector<render::GltfTexture> gltf_textures;
};

/// Builds the frame of `scene`. `model_materials` names, in order, the scene materials the shader
/// evaluates as constants of the generated code (cases 1, 2, ...); every other material must be
/// "analytic" or a "model" material with an analytic part, drawn as f_a (case 0: "evaluate":
/// "analytic", or not listed). `sphere_segments` >= 8 divides phi (theta gets half as many).
/// Throws std::invalid_argument naming the material for those the raster frame cannot draw.
FrameScene build_frame_scene(const render::Scene& scene, const std::vector<std::string>& model_materials,
                             int sphere_segments);

}  // namespace hbrdf::raster
