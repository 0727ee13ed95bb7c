// hbrdf_raster — a textured material's maps as sampled images: each map's stored 8-bit values with
// its mip chain, in the file hbrdf raster writes (python/hybridbrdf/raster/textures.py):
//   "HBTX", then uint32 width, height, levels, srgb (1: an sRGB format, the texture unit decodes),
//   addressing (0 repeat, 1 clamp to edge), then each level's RGBA8 rows, top row first, level 0 first.
// Sampled with linear filtering between texels and mip levels: the engine's trilinear lookup.
#pragma once

#include <string>

#include "device.hpp"
#include "hybridbrdf/render/gltf_material.hpp"

namespace hbrdf::raster {

struct Texture {
    Image image;
    VkSampler sampler = VK_NULL_HANDLE;
};

/// Reads `path`, uploads every level and leaves the image in SHADER_READ_ONLY_OPTIMAL.
/// Throws render::FileError naming the file for a malformed one.
Texture load_texture(const Device& device, const std::string& path);
void destroy(const Device& device, Texture& texture);

/// A glTF texture (the tracer's decoded image, render/gltf_material.hpp) as a sampled image: its
/// 8-bit RGBA level 0 (R8G8B8A8_SRGB for a baseColorTexture, the texture unit decodes; UNORM
/// otherwise), a mip chain blitted from it when the glTF minFilter is a mipmap mode, and a sampler
/// of its wrap modes and filters.
Texture upload_gltf_texture(const Device& device, const render::GltfTexture& texture);
/// A 1 x 1 white texture: the slots a frame's shader declares beyond the scene's glTF textures.
Texture blank_texture(const Device& device);

}  // namespace hbrdf::raster
