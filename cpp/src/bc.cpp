// libhybridbrdf — BC1, BC4, BC5 and BC7 block decoders (hybridbrdf/bc.hpp; docs/TEXTURES.md).
// Bit layouts and tables from the Khronos Data Format Specification (S3TC, RGTC, BPTC) and
// Direct3D 11's BC7 format documentation.
#include "hybridbrdf/bc.hpp"

#include <algorithm>
#include <cstring>

namespace hbrdf::bc {

void bc4_palette(int e0, int e1, int palette[8]) {
    palette[0] = e0;
    palette[1] = e1;
    if (e0 > e1) {
        for (int i = 1; i < 7; ++i) palette[i + 1] = ((7 - i) * e0 + i * e1) / 7;
    } else {
        for (int i = 1; i < 5; ++i) palette[i + 1] = ((5 - i) * e0 + i * e1) / 5;
        palette[6] = 0;
        palette[7] = 255;
    }
}

namespace {

// Little-endian bit reader over one 128-bit (or 64-bit) block: BC7 packs its fields from bit 0.
class BitReader {
public:
    explicit BitReader(const std::uint8_t* block) : block_(block) {}
    std::uint32_t read(int bits) {
        std::uint32_t value = 0;
        for (int i = 0; i < bits; ++i, ++pos_)
            value |= std::uint32_t((block_[pos_ >> 3] >> (pos_ & 7)) & 1u) << i;
        return value;
    }
    int position() const { return pos_; }

private:
    const std::uint8_t* block_;
    int pos_ = 0;
};

// ---- BC1 and BC4 (S3TC, RGTC) --------------------------------------------------------------

// A channel of 4 to 8 bits widened to 8 by replicating its high bits into the low ones.
inline int widen(int value, int bits) { return (value << (8 - bits)) | (value >> (2 * bits - 8)); }

void decode_bc1(const std::uint8_t* b, std::uint8_t* out) {
    const int c0 = b[0] | (b[1] << 8), c1 = b[2] | (b[3] << 8);
    int palette[4][3];
    const int e[2][3] = {{widen(c0 >> 11, 5), widen((c0 >> 5) & 63, 6), widen(c0 & 31, 5)},
                         {widen(c1 >> 11, 5), widen((c1 >> 5) & 63, 6), widen(c1 & 31, 5)}};
    for (int c = 0; c < 3; ++c) {
        palette[0][c] = e[0][c];
        palette[1][c] = e[1][c];
        if (c0 > c1) {  // four colours: the endpoints and the two thirds between them
            palette[2][c] = (2 * e[0][c] + e[1][c]) / 3;
            palette[3][c] = (e[0][c] + 2 * e[1][c]) / 3;
        } else {  // three colours and black (transparent in BC1 RGBA; these are the RGB formats)
            palette[2][c] = (e[0][c] + e[1][c]) / 2;
            palette[3][c] = 0;
        }
    }
    const std::uint32_t indices = std::uint32_t(b[4]) | std::uint32_t(b[5]) << 8 | std::uint32_t(b[6]) << 16 |
                                  std::uint32_t(b[7]) << 24;
    for (int t = 0; t < 16; ++t) {
        const int* colour = palette[(indices >> (2 * t)) & 3u];
        for (int c = 0; c < 3; ++c) out[3 * t + c] = std::uint8_t(colour[c]);
    }
}

// One BC4 block into 16 values `stride` bytes apart.
void decode_bc4(const std::uint8_t* b, std::uint8_t* out, int stride) {
    int palette[8];
    bc4_palette(b[0], b[1], palette);
    std::uint64_t indices = 0;
    for (int i = 0; i < 6; ++i) indices |= std::uint64_t(b[2 + i]) << (8 * i);
    for (int t = 0; t < 16; ++t) out[t * stride] = std::uint8_t(palette[(indices >> (3 * t)) & 7u]);
}

// ---- BC7 (BPTC) ----------------------------------------------------------------------------

struct Bc7Mode {
    int subsets, partition_bits, rotation_bits, index_selection_bits, colour_bits, alpha_bits;
    int endpoint_pbits, shared_pbits, index_bits, index_bits2;
};

// The eight modes (Khronos Data Format Specification, BPTC's mode table).
constexpr Bc7Mode kBc7Modes[8] = {
    {3, 4, 0, 0, 4, 0, 1, 0, 3, 0}, {2, 6, 0, 0, 6, 0, 0, 1, 3, 0}, {3, 6, 0, 0, 5, 0, 0, 0, 2, 0},
    {2, 6, 0, 0, 7, 0, 1, 0, 2, 0}, {1, 0, 2, 1, 5, 6, 0, 0, 2, 3}, {1, 0, 2, 0, 7, 8, 0, 0, 2, 2},
    {1, 0, 0, 0, 7, 7, 1, 0, 4, 0}, {2, 6, 0, 0, 5, 5, 1, 0, 2, 0},
};

// The 64 two-subset partitions: bit t is texel t's subset.
constexpr std::uint16_t kPartitions2[64] = {
    0xcccc, 0x8888, 0xeeee, 0xecc8, 0xc880, 0xfeec, 0xfec8, 0xec80, 0xc800, 0xffec, 0xfe80, 0xe800, 0xffe8,
    0xff00, 0xfff0, 0xf000, 0xf710, 0x008e, 0x7100, 0x08ce, 0x008c, 0x7310, 0x3100, 0x8cce, 0x088c, 0x3110,
    0x6666, 0x366c, 0x17e8, 0x0ff0, 0x718e, 0x399c, 0xaaaa, 0xf0f0, 0x5a5a, 0x33cc, 0x3c3c, 0x55aa, 0x9696,
    0xa55a, 0x73ce, 0x13c8, 0x324c, 0x3bdc, 0x6996, 0xc33c, 0x9966, 0x0660, 0x0272, 0x04e4, 0x4e40, 0x2720,
    0xc936, 0x936c, 0x39c6, 0x639c, 0x9336, 0x9cc6, 0x817e, 0xe718, 0xccf0, 0x0fcc, 0x7744, 0xee22,
};

// The 64 three-subset partitions: bits 2t, 2t + 1 are texel t's subset.
constexpr std::uint32_t kPartitions3[64] = {
    0xaa685050, 0x6a5a5040, 0x5a5a4200, 0x5450a0a8, 0xa5a50000, 0xa0a05050, 0x5555a0a0, 0x5a5a5050,
    0xaa550000, 0xaa555500, 0xaaaa5500, 0x90909090, 0x94949494, 0xa4a4a4a4, 0xa9a59450, 0x2a0a4250,
    0xa5945040, 0x0a425054, 0xa5a5a500, 0x55a0a0a0, 0xa8a85454, 0x6a6a4040, 0xa4a45000, 0x1a1a0500,
    0x0050a4a4, 0xaaa59090, 0x14696914, 0x69691400, 0xa08585a0, 0xaa821414, 0x50a4a450, 0x6a5a0200,
    0xa9a58000, 0x5090a0a8, 0xa8a09050, 0x24242424, 0x00aa5500, 0x24924924, 0x24499224, 0x50a50a50,
    0x500aa550, 0xaaaa4444, 0x66660000, 0xa5a0a5a0, 0x50a050a0, 0x69286928, 0x44aaaa44, 0x66666600,
    0xaa444444, 0x54a854a8, 0x95809580, 0x96969600, 0xa85454a8, 0x80959580, 0xaa141414, 0x96960000,
    0xaaaa1414, 0xa05050a0, 0xa0a5a5a0, 0x96000000, 0x40804080, 0xa9a8a9a8, 0xaaaaaa44, 0x2a4a5254,
};

// Anchor texels (whose index has one bit less): subset 0's is texel 0; these are subset 1's of the
// two-subset partitions, and subsets 1 and 2's of the three-subset ones.
constexpr std::uint8_t kAnchor2[64] = {
    15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 2,  8,  2,  2,  8,  8,  15, 2,  8,  2,  2,
    8,  8,  2,  2,  15, 15, 6,  8,  2,  8,  15, 15, 2,  8,  2,  2,  2,  15, 15, 6,  6,  2,  6,  8,  15, 15, 2,  2,
    15, 15, 15, 15, 15, 2,  2,  15,
};
constexpr std::uint8_t kAnchor3b[64] = {
    3,  3,  15, 15, 8,  3,  15, 15, 8,  8,  6,  6,  6,  5,  3,  3,  3,  3,  8,  15, 3,  3,  6,  10, 5,  8,  8,  6,
    8,  5,  15, 15, 8,  15, 3,  5,  6,  10, 8,  15, 15, 3,  15, 5,  15, 15, 15, 15, 3,  15, 5,  5,  5,  8,  5,  10,
    5,  10, 8,  13, 15, 12, 3,  3,
};
constexpr std::uint8_t kAnchor3c[64] = {
    15, 8,  8,  3,  15, 15, 3,  8,  15, 15, 15, 15, 15, 15, 15, 8,  15, 8,  15, 3,  15, 8,  15, 8,  3,  15, 6,  10,
    15, 15, 10, 8,  15, 3,  15, 10, 10, 8,  9,  10, 6,  15, 8,  15, 3,  6,  6,  8,  15, 3,  15, 15, 15, 15, 15, 15,
    15, 15, 15, 15, 3,  15, 15, 8,
};

// Interpolation weights (out of 64) for 2-, 3- and 4-bit indices.
constexpr int kWeights2[4] = {0, 21, 43, 64};
constexpr int kWeights3[8] = {0, 9, 18, 27, 37, 46, 55, 64};
constexpr int kWeights4[16] = {0, 4, 9, 13, 17, 21, 26, 30, 34, 38, 43, 47, 51, 55, 60, 64};

inline int interpolate(int e0, int e1, int index, int bits) {
    const int w = bits == 2 ? kWeights2[index] : bits == 3 ? kWeights3[index] : kWeights4[index];
    return ((64 - w) * e0 + w * e1 + 32) >> 6;
}

inline int subset_of(const Bc7Mode& m, int partition, int texel) {
    if (m.subsets == 2) return (kPartitions2[partition] >> texel) & 1;
    if (m.subsets == 3) return int((kPartitions3[partition] >> (2 * texel)) & 3u);
    return 0;
}

inline bool is_anchor(const Bc7Mode& m, int partition, int texel) {
    if (texel == 0) return true;
    if (m.subsets == 2) return texel == kAnchor2[partition];
    if (m.subsets == 3) return texel == kAnchor3b[partition] || texel == kAnchor3c[partition];
    return false;
}

void decode_bc7(const std::uint8_t* b, std::uint8_t* out) {
    int mode = 0;
    while (mode < 8 && !((b[0] >> mode) & 1)) ++mode;
    if (mode == 8) {  // reserved: Direct3D decodes it to 0 in every channel
        std::memset(out, 0, 64);
        return;
    }
    const Bc7Mode& m = kBc7Modes[mode];
    BitReader bits(b);
    bits.read(mode + 1);
    const int partition = int(bits.read(m.partition_bits));
    const int rotation = int(bits.read(m.rotation_bits));
    const int index_selection = int(bits.read(m.index_selection_bits));
    const int endpoints = 2 * m.subsets;
    int e[6][4] = {};
    for (int c = 0; c < 3; ++c)
        for (int i = 0; i < endpoints; ++i) e[i][c] = int(bits.read(m.colour_bits));
    for (int i = 0; i < endpoints; ++i) e[i][3] = m.alpha_bits ? int(bits.read(m.alpha_bits)) : 255;
    int pbit[6] = {};
    for (int i = 0; i < endpoints && m.endpoint_pbits; ++i) pbit[i] = int(bits.read(1));
    for (int s = 0; s < m.subsets && m.shared_pbits; ++s) pbit[2 * s] = pbit[2 * s + 1] = int(bits.read(1));
    const bool has_pbits = m.endpoint_pbits || m.shared_pbits;
    for (int i = 0; i < endpoints; ++i)
        for (int c = 0; c < 4; ++c) {
            const int channel_bits = c < 3 ? m.colour_bits : m.alpha_bits;
            if (channel_bits == 0) continue;  // alpha of an opaque mode stays 255
            const int value = has_pbits ? (e[i][c] << 1) | pbit[i] : e[i][c];
            e[i][c] = widen(value, channel_bits + (has_pbits ? 1 : 0));
        }
    int index1[16], index2[16] = {};
    for (int t = 0; t < 16; ++t) index1[t] = int(bits.read(m.index_bits - (is_anchor(m, partition, t) ? 1 : 0)));
    for (int t = 0; t < 16 && m.index_bits2; ++t) index2[t] = int(bits.read(m.index_bits2 - (t == 0 ? 1 : 0)));
    for (int t = 0; t < 16; ++t) {
        const int s = subset_of(m, partition, t);
        const int* e0 = e[2 * s];
        const int* e1 = e[2 * s + 1];
        int colour_index = index1[t], colour_bits = m.index_bits, alpha_index = index1[t], alpha_bits = m.index_bits;
        if (m.index_bits2) {  // modes 4 and 5: colour and alpha have index sets of their own
            alpha_index = index2[t];
            alpha_bits = m.index_bits2;
            if (index_selection) {
                std::swap(colour_index, alpha_index);
                std::swap(colour_bits, alpha_bits);
            }
        }
        int texel[4];
        for (int c = 0; c < 3; ++c) texel[c] = interpolate(e0[c], e1[c], colour_index, colour_bits);
        texel[3] = interpolate(e0[3], e1[3], alpha_index, alpha_bits);
        if (rotation) std::swap(texel[3], texel[rotation - 1]);  // 1: alpha <-> red, 2: green, 3: blue
        for (int c = 0; c < 4; ++c) out[4 * t + c] = std::uint8_t(texel[c]);
    }
}

}  // namespace

std::size_t block_bytes(BlockFormat format) {
    return format == BlockFormat::BC1 || format == BlockFormat::BC4 ? 8 : 16;
}

int block_channels(BlockFormat format) {
    switch (format) {
    case BlockFormat::BC1: return 3;
    case BlockFormat::BC4: return 1;
    case BlockFormat::BC5: return 2;
    case BlockFormat::BC7: return 4;
    }
    return 0;
}

void decode_block(BlockFormat format, const std::uint8_t* block, std::uint8_t* texels) {
    switch (format) {
    case BlockFormat::BC1: decode_bc1(block, texels); break;
    case BlockFormat::BC4: decode_bc4(block, texels, 1); break;
    case BlockFormat::BC5:
        decode_bc4(block, texels, 2);
        decode_bc4(block + 8, texels + 1, 2);
        break;
    case BlockFormat::BC7: decode_bc7(block, texels); break;
    }
}

std::size_t level_bytes(BlockFormat format, std::uint32_t width, std::uint32_t height) {
    return std::size_t((width + 3) / 4) * std::size_t((height + 3) / 4) * block_bytes(format);
}

void decode_level(BlockFormat format, const std::uint8_t* blocks, std::uint32_t width, std::uint32_t height,
                  std::uint8_t* texels) {
    const std::size_t channels = std::size_t(block_channels(format)), stride = block_bytes(format);
    const std::uint32_t blocks_x = (width + 3) / 4, blocks_y = (height + 3) / 4;
    std::uint8_t block[16 * 4];
    for (std::uint32_t by = 0; by < blocks_y; ++by)
        for (std::uint32_t bx = 0; bx < blocks_x; ++bx) {
            decode_block(format, blocks + (std::size_t(by) * blocks_x + bx) * stride, block);
            const std::uint32_t rows = std::min<std::uint32_t>(4, height - 4 * by);
            const std::uint32_t cols = std::min<std::uint32_t>(4, width - 4 * bx);
            for (std::uint32_t y = 0; y < rows; ++y)
                std::memcpy(texels + ((std::size_t(4 * by + y) * width) + 4 * bx) * channels,
                            block + std::size_t(4 * y) * channels, cols * channels);
        }
}

}  // namespace hbrdf::bc
