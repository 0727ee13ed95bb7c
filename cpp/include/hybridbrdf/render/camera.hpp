// hybridbrdf renderer — the pinhole camera.
#pragma once

#include <algorithm>
#include <cmath>
#include <string>
#include <stdexcept>

#include "hybridbrdf/render/frame.hpp"
#include "hybridbrdf/render/limits.hpp"

namespace hbrdf::render {

struct Ray {
    Vec3f origin;
    Vec3f dir;  ///< unit
};

/// A pinhole at `position` looking at `look_at`; `fov_deg` is the full
/// vertical field of view; pixel (0, 0) is the top-left corner of the image.
class PinholeCamera {
public:
    PinholeCamera() = default;
    PinholeCamera(const Vec3f& position, const Vec3f& look_at, const Vec3f& up, float fov_deg, int width, int height)
        : position_(position), width_(width), height_(height) {
        if (width < 1 || height < 1) throw std::invalid_argument("camera width and height must be >= 1");
        // Before anything allocates the film (limits.hpp): an error, not std::bad_alloc.
        const std::string too_big = check_image_size(width, height, kMaxFilmPixels, kFilmBytesPerPixel, "of film");
        if (!too_big.empty()) throw std::invalid_argument("width x height = " + too_big);
        if (!(fov_deg > 0.0f && fov_deg < 180.0f)) throw std::invalid_argument("camera fov_deg must be in (0, 180)");
        // Before any float arithmetic on them: the scene's scale comes from here (limits.hpp).
        for (const Vec3f* p : {&position, &look_at}) {
            const double extent = std::max({std::fabs(double(p->x)), std::fabs(double(p->y)), std::fabs(double(p->z))});
            if (!(extent <= kMaxCoordinate))
                throw std::invalid_argument(std::string(p == &position ? "position" : "look_at") + " has a coordinate of magnitude " +
                                            format_number(extent) + ", above the limit " +
                                            format_number(kMaxCoordinate) + " for any coordinate (docs/RENDERING.md, \"Limits\")");
        }
        const Vec3f f = look_at - position;
        if (!(dot(f, f) > 0.0f)) throw std::invalid_argument("camera look_at equals position");
        distance_ = std::sqrt(double(f.x) * f.x + double(f.y) * f.y + double(f.z) * f.z);
        const double offset = std::max({std::fabs(double(position.x)), std::fabs(double(position.y)), std::fabs(double(position.z))});
        if (!(offset <= kMaxCameraOffsetOverDistance * distance_))
            throw std::invalid_argument(
                "position has a coordinate of magnitude " + format_number(offset) + ", above the limit " +
                format_number(kMaxCameraOffsetOverDistance * distance_) + " = " +
                format_number(kMaxCameraOffsetOverDistance) + " x its distance to look_at (" + format_number(distance_) +
                "): rays that far out start too far from their surfaces; move the scene's origin near the "
                "camera, or look_at onto the subject (docs/RENDERING.md, \"Limits\")");
        forward_ = glm::normalize(f);
        const Vec3f r = glm::cross(forward_, up);
        if (!(dot(r, r) > 1e-12f)) throw std::invalid_argument("camera up is parallel to the viewing direction");
        right_ = glm::normalize(r);
        up_ = glm::cross(right_, forward_);
        tan_half_ = std::tan(0.5f * fov_deg * 3.14159265358979323846f / 180.0f);
        aspect_ = float(width) / float(height);
    }

    int width() const { return width_; }
    /// |look_at - position|: the scale of what the camera frames, which bounds the scene's
    /// coordinates (limits.hpp, check_extent). 1 for a default-constructed camera.
    double distance() const { return distance_; }
    int height() const { return height_; }
    /// The pinhole and its orthonormal basis (forward = toward look_at, right, up = right x
    /// forward), and tan(fov / 2): generate() maps pixel (px, py) to the direction
    /// forward + right sx + up sy. For tools that project the scene instead of tracing it
    /// (the raster frame, issue 59: hbrdf_raster's projection matrix).
    const Vec3f& position() const { return position_; }
    const Vec3f& forward() const { return forward_; }
    const Vec3f& right() const { return right_; }
    const Vec3f& up() const { return up_; }
    float tan_half_fov() const { return tan_half_; }

    /// The width of one pixel per unit of distance along the view axis, 2 tan(fov / 2) / height:
    /// a camera ray's cone spreads by this (the ray cones of Akenine-Moller et al., Ray Tracing Gems
    /// 2019, ch. 20, whose spread angle arctan(2 tan(fov / 2) / height) it is the tangent of), so
    /// a cone at distance t from the pinhole is this x t wide, the pixel's exact width at the
    /// image centre on a surface facing the camera.
    float pixel_spread() const { return 2.0f * tan_half_ / float(height_); }

    /// The ray through image point (px, py) in pixel units (px in [0, width),
    /// py in [0, height), y down).
    Ray generate(float px, float py) const {
        const float sx = (2.0f * px / float(width_) - 1.0f) * tan_half_ * aspect_;
        const float sy = (1.0f - 2.0f * py / float(height_)) * tan_half_;
        return Ray{position_, glm::normalize(forward_ + right_ * sx + up_ * sy)};
    }

private:
    Vec3f position_{0, 0, 0}, forward_{0, 0, -1}, right_{1, 0, 0}, up_{0, 1, 0};
    float tan_half_ = 1, aspect_ = 1;
    double distance_ = 1;
    int width_ = 1, height_ = 1;
};

}  // namespace hbrdf::render
