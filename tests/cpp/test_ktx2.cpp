// libhybridbrdf's KTX2 reader (render/ktx2.hpp; docs/TEXTURES.md) on files built byte by byte here
// from the KTX 2.0 specification's layout: a 2 x 1 RGBA8 texture and its 1 x 1 level read back,
// and damaged copies refused in one line naming the file, before anything large is allocated
// (these run under ASan/UBSan too; tests/python/test_ktx2.py compares it with the Python reader).
#include <doctest/doctest.h>

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "hybridbrdf/render/image.hpp"
#include "hybridbrdf/render/ktx2.hpp"

using namespace hbrdf::render;

namespace {

void put32(std::vector<std::uint8_t>& b, std::size_t at, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) b[at + std::size_t(i)] = std::uint8_t(v >> (8 * i));
}
void put64(std::vector<std::uint8_t>& b, std::size_t at, std::uint64_t v) {
    for (int i = 0; i < 8; ++i) b[at + std::size_t(i)] = std::uint8_t(v >> (8 * i));
}

// R8G8B8A8_UNORM, 2 x 1, two levels; no key/value data. Layout: header 0-79, level index 80-127,
// DFD 128-219 (4 + 24 + 4 samples x 16), level 1 at 220 (4 bytes), level 0 at 224 (8 bytes).
std::vector<std::uint8_t> tiny_file() {
    std::vector<std::uint8_t> b(232, 0);
    const std::uint8_t id[12] = {0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A};
    for (int i = 0; i < 12; ++i) b[std::size_t(i)] = id[i];
    const std::uint32_t header[9] = {37, 1, 2, 1, 0, 0, 1, 2, 0};  // vkFormat .. supercompressionScheme
    for (int i = 0; i < 9; ++i) put32(b, 12 + 4 * std::size_t(i), header[i]);
    put32(b, 48, 128), put32(b, 52, 92);                              // DFD; kvd and sgd empty
    put64(b, 80, 224), put64(b, 88, 8), put64(b, 96, 8);              // level 0
    put64(b, 104, 220), put64(b, 112, 4), put64(b, 120, 4);           // level 1
    const std::uint32_t dfd[23] = {92, 0, 2u | 88u << 16, 1u | 1u << 8 | 1u << 16, 0, 4, 0,
                                   0u | 7u << 16 | 0u << 24, 0, 0, 255, 8u | 7u << 16 | 1u << 24, 0, 0, 255,
                                   16u | 7u << 16 | 2u << 24, 0, 0, 255, 24u | 7u << 16 | 15u << 24, 0, 0, 255};
    for (int i = 0; i < 23; ++i) put32(b, 128 + 4 * std::size_t(i), dfd[i]);
    const std::uint8_t level1[4] = {30, 40, 50, 60}, level0[8] = {10, 20, 30, 40, 50, 60, 70, 80};
    for (int i = 0; i < 4; ++i) b[220 + std::size_t(i)] = level1[i];
    for (int i = 0; i < 8; ++i) b[224 + std::size_t(i)] = level0[i];
    return b;
}

std::string write(const std::vector<std::uint8_t>& bytes, std::size_t length) {
    const std::string path = "hbrdf_test_ktx2.ktx2";
    std::FILE* f = std::fopen(path.c_str(), "wb");
    std::fwrite(bytes.data(), 1, length, f);
    std::fclose(f);
    return path;
}

std::string error_of(const std::vector<std::uint8_t>& bytes, std::size_t length) {
    const std::string path = write(bytes, length);
    try {
        read_ktx2(path);
    } catch (const FileError& e) {
        return e.what();
    }
    return "no error";
}

}  // namespace

TEST_CASE("KTX2: a 2 x 1 RGBA8 texture and its 1 x 1 level, built byte by byte, read back") {
    const std::vector<std::uint8_t> b = tiny_file();
    const Ktx2Texture t = read_ktx2(write(b, b.size()));
    CHECK(t.vk_format == 37);
    CHECK(t.format_name == "R8G8B8A8_UNORM");
    CHECK((t.width == 2 && t.height == 1 && t.channels == 4 && !t.srgb && !t.is_float));
    REQUIRE(t.levels.size() == 2);
    CHECK(t.levels[0].bytes == std::vector<std::uint8_t>{10, 20, 30, 40, 50, 60, 70, 80});
    CHECK((t.levels[1].width == 1 && t.levels[1].height == 1));
    CHECK(t.levels[1].bytes == std::vector<std::uint8_t>{30, 40, 50, 60});
}

TEST_CASE("KTX2: damaged copies refused in one line naming the file") {
    const std::vector<std::uint8_t> good = tiny_file();
    const std::string p = "hbrdf_test_ktx2.ktx2: ";
    CHECK(error_of(good, 40) == p + "truncated: 40 bytes, a KTX2 header needs 80");
    CHECK(error_of(good, 230) == p + "level 0: byteOffset 224 + byteLength 8 lies outside the file's 230 bytes");
    std::vector<std::uint8_t> b = good;
    put32(b, 44, 2);
    CHECK(error_of(b, b.size()) == p + "supercompressionScheme 2 is not supported (only 0, none)");
    b = good;
    put64(b, 88, std::uint64_t(1) << 40), put64(b, 96, std::uint64_t(1) << 40);  // a forged 1 TiB level
    CHECK(error_of(b, b.size()) == p + "level 0: byteLength 1099511627776, a 2 x 1 R8G8B8A8_UNORM level is 8 bytes");
    b = good;
    put32(b, 20, 16384), put32(b, 24, 16384), put64(b, 88, std::uint64_t(1) << 30), put64(b, 96, std::uint64_t(1) << 30);
    CHECK(error_of(b, b.size()) ==
          p + "level 0: byteOffset 224 + byteLength 1073741824 lies outside the file's 232 bytes");
    b = good;
    b[128 + 4 + 10] = 2;  // transferFunction sRGB on a UNORM format
    CHECK(error_of(b, b.size()) == p + "data format descriptor: transferFunction 2, R8G8B8A8_UNORM needs 1 (linear)");
    b = good;
    put64(b, 104, 224);  // level 1 over level 0: stored after it
    CHECK(error_of(b, b.size()) == p + "level 1: stored after level 0 (KTX2 stores the smallest level first)");
    std::remove("hbrdf_test_ktx2.ktx2");
}
