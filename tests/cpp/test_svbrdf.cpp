// Textured materials in libhybridbrdf (hybridbrdf/svbrdf.hpp; docs/SVBRDF.md) on a hand-built model
// whose network is all zeros, so that f_t = exp(0) + sigmoid(0) f_a = 1 + f_a / 2 in closed form:
// per-texel kd maps, the layers' mixture, filtering, the batched path against the scalar one, and
// the texel sampler's density (these also run under ASan/UBSan).
#include <doctest/doctest.h>

#include <memory>
#include <vector>

#include "test_util.hpp"

using namespace hbrdf;
using namespace hbrdf::test;

namespace {

std::shared_ptr<const HybridModel> zero_model() {
    const std::string path = write_model("svbrdf_zero.safetensors", meta("hybrid", 1, 2, 8, 6), zero_hybrid(2));
    return std::make_shared<const HybridModel>(HybridModel::load(path));
}

Vec3<float> closed_form(const AnalyticParams& p, const Vec3<float>& wi, const Vec3<float>& wo) {
    return Vec3<float>(1.f) + AnalyticBrdf(p).eval(wi, wo) * 0.5f;
}

}  // namespace

TEST_CASE("a texel's kd map and its layers' mixture give the closed form of a zero network") {
    auto model = zero_model();
    const int W = 2, H = 1;
    std::vector<SvbrdfLayer> layers(2);
    layers[0].kd = {0.1f, 0.2f, 0.3f, 0.9f, 0.8f, 0.7f};  // texel (0, 0), texel (1, 0)
    layers[1].kd = {0.5f, 0.5f, 0.5f, 0.0f, 0.0f, 0.0f};
    const std::vector<float> weights = {0.25f, 0.f, 0.f, 1.f, 0.f, 0.f};  // w_1 per texel
    const Svbrdf sv(model, W, H, TexelAddressing::Repeat, layers, weights);
    const Vec3<float> wi = normalize(Vec3<float>(0.3f, -0.2f, 0.9f)), wo = normalize(Vec3<float>(-0.4f, 0.1f, 0.8f));
    AnalyticParams p = model->materials()[0].params;
    for (int texel = 0; texel < 2; ++texel) {
        const Vec2<float> uv((texel + 0.5f) / W, 0.5f);
        const float w1 = weights[3 * texel];
        p.kd = Vec3<float>(layers[0].kd[3 * texel], layers[0].kd[3 * texel + 1], layers[0].kd[3 * texel + 2]);
        Vec3<float> ref = closed_form(p, wi, wo) * (1.f - w1);
        p.kd = Vec3<float>(layers[1].kd[3 * texel], layers[1].kd[3 * texel + 1], layers[1].kd[3 * texel + 2]);
        ref = ref + closed_form(p, wi, wo) * w1;
        const Vec3<float> f = sv.eval(uv, TexelFilter::Nearest, wi, wo);
        for (int c = 0; c < 3; ++c) CHECK(f[c] == doctest::Approx(ref[c]).epsilon(1e-6));
    }
    // Bilinear halfway between the two texel centres: the weights are averaged (w_1 = 0.625), kd too.
    Texel t;
    sv.texel(Vec2<float>(0.5f, 0.5f), TexelFilter::Bilinear, &t);
    CHECK(t.layers[1].weight == doctest::Approx(0.625f));
    CHECK(t.layers[0].weight == doctest::Approx(0.375f));
    CHECK(t.layers[0].params.kd.x == doctest::Approx(0.5f));
    // Repeat addressing: u = 1.25 is u = 0.25.
    CHECK(sv.eval(Vec2<float>(1.25f, 0.5f), TexelFilter::Nearest, wi, wo).x ==
          sv.eval(Vec2<float>(0.25f, 0.5f), TexelFilter::Nearest, wi, wo).x);
}

TEST_CASE("the batched texel path equals the scalar one, and the texel sampler's pdf is its own") {
    auto model = zero_model();
    const int W = 8, H = 8;
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> U(0.f, 1.f);
    std::vector<SvbrdfLayer> layers(3);
    for (auto& l : layers) {
        l.alpha.resize(2 * W * H);
        for (float& a : l.alpha) a = 0.05f + 0.9f * U(rng);
    }
    std::vector<float> weights(3 * W * H, 0.f);
    for (int i = 0; i < W * H; ++i) weights[3 * i] = 0.5f * U(rng), weights[3 * i + 1] = 0.5f * U(rng);
    const Svbrdf sv(model, W, H, TexelAddressing::Clamp, layers, weights);
    const std::size_t n = 1000;
    std::vector<float> uv(2 * n), wi(3 * n), wo(3 * n), f(3 * n);
    for (std::size_t i = 0; i < n; ++i) {
        uv[2 * i] = U(rng), uv[2 * i + 1] = U(rng);
        const Vec3<float> a = normalize(Vec3<float>(U(rng) - 0.5f, U(rng) - 0.5f, U(rng)));
        const Vec3<float> b = normalize(Vec3<float>(U(rng) - 0.5f, U(rng) - 0.5f, U(rng)));
        for (int c = 0; c < 3; ++c) wi[3 * i + c] = a[c], wo[3 * i + c] = b[c];
    }
    sv.eval_batch(n, uv.data(), wi.data(), wo.data(), TexelFilter::Bilinear, f.data());
    for (std::size_t i = 0; i < n; ++i) {
        const Vec2<float> t(uv[2 * i], uv[2 * i + 1]);
        const Vec3<float> a(wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]), b(wo[3 * i], wo[3 * i + 1], wo[3 * i + 2]);
        const Vec3<float> ref = sv.eval(t, TexelFilter::Bilinear, a, b);
        for (int c = 0; c < 3; ++c) CHECK(f[3 * i + c] == doctest::Approx(ref[c]).epsilon(2e-5));
        const BrdfSample s = sv.sample(t, TexelFilter::Bilinear, Strategy::Mis, b, Vec2<float>(U(rng), U(rng)));
        if (s.pdf > 0.f) CHECK(s.pdf == doctest::Approx(sv.pdf(t, TexelFilter::Bilinear, Strategy::Mis, s.wi, b)).epsilon(1e-5));
    }
}

