// hybridbrdf renderer — texture footprints by ray cones (docs/RENDERING.md, "Texture footprints").
//
// A camera ray stands for its pixel: a cone from the pinhole, width 0 there, spreading by the
// pixel's width per unit distance (PinholeCamera::pixel_spread). Where it hits a surface at
// distance t it is w = spread t wide, stretched to w / |n.d| along the surface by the slant; in uv
// units that is  w / |n.d| x (uv units per world unit), and in level-0 texels of a W x H texture
//
//     lod = Delta + log2(w / |n.d|),   Delta = 0.5 log2(t_a / p_a)
//
// with t_a the triangle's uv area times W H and p_a its world area (Akenine-Moller et al., "Texture
// Level of Detail Strategies for Real-Time Ray Tracing", Ray Tracing Gems 2019, ch. 20, eq. 34;
// "Improved Shader and Texture Level of Detail Using Ray Cones", JCGT 2021). The renderer splits
// Delta: the surface's share 0.5 log2(uv area / world area) here (SurfaceHit::uv_scale_log2), the
// texture's 0.5 log2(W H) in the textured material, which alone knows W and H.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "hybridbrdf/render/frame.hpp"

namespace hbrdf::render {

/// A footprint that is a point: textured materials read level 0 (lod -inf).
inline constexpr float kPointFootprint = -std::numeric_limits<float>::infinity();

/// 0.5 log2(uv area / world area) of a triangle: log2 of the uv units per world unit on it (the
/// surface's share of Delta). kPointFootprint when its uvs span no area (a mesh without uvs) or its
/// world area is 0. In double: the products of large coordinates would round in float.
inline float triangle_uv_scale_log2(const Vec3f& p0, const Vec3f& p1, const Vec3f& p2, const Vec2<float>& t0,
                                    const Vec2<float>& t1, const Vec2<float>& t2) {
    const double ux = double(t1.x) - t0.x, uy = double(t1.y) - t0.y, vx = double(t2.x) - t0.x, vy = double(t2.y) - t0.y;
    const double uv_area2 = std::fabs(ux * vy - vx * uy);
    const double e1[3] = {double(p1.x) - p0.x, double(p1.y) - p0.y, double(p1.z) - p0.z};
    const double e2[3] = {double(p2.x) - p0.x, double(p2.y) - p0.y, double(p2.z) - p0.z};
    const double c[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    const double world_area2 = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    if (!(uv_area2 > 0.0) || !(world_area2 > 0.0) || !std::isfinite(world_area2)) return kPointFootprint;
    return float(0.5 * std::log2(uv_area2 / world_area2));
}

/// The same for the sphere's uv (u = phi / 2 pi, v = theta / pi; scene.cpp) at polar angle theta:
/// du dv = dphi dtheta / (2 pi^2) over dA = r^2 sin(theta) dphi dtheta, so uv area / world area =
/// 1 / (2 pi^2 r^2 sin theta), exact at the point (the map stretches u toward the poles, where this
/// grows without bound and the lookup reads the chain's coarsest level).
inline float sphere_uv_scale_log2(float radius, float sin_theta) {
    const double s = std::max(double(sin_theta), 1e-12);
    const double pi = 3.14159265358979323846;
    return float(-0.5 * std::log2(2.0 * pi * pi * double(radius) * double(radius) * s));
}

/// log2 of the cone's footprint in uv units at a hit: uv_scale_log2 + log2(width / |cos_nd|), with
/// cos_nd the cosine between the geometric normal and the ray. kPointFootprint for a cone of width 0
/// or a surface without a uv scale; a grazing hit (cos_nd -> 0) gives a large footprint, which the
/// lookup clamps to the chain's coarsest level.
inline float cone_footprint_log2(float width, float cos_nd, float uv_scale_log2) {
    if (!(width > 0.0f) || !(uv_scale_log2 > kPointFootprint)) return kPointFootprint;
    const double c = std::max(std::fabs(double(cos_nd)), 1e-12);
    return float(double(uv_scale_log2) + std::log2(double(width) / c));
}

/// The camera cone's spread per pixel sample: pixel_spread x max(1/8, 1/sqrt(spp)). A pixel of many
/// samples averages the texture over its area itself, so each sample's cone narrows with their
/// number (pbrt-v3/v4 scale their camera rays' differentials the same way): at 1 spp a sample
/// filters its whole pixel, and a converged render tends to the pixel's box filter of level 0.
inline float camera_cone_spread(float pixel_spread, int spp) {
    return pixel_spread * float(std::max(0.125, 1.0 / std::sqrt(double(std::max(spp, 1)))));
}

}  // namespace hbrdf::render
