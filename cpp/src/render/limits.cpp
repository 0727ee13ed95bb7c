// hybridbrdf renderer — size limits (limits.hpp).
#include "hybridbrdf/render/limits.hpp"

#include <cmath>
#include <cstdio>

namespace hbrdf::render {

std::string format_bytes(double bytes) {
    static const char* const kUnits[] = {"bytes", "kB", "MB", "GB", "TB", "PB", "EB"};
    int u = 0;
    while (bytes >= 999.5 && u < 6) {
        bytes /= 1000.0;
        ++u;
    }
    char buf[32];
    std::snprintf(buf, sizeof buf, bytes < 9.95 && u > 0 ? "%.1f %s" : "%.0f %s", bytes, kUnits[u]);
    return buf;
}

std::string format_number(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", x);
    return buf;
}

std::string check_image_size(std::int64_t width, std::int64_t height, std::uint64_t max_pixels, double bytes_per_pixel,
                             const char* what) {
    if (width < 1 || height < 1) return "";  // the caller's own check names the lower bounds
    // Both factors are below 2^31 for an int, so the product fits 64 bits.
    const std::uint64_t pixels = std::uint64_t(width) * std::uint64_t(height);
    if (pixels <= max_pixels) return "";
    // The 2:1 image of the same size, as an example a reader can relate to.
    const auto example_w = std::uint64_t(std::llround(std::sqrt(2.0 * double(max_pixels))));
    return std::to_string(width) + " x " + std::to_string(height) + " = " + std::to_string(pixels) + " pixels need ~" +
           format_bytes(double(pixels) * bytes_per_pixel) + " " + what + " (limit " + std::to_string(max_pixels) +
           " pixels, e.g. " + std::to_string(example_w) + " x " + std::to_string(example_w / 2) + ")";
}

std::string check_extent(const std::string& what, double extent, double camera_distance) {
    const std::string why = "; float32 places points that far out too coarsely (docs/RENDERING.md, \"Limits\")";
    if (!(extent <= kMaxCoordinate))
        return what + " has a coordinate of magnitude " + format_number(extent) + ", above the limit " +
               format_number(kMaxCoordinate) + " for any coordinate" + why;
    const double bound = kMaxExtentOverCameraDistance * camera_distance;
    if (!(extent <= bound))
        return what + " has a coordinate of magnitude " + format_number(extent) + ", above the limit " +
               format_number(bound) + " = " + format_number(kMaxExtentOverCameraDistance) +
               " x the camera's distance to its look_at point (" + format_number(camera_distance) + ")" + why;
    return "";
}

}  // namespace hbrdf::render
