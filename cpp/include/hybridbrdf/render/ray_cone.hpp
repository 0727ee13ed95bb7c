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

/// Where a hit reads its textures (docs/RENDERING.md, "Anisotropic footprints"). The isotropic
/// cone's width, and for the anisotropic lookup (`"anisotropic": N`, N >= 2 probes) the pixel's
/// footprint on the surface in uv: its two screen axes, duv/dx and duv/dy per (cone-scaled) pixel
/// from ray differentials, and the offset from the hit's uv to the footprint's centre.
struct Footprint {
    float cone_log2 = kPointFootprint;  ///< log2 of the cone's width in uv units (cone_footprint_log2)
    Vec2<float> duv_dx{0.0f, 0.0f}, duv_dy{0.0f, 0.0f};
    Vec2<float> centre{0.0f, 0.0f};     ///< uv offset of the footprint's centre from the hit
    int max_probes = 1;                 ///< 1: the cone's isotropic lookup; N >= 2: up to N probes
    bool anisotropic() const { return max_probes > 1; }
};

/// The gradients of u and v over a triangle's plane (world vectors g_u, g_v with du = g_u . dp for
/// dp in the plane): g = a e1 + b e2 solving g . e1 = du1, g . e2 = du2 through the edges' Gram
/// matrix, in double. Zero for a triangle of no world area or without uvs.
inline void triangle_uv_gradients(const Vec3f& p0, const Vec3f& p1, const Vec3f& p2, const Vec2<float>& t0,
                                  const Vec2<float>& t1, const Vec2<float>& t2, Vec3f* du_dp, Vec3f* dv_dp) {
    const double e1[3] = {double(p1.x) - p0.x, double(p1.y) - p0.y, double(p1.z) - p0.z};
    const double e2[3] = {double(p2.x) - p0.x, double(p2.y) - p0.y, double(p2.z) - p0.z};
    const double g11 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2], g22 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
    const double g12 = e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2];
    const double det = g11 * g22 - g12 * g12;
    *du_dp = *dv_dp = Vec3f(0.0f);
    if (!(det > 1e-30 * g11 * g22) || !std::isfinite(det)) return;
    const double d[2][2] = {{double(t1.x) - t0.x, double(t2.x) - t0.x}, {double(t1.y) - t0.y, double(t2.y) - t0.y}};
    Vec3f* out[2] = {du_dp, dv_dp};
    for (int k = 0; k < 2; ++k) {
        const double a = (g22 * d[k][0] - g12 * d[k][1]) / det, b = (g11 * d[k][1] - g12 * d[k][0]) / det;
        *out[k] = Vec3f(float(a * e1[0] + b * e2[0]), float(a * e1[1] + b * e2[1]), float(a * e1[2] + b * e2[2]));
    }
}

/// The same for the sphere's uv at unit normal n (u = phi / 2 pi with phi = atan2(n.z, n.x), v =
/// theta / pi with theta = acos(n.y); scene.cpp): |grad phi| = 1 / (r sin theta) along
/// (-n.z, 0, n.x) / sin theta, |grad theta| = 1 / r along dn/dtheta = (n.y n.x, -sin^2 theta,
/// n.y n.z) / sin theta. sin theta is held above 1e-6 at the poles (a huge footprint there).
inline void sphere_uv_gradients(const Vec3f& n, float radius, Vec3f* du_dp, Vec3f* dv_dp) {
    const double s2 = std::max(double(n.x) * n.x + double(n.z) * n.z, 1e-12), r = double(radius);
    const double pi = 3.14159265358979323846;
    const double ku = 1.0 / (2.0 * pi * r * s2), kv = 1.0 / (pi * r * std::sqrt(s2));
    *du_dp = Vec3f(float(-n.z * ku), 0.0f, float(n.x * ku));
    *dv_dp = Vec3f(float(n.y * n.x * kv), float(-s2 * kv), float(n.y * n.z * kv));
}

/// The surface's motion per unit step of the camera ray's unnormalised direction D along e (a ray
/// differential, Igehy 1999; pbrt-v4's Camera::Approximate_dp_dxy): the offset ray o + t' (D + e)
/// meets the hit's tangent plane at p + t_D (e - D (e . n) / (D . n)), with t_D the hit's parameter
/// along D. Infinite where D lies in the plane.
inline Vec3f ray_differential_dp(const Vec3f& D, float t_D, const Vec3f& e, const Vec3f& n) {
    const float dn = dot(D, n);
    if (dn == 0.0f) return Vec3f(std::numeric_limits<float>::infinity());  // the lookup reads the coarsest level
    return (e - D * (dot(e, n) / dn)) * t_D;
}

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
