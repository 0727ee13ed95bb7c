// hybridbrdf renderer — orthonormal shading frames.
//
// The BRDF lives in the local frame of docs/CONVENTIONS.md: +z the shading
// normal, +x the tangent (the alpha_x axis), +y the bitangent. A Frame maps
// world directions into it and back.
#pragma once

#include <cmath>

#include <glm/geometric.hpp>

#include "hybridbrdf/math.hpp"

namespace hbrdf::render {

using Vec3f = Vec3<float>;

struct Frame {
    Vec3f t{1, 0, 0}, b{0, 1, 0}, n{0, 0, 1};

    Vec3f to_local(const Vec3f& w) const { return Vec3f(dot(w, t), dot(w, b), dot(w, n)); }
    Vec3f to_world(const Vec3f& w) const { return t * w.x + b * w.y + n * w.z; }

    /// Any orthonormal frame around unit n (Duff et al. 2017, "Building an
    /// orthonormal basis, revisited": continuous except at n.z = -0 and free of
    /// the cancellation of Frisvad's original). Used where no tangent is known,
    /// which is harmless for isotropic materials and documented for the rest.
    static Frame from_normal(const Vec3f& n) {
        const float sign = std::copysign(1.0f, n.z);
        const float a = -1.0f / (sign + n.z);
        const float b = n.x * n.y * a;
        Frame f;
        f.n = n;
        f.t = Vec3f(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x);
        f.b = Vec3f(b, sign + n.y * n.y * a, -n.y);
        return f;
    }

    /// Frame with normal n whose tangent is `tangent` made orthogonal to n
    /// (Gram-Schmidt); falls back to from_normal() when the tangent is (nearly)
    /// parallel to n or not finite.
    static Frame from_normal_tangent(const Vec3f& n, const Vec3f& tangent) {
        const Vec3f t = tangent - n * dot(n, tangent);
        const float len2 = dot(t, t);
        if (!(len2 > 1e-12f) || !is_finite(len2)) return from_normal(n);
        Frame f;
        f.n = n;
        f.t = t / std::sqrt(len2);
        f.b = glm::cross(n, f.t);
        return f;
    }
};

}  // namespace hbrdf::render