TEST_CASE("a Svbrdf refuses what it cannot evaluate") {
    auto model = zero_model();
    std::vector<SvbrdfLayer> two(2);
    CHECK_THROWS_AS(Svbrdf(model, 2, 2, TexelAddressing::Repeat, two, {}), std::invalid_argument);  // no weights
    std::vector<SvbrdfLayer> bad(1);
    bad[0].material = 3;
    CHECK_THROWS_AS(Svbrdf(model, 2, 2, TexelAddressing::Repeat, bad, {}), std::invalid_argument);
    std::vector<SvbrdfLayer> short_map(1);
    short_map[0].kd = {0.5f};
    CHECK_THROWS_AS(Svbrdf(model, 2, 2, TexelAddressing::Repeat, short_map, {}), std::invalid_argument);
    CHECK_THROWS_AS(Svbrdf(model, 0, 2, TexelAddressing::Repeat, std::vector<SvbrdfLayer>(1), {}), std::invalid_argument);
    std::vector<float> weights(3 * 4, 2.f);
    CHECK_THROWS_AS(Svbrdf(model, 2, 2, TexelAddressing::Repeat, two, weights), std::invalid_argument);
}

TEST_CASE("a normal map shades the texel in its Gram-Schmidt frame, zero below either horizon (normal_map.hpp)") {
    // A normal tilted by 0.5 rad towards +t: the frame is the rotation about b, so the texel is the
    // closed form at the directions rotated back by hand; with an engine's own TBN the same frame.
    const float th = 0.5f, s = std::sin(th), c = std::cos(th);
    const ShadingFrame fr = shading_frame(tangent_normal(s, 0.f));
    CHECK(fr.n.x == doctest::Approx(s));
    CHECK(fr.n.z == doctest::Approx(c));
    CHECK(fr.t.x == doctest::Approx(c));
    CHECK(fr.t.z == doctest::Approx(-s));
    CHECK(fr.b.y == doctest::Approx(1.f));
    const ShadingFrame world = shading_frame(Vec3<float>(0, 0, 1), Vec3<float>(1, 0, 0), Vec3<float>(0, 1, 0), tangent_normal(s, 0.f));
    CHECK(world.n.y == doctest::Approx(c));  // (t, b, n) = (z, x, y), b = n x t: n_s = s t + c n
    CHECK(world.n.z == doctest::Approx(s));
    CHECK(world.b.x == doctest::Approx(1.f));
    auto model = zero_model();
    std::vector<SvbrdfLayer> layers(1);
    Svbrdf sv(model, 1, 1, TexelAddressing::Repeat, layers, {});
    sv.set_normal_map({s, 0.f});
    CHECK_THROWS_AS(sv.set_normal_map({0.f}), std::invalid_argument);
    const AnalyticParams p = model->materials()[0].params;
    const Vec3<float> wi = normalize(Vec3<float>(0.3f, -0.2f, 0.9f)), wo = normalize(Vec3<float>(-0.4f, 0.1f, 0.8f));
    const auto back = [&](const Vec3<float>& w) { return Vec3<float>(c * w.x - s * w.z, w.y, s * w.x + c * w.z); };
    const Vec3<float> ref = closed_form(p, back(wi), back(wo)), f = sv.eval(Vec2<float>(0.5f, 0.5f), TexelFilter::Nearest, wi, wo);
    for (int k = 0; k < 3; ++k) CHECK(f[k] == doctest::Approx(ref[k]).epsilon(1e-5));
    // Above the geometric horizon, below the shading one (and the swap): 0 both ways, reciprocal.
    const Vec3<float> low = normalize(Vec3<float>(-0.95f, 0.f, 0.2f));
    CHECK(dot(low, fr.n) < 0.f);
    CHECK(sv.eval(Vec2<float>(0.5f, 0.5f), TexelFilter::Nearest, low, wo).x == 0.f);
    CHECK(sv.eval(Vec2<float>(0.5f, 0.5f), TexelFilter::Nearest, wo, low).x == 0.f);
    // Below the geometric horizon, above the shading one: 0 too (no light through the surface).
    const Vec3<float> under = normalize(Vec3<float>(0.95f, 0.f, -0.1f));
    CHECK(dot(under, fr.n) > 0.f);
    CHECK(sv.eval(Vec2<float>(0.5f, 0.5f), TexelFilter::Nearest, under, wo).x == 0.f);
    Texel t;
    sv.texel(Vec2<float>(0.5f, 0.5f), TexelFilter::Nearest, &t);
    CHECK(Svbrdf::pdf(t, Strategy::Mis, under, wo) == 0.f);
}
