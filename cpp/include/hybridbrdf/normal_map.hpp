// hybridbrdf — tangent-space normal maps: the shading frame a texel's normal builds from the
// geometric frame, and the horizon rule (docs/SVBRDF.md, "Normal maps"; Python's twin is
// hybridbrdf.svbrdf.normals). Header-only and free of the rest of the library but math.hpp, so
// that an engine passes its own TBN.
//
// Convention (glTF 2.0 normalTexture): the map stores x, y in [-1, 1] (8-bit: 2 v - 1, linear);
// z = sqrt(max(0, 1 - x^2 - y^2)). +x is the tangent t (increasing u), +y the bitangent b = n x t
// of the right-handed geometric frame (t, b, n): with this library's uv (v = 0 the image's top row,
// as glTF's) b points towards decreasing v, the image's top, when the uv map is not mirrored
// (green up, OpenGL-style: glTF's bitangent = cross(normal, tangent.xyz) * tangent.w, w = +1).
// An engine with mirrored uv passes its b = -(n x t).
//
// Frame: n_s = normalize(x t + y b + z n); t_s = t - (t . n_s) n_s normalised (Gram-Schmidt: the
// anisotropic alpha_x axis stays as near the tangent as the normal allows); b_s = n_s x t_s.
// Rule: f = 0 unless wi and wo are above both the shading horizon (n_s) and the geometric one
// (n): the same test for both directions keeps the texel reciprocal where its layers are, and it
// only removes lobe, so the albedo in the perturbed frame stays within the layers' bound.
#pragma once

#include <algorithm>
#include <cmath>

#include "hybridbrdf/math.hpp"

namespace hbrdf {

/// An orthonormal frame (t, b, n): directions into its coordinates and back.
struct ShadingFrame {
    Vec3<float> t{1, 0, 0}, b{0, 1, 0}, n{0, 0, 1};

    Vec3<float> to_local(const Vec3<float>& w) const { return Vec3<float>(dot(w, t), dot(w, b), dot(w, n)); }
    Vec3<float> to_world(const Vec3<float>& w) const { return t * w.x + b * w.y + n * w.z; }
};

/// The unit tangent-space normal of a map's stored (x, y): z = sqrt(max(0, 1 - x^2 - y^2)), then
/// normalised (x^2 + y^2 > 1 gives a vector longer than 1). Non-finite input reads (0, 0, 1).
inline Vec3<float> tangent_normal(float x, float y) {
    if (!is_finite(x) || !is_finite(y)) return Vec3<float>(0.f, 0.f, 1.f);
    const double z = std::sqrt(std::max(0.0, 1.0 - double(x) * x - double(y) * y));
    const double len = std::sqrt(double(x) * x + double(y) * y + z * z);
    if (!(len > 0.0)) return Vec3<float>(0.f, 0.f, 1.f);
    return Vec3<float>(float(x / len), float(y / len), float(z / len));
}

/// The shading frame of tangent-space normal `tn` (unit) on the geometric frame (t, b, n) (unit,
/// orthogonal, b = n x t), in the coordinates t, b, n are given in. When the normal lies along
/// +-t (Gram-Schmidt leaves nothing), t_s = b x n_s normalised.
inline ShadingFrame shading_frame(const Vec3<float>& t, const Vec3<float>& b, const Vec3<float>& n, const Vec3<float>& tn) {
    const auto cross = [](const Vec3<float>& p, const Vec3<float>& q) {
        return Vec3<float>(p.y * q.z - p.z * q.y, p.z * q.x - p.x * q.z, p.x * q.y - p.y * q.x);
    };
    ShadingFrame f;
    Vec3<float> ns = t * tn.x + b * tn.y + n * tn.z;
    ns = ns * inverse_length_or_zero(ns);
    if (!(dot(ns, ns) > 0.f)) ns = n;
    Vec3<float> ts = t - ns * dot(t, ns);
    float inv = inverse_length_or_zero(ts);
    if (!(dot(ts, ts) > 1e-12f)) ts = cross(b, ns), inv = inverse_length_or_zero(ts);
    f.n = ns;
    f.t = ts * inv;
    f.b = cross(f.n, f.t);
    return f;
}

/// The shading frame in the geometric frame's own coordinates (t = +x, b = +y, n = +z): what a
/// BRDF evaluated in local coordinates, as libhybridbrdf's, needs.
inline ShadingFrame shading_frame(const Vec3<float>& tn) {
    return shading_frame(Vec3<float>(1, 0, 0), Vec3<float>(0, 1, 0), Vec3<float>(0, 0, 1), tn);
}

/// The rule: whether f may be nonzero for local (geometric-frame) wi, wo and the shading frame.
inline bool above_both_horizons(const ShadingFrame& s, const Vec3<float>& wi, const Vec3<float>& wo) {
    return wi.z > 0.f && wo.z > 0.f && dot(wi, s.n) > 0.f && dot(wo, s.n) > 0.f;
}

}  // namespace hbrdf
