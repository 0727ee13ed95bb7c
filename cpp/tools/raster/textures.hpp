// hbrdf_raster — a textured material's maps as sampled images: each map's stored 8-bit values with
// its mip chain, in the file hbrdf raster writes (python/hybridbrdf/raster/textures.py):
//   "HBTX", then uint32 width, height, levels, srgb (1: an sRGB format, the texture unit decodes),
//   addressing (0 repeat, 1 clamp to edge), then each level's RGBA8 rows, top row first, level 0 first.
// Sampled with linear filtering between texels and mip levels: the engine's trilinear lookup.
#pragma once

#include <string>

#include "device.hpp"

namespace hbrdf::raster {

struct Texture {
    Image image;
    VkSampler sampler = VK_NULL_HANDLE;
};

/// Reads `path`, uploads every level and leaves the image in SHADER_READ_ONLY_OPTIMAL.
/// Throws render::FileError naming the file for a malformed one.
Texture load_texture(const Device& device, const std::string& path);
void destroy(const Device& device, Texture& texture);

}  // namespace hbrdf::raster
