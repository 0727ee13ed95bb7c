// BC1, BC4 and BC7 blocks built bit by bit from the format specification (Khronos Data Format
// Specification, S3TC / RGTC / BPTC) and their texels worked out by hand: an independent check of
// hybridbrdf/bc.hpp's bit layout and arithmetic (tests/python/test_ktx2.py compares every format
// with texture2ddecoder over random blocks; these also run under ASan/UBSan).
#include <doctest/doctest.h>

#include <array>
#include <cstdint>
#include <vector>

#include "hybridbrdf/bc.hpp"

using hbrdf::bc::BlockFormat;

namespace {

// Writes fields from bit 0 up, least significant bit first (BPTC's packing).
struct BitWriter {
    std::array<std::uint8_t, 16> bytes{};
    int pos = 0;
    void put(std::uint32_t value, int bits) {
        for (int i = 0; i < bits; ++i, ++pos)
            if ((value >> i) & 1u) bytes[std::size_t(pos >> 3)] |= std::uint8_t(1u << (pos & 7));
    }
};

std::vector<std::uint8_t> decode(BlockFormat f, const std::uint8_t* block) {
    std::vector<std::uint8_t> out(16 * std::size_t(hbrdf::bc::block_channels(f)));
    hbrdf::bc::decode_block(f, block, out.data());
    return out;
}

}  // namespace

TEST_CASE("BC1: pure red and blue endpoints, four colours and three plus black") {
    // c0 = 0xF800 (255, 0, 0), c1 = 0x0021 (g 1 -> 4, b 1 -> 8 widened); indices 0, 1, 2, 3 in
    // every row (byte 0b11100100); the thirds are floored: (0 + 8) / 3 = 2, (0 + 16) / 3 = 5.
    const std::uint8_t four[8] = {0x00, 0xF8, 0x21, 0x00, 0xE4, 0xE4, 0xE4, 0xE4};
    auto t = decode(BlockFormat::BC1, four);
    const std::vector<std::uint8_t> row = {255, 0, 0, 0, 4, 8, 170, 1, 2, 85, 2, 5};
    for (int r = 0; r < 4; ++r) CHECK(std::vector<std::uint8_t>(t.begin() + 12 * r, t.begin() + 12 * r + 12) == row);
    const std::uint8_t three[8] = {0x1F, 0x00, 0x00, 0xF8, 0xE4, 0xE4, 0xE4, 0xE4};  // c0 <= c1
    t = decode(BlockFormat::BC1, three);
    CHECK(std::vector<std::uint8_t>(t.begin(), t.begin() + 12) ==
          std::vector<std::uint8_t>{0, 0, 255, 255, 0, 0, 127, 0, 127, 0, 0, 0});
}

TEST_CASE("BC4: eight-value and six-value palettes") {
    // r0 = 200 > r1 = 100; texels 0..3 take indices 0, 1, 2, 7 (3 bits each from bit 16).
    const std::uint32_t idx = 1u << 3 | 2u << 6 | 7u << 9;
    const std::uint8_t eight[8] = {200, 100, std::uint8_t(idx), std::uint8_t(idx >> 8), 0, 0, 0, 0};
    auto t = decode(BlockFormat::BC4, eight);
    CHECK(std::vector<std::uint8_t>(t.begin(), t.begin() + 5) == std::vector<std::uint8_t>{200, 100, 185, 114, 200});
    // r0 = 50 <= r1 = 200: indices 6 and 7 are 0 and 255, index 2 is (4 r0 + r1) / 5 = 80.
    const std::uint32_t six = 6u | 7u << 3 | 2u << 6;
    const std::uint8_t block[8] = {50, 200, std::uint8_t(six), std::uint8_t(six >> 8), 0, 0, 0, 0};
    t = decode(BlockFormat::BC4, block);
    CHECK(std::vector<std::uint8_t>(t.begin(), t.begin() + 4) == std::vector<std::uint8_t>{0, 255, 80, 50});
}

TEST_CASE("BC7 mode 6: 7-bit endpoints with p-bits, 4-bit indices, the anchor's 3") {
    BitWriter w;
    w.put(1u << 6, 7);                                    // mode 6
    for (int c = 0; c < 4; ++c) w.put(0, 7), w.put(127, 7);  // R, G, B, A: endpoint 0 = 0, endpoint 1 = 127
    w.put(0, 1), w.put(1, 1);                             // p-bits: e0 = 0 << 1 | 0 = 0, e1 = 127 << 1 | 1 = 255
    w.put(0, 3);                                          // texel 0 (anchor): index 0
    w.put(15, 4), w.put(8, 4);                            // texel 1: 15 (255), texel 2: 8 (weight 34)
    for (int t = 3; t < 16; ++t) w.put(4, 4);             // weight 17: (17 * 255 + 32) >> 6 = 68
    REQUIRE(w.pos == 128);
    const auto t = decode(BlockFormat::BC7, w.bytes.data());
    CHECK(std::vector<std::uint8_t>(t.begin(), t.begin() + 16) ==
          std::vector<std::uint8_t>{0, 0, 0, 0, 255, 255, 255, 255, 135, 135, 135, 135, 68, 68, 68, 68});
}

TEST_CASE("BC7 reserved mode (first byte 0) decodes to zero, alpha included") {
    std::uint8_t block[16];
    for (int i = 0; i < 16; ++i) block[i] = std::uint8_t(i == 0 ? 0 : 0xA5);
    for (std::uint8_t v : decode(BlockFormat::BC7, block)) CHECK(v == 0);
}

TEST_CASE("decode_level cuts the edge blocks of a 5 x 3 level") {
    const std::uint8_t blocks[16] = {0x00, 0xF8, 0x1F, 0x00, 0xE4, 0xE4, 0xE4, 0xE4,   // first block as above
                                     0x1F, 0x00, 0x00, 0xF8, 0x00, 0x00, 0x00, 0x00};  // second: all c0 (blue)
    CHECK(hbrdf::bc::level_bytes(BlockFormat::BC1, 5, 3) == 16);
    std::vector<std::uint8_t> texels(5 * 3 * 3);
    hbrdf::bc::decode_level(BlockFormat::BC1, blocks, 5, 3, texels.data());
    for (int y = 0; y < 3; ++y) {
        CHECK(texels[std::size_t(3 * (5 * y + 2))] == 170);     // (2, y): the first block's index 2
        CHECK(texels[std::size_t(3 * (5 * y + 4)) + 2] == 255); // (4, y): the second block's blue
    }
}
