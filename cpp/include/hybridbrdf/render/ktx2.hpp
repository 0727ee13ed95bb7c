// hybridbrdf renderer — reading KTX 2.0 textures (Khronos KTX File Format Specification 2.0;
// docs/TEXTURES.md): one 2D texture and its mip chain, without supercompression, in the formats
// hybridbrdf.svbrdf.ktx2 writes (8-bit RGBA, half and single float RGBA, BC1 RGB, BC4, BC5, BC7).
// The checks and their words are hybridbrdf.svbrdf.ktx2.read_ktx2's (tests/python/test_ktx2.py
// runs the same damaged files through both).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace hbrdf::render {

/// Most texels on a side of a KTX2 texture's level 0 (Vulkan's usual maxImageDimension2D).
inline constexpr std::uint32_t kMaxKtx2Side = 16384;

/// One level's stored values, row-major from the top-left texel, `channels` values a texel:
/// bytes (the 8-bit and BC formats) or floats (the float formats), the other vector empty.
struct Ktx2Level {
    std::uint32_t width = 0, height = 0;
    std::vector<std::uint8_t> bytes;
    std::vector<float> floats;
    /// The level's bytes as the file stores them (blocks, halves, floats): what a GPU upload copies.
    std::vector<std::uint8_t> stored;
};

struct Ktx2Texture {
    std::uint32_t vk_format = 0;
    std::string format_name;  ///< "BC7_SRGB_BLOCK", ... (the VkFormat name without VK_FORMAT_)
    std::uint32_t width = 0, height = 0;
    int channels = 0;         ///< 4 (RGBA formats, BC7), 3 (BC1), 2 (BC5), 1 (BC4)
    bool srgb = false;        ///< colour channels sRGB-encoded (the *_SRGB formats)
    bool is_float = false;    ///< the levels hold floats
    std::vector<Ktx2Level> levels;  ///< level 0 first
};

/// Reads and checks `path`: every size in the header, the level index and the data format
/// descriptor is checked against the file's length and the format before anything is allocated.
/// Throws FileError("<path>: <problem>") (render/image.hpp).
Ktx2Texture read_ktx2(const std::string& path);

}  // namespace hbrdf::render
