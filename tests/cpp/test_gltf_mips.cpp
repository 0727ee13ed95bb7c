// Tests of a glTF texture's mip chain and its trilinear lookup (gltf_material.hpp; docs/GLTF.md,
// "Samplers"). References are computed by hand from the rule: a one-texel checkerboard's level 1
// is uniform linear 0.5 (sRGB: round(255 encode(0.5)) = 188; linear: 127.5 rounded to 128), an odd
// side's texels weigh their overlap with the footprint, and Vulkan 1.3's mip selection (16.6.1).
#include <doctest/doctest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "hybridbrdf/render/gltf_material.hpp"

using namespace hbrdf::render;

namespace {

// A grey image of width x height from one value a texel (row-major, top row first), alpha 255.
GltfImage grey(int width, int height, const std::vector<int>& values) {
    GltfImage im;
    im.width = width, im.height = height;
    for (int v : values) im.rgba.insert(im.rgba.end(), {(unsigned char)v, (unsigned char)v, (unsigned char)v, 255});
    return im;
}

GltfImage checkerboard(int n) {
    std::vector<int> values;
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) values.push_back((x + y) % 2 ? 255 : 0);
    return grey(n, n, values);
}

GltfTexture texture_of(const GltfImage& im, bool srgb, int min_filter) {
    GltfTexture t;
    t.image = std::make_shared<const GltfImage>(im);
    t.srgb = srgb;
    t.min_filter = min_filter;
    t.wrap_s = t.wrap_t = GltfWrap::ClampToEdge;  // no texels from the far side
    if (gltf_mipmapped(min_filter)) t.mips = std::make_shared<const std::vector<GltfImage>>(gltf_mip_chain(im, srgb));
    return t;
}

}  // namespace

TEST_CASE("glTF mips: a one-texel checkerboard's level 1 is uniform linear 0.5, averaged after the sRGB decode") {
    const auto srgb = gltf_mip_chain(checkerboard(8), true), linear = gltf_mip_chain(checkerboard(8), false);
    REQUIRE(srgb.size() == 3);  // 4 x 4, 2 x 2, 1 x 1
    CHECK(srgb[0].width == 4);
    CHECK(srgb[2].width == 1);
    // 255 * (1.055 * 0.5^(1/2.4) - 0.055) = 187.52: 188 (averaging the encoded bytes would give 128)
    for (const GltfImage& level : srgb)
        for (std::size_t i = 0; i < level.rgba.size(); ++i) CHECK(int(level.rgba[i]) == (i % 4 == 3 ? 255 : 188));
    for (const GltfImage& level : linear)
        for (std::size_t i = 0; i < level.rgba.size(); ++i) CHECK(int(level.rgba[i]) == (i % 4 == 3 ? 255 : 128));
    const GltfTexture t = texture_of(checkerboard(8), true, 9987);
    const double half = std::pow((188 / 255.0 + 0.055) / 1.055, 2.4);  // 0.50289
    for (double u : {0.03, 0.31, 0.77})
        CHECK(t.sample(u, 0.4, 1.0)[0] == doctest::Approx(half).epsilon(1e-12));
}

TEST_CASE("glTF mips: odd sides weigh each texel by its overlap; the sizes are Vulkan's") {
    // 5 x 3: level 1 is 2 x 1 (5 / 2, 3 / 2), level 2 1 x 1.
    const std::vector<int> row{0, 50, 100, 150, 250};
    std::vector<int> values;
    for (int y = 0; y < 3; ++y) values.insert(values.end(), row.begin(), row.end());
    const auto chain = gltf_mip_chain(grey(5, 3, values), false);
    REQUIRE(chain.size() == 2);
    CHECK((chain[0].width == 2 && chain[0].height == 1 && chain[1].width == 1 && chain[1].height == 1));
    // destination texel 0 covers [0, 2.5): texels 0, 1 whole and half of 2, over 2.5
    CHECK(int(chain[0].rgba[0]) == int(std::lround((0 + 50 + 0.5 * 100) / 2.5)));          // 40
    CHECK(int(chain[0].rgba[4]) == int(std::lround((0.5 * 100 + 150 + 250) / 2.5)));       // 180
    CHECK(int(chain[1].rgba[0]) == int(std::lround((0 + 50 + 100 + 150 + 250) / 5.0)));    // 110, from the unrounded level 1
    // a side of 1 stays 1 while the other halves: 1 x 4 -> 1 x 2 -> 1 x 1
    const auto tall = gltf_mip_chain(grey(1, 4, {0, 100, 200, 250}), false);
    REQUIRE(tall.size() == 2);
    CHECK((tall[0].width == 1 && tall[0].height == 2 && int(tall[0].rgba[4]) == 225));
}

TEST_CASE("glTF mips: the level of detail picks levels as Vulkan's sampler does") {
    // 4 x 4 of 0 | 255 halves (left | right): level 1 keeps them (2 x 2), level 2 is their mean.
    std::vector<int> values;
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x) values.push_back(x < 2 ? 0 : 255);
    const GltfImage im = grey(4, 4, values);
    const double u = 0.1, v = 0.5;  // inside the left half at levels 0 and 1
    const double level2 = 128 / 255.0;
    auto at = [&](int min_filter, double lod) { return texture_of(im, false, min_filter).sample(u, v, lod)[0]; };
    // LINEAR_MIPMAP_LINEAR: between levels 1 (0) and 2 at lod 1.25; clamped to the last level above
    CHECK(at(9987, 1.25) == doctest::Approx(0.25 * level2).epsilon(1e-12));
    CHECK(at(9987, 7.0) == doctest::Approx(level2).epsilon(1e-12));
    // NEAREST_MIPMAP_*: d = ceil(lambda + 1/2) - 1, ties down
    CHECK(at(9984, 1.5) == 0.0);
    CHECK(at(9985, 1.51) == doctest::Approx(level2).epsilon(1e-12));
    // magnified (lod <= 0 or the point footprint) and a minFilter without mips: level 0
    CHECK(at(9987, -2.0) == 0.0);
    CHECK(at(9987, -INFINITY) == 0.0);
    CHECK(at(9729, 5.0) == 0.0);
    CHECK(at(9728, 5.0) == 0.0);
    CHECK(texture_of(im, false, 9729).sample(0.55, v, 5.0)[0] == doctest::Approx(0.7).epsilon(1e-12));  // bilinear level 0
    CHECK(texture_of(im, false, 9728).sample(0.55, v, 5.0)[0] == 1.0);                                        // nearest
    // the footprint's level of detail: footprint + 0.5 log2(W H)
    CHECK(texture_of(im, false, 9987).lod(-1.0f) == doctest::Approx(1.0));
}
