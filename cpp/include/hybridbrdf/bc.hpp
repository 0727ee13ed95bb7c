// libhybridbrdf — decoders of the block-compressed texture formats BC1, BC4, BC5 and BC7
// (docs/TEXTURES.md), written from the Khronos Data Format Specification (sections "S3TC" and
// "RGTC", "BPTC") and Direct3D's documentation of the BC formats. A block is 4 x 4 texels;
// the decoders give 8-bit stored values, the integer arithmetic of the reference decoders
// (texture2ddecoder, the encoders' own models): BC1's thirds and BC4's sevenths and fifths are
// floor((a e0 + b e1) / n), BC7's interpolation is ((64 - w) e0 + w e1 + 32) >> 6. A GPU may
// return BC1 and BC4/BC5's interpolated values at a higher precision (a float, not a byte):
// those differ from these by less than one step of 1/255.
#pragma once

#include <cstddef>
#include <cstdint>

namespace hbrdf::bc {

/// The block formats, each 4 x 4 texels a block.
enum class BlockFormat {
    BC1,  ///< 8 bytes: RGB, two RGB565 endpoints and 2-bit indices (the RGB variant: never transparent)
    BC4,  ///< 8 bytes: one channel, two 8-bit endpoints and 3-bit indices
    BC5,  ///< 16 bytes: two BC4 blocks, red then green
    BC7,  ///< 16 bytes: RGBA, eight modes (BPTC)
};

/// Bytes of one block: 8 (BC1, BC4) or 16 (BC5, BC7).
std::size_t block_bytes(BlockFormat format);

/// Channels a decoded texel has: BC1 3 (RGB), BC4 1, BC5 2, BC7 4 (RGBA).
int block_channels(BlockFormat format);

/// One block into 16 texels of block_channels(format) bytes each, row-major from the block's
/// top-left texel. Every 8 or 16 bytes are a valid block; BC7's reserved mode (a first byte of 0)
/// decodes to 0 in every channel, alpha included, as Direct3D specifies.
void decode_block(BlockFormat format, const std::uint8_t* block, std::uint8_t* texels);

/// Bytes of a width x height level's blocks: ceil(width / 4) ceil(height / 4) block_bytes(format).
std::size_t level_bytes(BlockFormat format, std::uint32_t width, std::uint32_t height);

/// A width x height level from its level_bytes(format, width, height) bytes of blocks (rows of
/// blocks from the top) into width x height texels of block_channels(format) bytes, row-major;
/// the texels of edge blocks beyond the level are dropped.
void decode_level(BlockFormat format, const std::uint8_t* blocks, std::uint32_t width, std::uint32_t height,
                  std::uint8_t* texels);

/// The eight values a BC4 block's 3-bit indices select, from its endpoints (e0, e1): e0, e1 and six
/// levels between them when e0 > e1, else four levels between them, 0 and 255 (Khronos Data
/// Format 1.3, "BC4"). The decoder and the encoder share it.
void bc4_palette(int e0, int e1, int palette[8]);

/// One BC4 block of 16 values (row-major from the block's top-left texel) minimising the squared
/// error of its decode_block() under one constraint: a value of 0 or 255 decodes exactly (the
/// search: bc_encode.cpp; docs/TEXTURES.md, "Encoders").
void encode_bc4_block(const std::uint8_t values[16], std::uint8_t block[8]);

/// A width x height level of `channels` bytes a texel (row-major) as BC4 (channel 0) or BC5
/// (channels 0 and 1) blocks, level_bytes(format, width, height) of them; edge blocks repeat the
/// level's last row and column. std::invalid_argument for another format or too few channels.
void encode_level(BlockFormat format, const std::uint8_t* texels, std::uint32_t width, std::uint32_t height,
                  int channels, std::uint8_t* blocks);

}  // namespace hbrdf::bc
