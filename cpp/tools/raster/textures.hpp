// hbrdf_raster and hbrdf_vk_runner — a textured material's maps as sampled images, each with its
// mip chain, from one of two files:
// - the file hbrdf raster writes (python/hybridbrdf/raster/textures.py): "HBTX", then uint32 width,
//   height, levels, srgb (1: an sRGB format, the texture unit decodes), addressing (0 repeat, 1
//   clamp to edge), then each level's RGBA8 rows, top row first, level 0 first;
// - a KTX 2.0 file (docs/TEXTURES.md; read by render::read_ktx2), uploaded in its own format: the
//   blocks of BC1/BC4/BC5/BC7 as stored (the texture unit decodes them), 8-bit RGBA, half or float
//   RGBA. The device must sample the format with linear filtering (BC: textureCompressionBC);
//   otherwise the file is refused in one line naming it and the device.
// Sampled with linear filtering between texels and (unless told nearest) between mip levels: the
// engine's trilinear lookup.
#pragma once

#include <string>

#include "device.hpp"
#include "hybridbrdf/render/gltf_material.hpp"

namespace hbrdf::raster {

struct Texture {
    Image image;
    VkSampler sampler = VK_NULL_HANDLE;
};

/// How a loaded texture is sampled: a KTX2 file's addressing (an HBTX file's is its header's) and
/// the filter between mip levels.
struct Sampling {
    bool clamp = false;        ///< KTX2: clamp to edge instead of repeat
    bool nearest_mip = false;  ///< the nearest level instead of linear between the two around lod
};

/// Reads `path` (an HBTX file, or a KTX2 file: its name ends in .ktx2), uploads every level and
/// leaves the image in SHADER_READ_ONLY_OPTIMAL. Throws render::FileError naming the file for a
/// malformed one or a format the device cannot sample.
Texture load_texture(const Device& device, const std::string& path, const Sampling& sampling = {});
void destroy(const Device& device, Texture& texture);

/// A glTF texture (the tracer's decoded image, render/gltf_material.hpp) as a sampled image: its
/// 8-bit RGBA level 0 (R8G8B8A8_SRGB for a baseColorTexture, the texture unit decodes; UNORM
/// otherwise), with a mipmap minFilter the levels the tracer reads (render::gltf_mip_chain: the
/// texture's own, or built here when it has none), and a sampler of its wrap modes and filters.
Texture upload_gltf_texture(const Device& device, const render::GltfTexture& texture);
/// A 1 x 1 white texture: the slots a frame's shader declares beyond the scene's glTF textures.
Texture blank_texture(const Device& device);

}  // namespace hbrdf::raster
