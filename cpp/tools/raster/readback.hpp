// hbrdf_raster — the frame's colour target back on the host, as the renderer's RGB image.
#pragma once

#include "device.hpp"
#include "hybridbrdf/render/image.hpp"

namespace hbrdf::raster {

/// Copies `color` (RGBA32F, in TRANSFER_SRC_OPTIMAL) into host memory and drops alpha: the
/// linear RGB image, row 0 at the top (Vulkan's framebuffer y points down, as the tracer's).
render::Image read_color(const Device& device, VkImage color, uint32_t width, uint32_t height);

}  // namespace hbrdf::raster
