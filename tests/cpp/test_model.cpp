// Model files read by the C++ library: a hand-built file with known weights
// gives closed-form values, and damaged files throw ModelFileError naming the
// file (these also run under ASan/UBSan, where a parser overrun would show).
#include <doctest/doctest.h>

#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "test_util.hpp"

using namespace hbrdf;

using namespace hbrdf::test;

TEST_CASE("a hybrid model with zero weights is f_t = 1 + f_a / 2 (exp(0) + sigmoid(0) f_a)") {
    const std::string path = write_model("zero.safetensors", meta("hybrid", 1, 2, 8, 6), zero_hybrid(2));
    const HybridModel model = HybridModel::load(path);
    CHECK(model.materials().size() == 1);
    CHECK(model.find("m") == 0);
    CHECK(model.find("nope") == -1);
    const Vec3<float> wi = test::spherical(0.4f, 0.3f), wo = test::spherical(0.9f, 2.0f);
    const Vec3<float> fa = eval_analytic(wi, wo, model.materials()[0].params);
    const Vec3<float> f = model.eval(0, wi, wo);
    for (int c = 0; c < 3; ++c) CHECK(f[c] == doctest::Approx(1.0f + 0.5f * fa[c]).epsilon(1e-6));
    CHECK(model.eval(0, wi, Vec3<float>(0, 0, -1)).x == 0.f);  // below the horizon: 0, not exp(0)
    std::remove(path.c_str());
}

TEST_CASE("a relu hidden unit and an output weight give the hand-computed correction") {
    auto t = zero_hybrid(0);
    t[0].data = {0.f, 0.f, 2.f, 0.f, 0.f, 0.f};  // hidden = relu(2 wi.z)
    t[2].data = {1.f, 0.f, 0.f, 0.f, 0.f, 0.f};  // o[0] = hidden
    const std::string path = write_model("relu.safetensors", meta("hybrid", 1, 0, 6, 6), t);
    const HybridModel model = HybridModel::load(path);
    const Vec3<float> wi = test::spherical(0.5f, 0.f), wo = test::spherical(0.2f, 1.f);
    const Vec3<float> fa = eval_analytic(wi, wo, model.materials()[0].params);
    CHECK(model.eval(0, wi, wo).x == doctest::Approx(std::exp(2.f * std::cos(0.5f)) + 0.5f * fa.x).epsilon(1e-6));
    CHECK(model.eval(0, wi, wo).y == doctest::Approx(1.f + 0.5f * fa.y).epsilon(1e-6));
    std::remove(path.c_str());
}

TEST_CASE("damaged model files throw ModelFileError naming the file") {
    const std::string good = write_model("good.safetensors", meta("hybrid", 1, 2, 8, 6), zero_hybrid(2));
    std::ifstream in(good, std::ios::binary);
    const std::string raw((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (std::size_t cut : {std::size_t(0), std::size_t(5), std::size_t(40), raw.size() - 3}) {
        const std::string path = "hbrdf_test_cut.safetensors";
        std::ofstream(path, std::ios::binary) << raw.substr(0, cut);
        CAPTURE(cut);
        CHECK_THROWS_AS(HybridModel::load(path), ModelFileError);
        try {
            HybridModel::load(path);
        } catch (const ModelFileError& e) {
            CHECK(std::string(e.what()).rfind(path + ": ", 0) == 0);
        }
        std::remove(path.c_str());
    }
    auto t = zero_hybrid(2);
    t[4].data[1] = std::nanf("");
    const std::string nan_path = write_model("nan.safetensors", meta("hybrid", 1, 2, 8, 6), t);
    CHECK_THROWS_WITH_AS(HybridModel::load(nan_path), doctest::Contains("NaN or Inf"), ModelFileError);
    const std::string kind_path = write_model("kind.safetensors", meta("transformer", 1, 2, 8, 6), zero_hybrid(2));
    CHECK_THROWS_WITH_AS(HybridModel::load(kind_path), doctest::Contains("arch.kind"), ModelFileError);
    const std::string shape_path = write_model("shape.safetensors", meta("hybrid", 1, 3, 9, 6), zero_hybrid(2));
    CHECK_THROWS_AS(HybridModel::load(shape_path), ModelFileError);
    CHECK_THROWS_WITH_AS(HybridModel::load("hbrdf_test_missing.safetensors"), doctest::Contains("no such file"),
                         ModelFileError);
    for (const auto& p : {good, nan_path, kind_path, shape_path}) std::remove(p.c_str());
}
