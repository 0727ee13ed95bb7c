// Hard cases are part of the contract: every output finite and >= 0 for the
// parameter corners and the hard directions; 0 below the horizon and for
// invalid input; sampling returns usable numbers for any wo and any u.
#include <doctest/doctest.h>

#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "test_util.hpp"

using namespace hbrdf;
using namespace hbrdf::test;

namespace {

// One component of tests/data/hard_directions.json: a number, or a string for what JSON
// cannot hold ("nan", "inf", "-inf") or what depends on the type ("denorm_min").
template <typename T> T hard_component(const nlohmann::json& v, const std::string& file) {
    if (v.is_number()) return T(v.get<double>());
    const std::string s = v.is_string() ? v.get<std::string>() : v.dump();
    if (s == "nan") return std::numeric_limits<T>::quiet_NaN();
    if (s == "inf") return std::numeric_limits<T>::infinity();
    if (s == "-inf") return -std::numeric_limits<T>::infinity();
    if (s == "denorm_min") return std::numeric_limits<T>::denorm_min();
    throw std::runtime_error(file + ": unknown component " + s);
}

/// The hard directions of the contract, read from tests/data/hard_directions.json (the table
/// the Python tests read too): grazing (z = 0, 1e-8), the normal, below the horizon,
/// zero-length, NaN and Inf, huge, tiny and subnormal lengths. Read once per type.
template <typename T> const std::vector<Vec3<T>>& hard_directions() {
    static const std::vector<Vec3<T>> dirs = [] {
        const std::string file = HBRDF_TEST_DATA_DIR "/hard_directions.json";
        std::ifstream in(file);
        if (!in) throw std::runtime_error(file + ": cannot open");
        const nlohmann::json doc = nlohmann::json::parse(in);
        std::vector<Vec3<T>> out;
        for (const auto& entry : doc.at("directions")) {
            const auto& w = entry.at("w");
            if (w.size() != 3) throw std::runtime_error(file + ": an entry's w has " + std::to_string(w.size()) +
                                                        " components, expected 3");
            out.emplace_back(hard_component<T>(w[0], file), hard_component<T>(w[1], file),
                             hard_component<T>(w[2], file));
        }
        return out;
    }();
    return dirs;
}

template <typename T> bool is_valid_upper(const Vec3<T>& v) {
    const T len2 = v.x * v.x + v.y * v.y + v.z * v.z;
    return std::isfinite(len2) && len2 >= std::numeric_limits<T>::min() && v.z > T(0);
}

template <typename T> void check_eval_hard_cases() {
    const auto dirs = hard_directions<T>();
    for (const auto& p : param_corners<T>()) {
        const AnalyticBrdfT<T> brdf(p);
        for (const auto& wi : dirs)
            for (const auto& wo : dirs) {
                const Vec3<T> f = brdf.eval(wi, wo);
                CAPTURE(wi.x); CAPTURE(wi.y); CAPTURE(wi.z); CAPTURE(wo.x); CAPTURE(wo.y); CAPTURE(wo.z);
                CAPTURE(p.alpha.x); CAPTURE(p.alpha.y); CAPTURE(p.eta.x);
                REQUIRE(finite_nonneg(f));
                if (!is_valid_upper(wi) || !is_valid_upper(wo)) REQUIRE((f.x == 0 && f.y == 0 && f.z == 0));
                for (Strategy s : {Strategy::Cosine, Strategy::Ggx, Strategy::Mis}) {
                    const T q = pdf(s, brdf, wi, wo);
                    REQUIRE(std::isfinite(q));
                    REQUIRE(q >= 0);
                    if (!is_valid_upper(wo)) REQUIRE(q == 0);
                }
            }
    }
}

template <typename T> void check_sample_hard_cases() {
    const T nan = std::numeric_limits<T>::quiet_NaN();
    const std::vector<Vec2<T>> us = {{0, 0}, {0.5, 0.5}, {kOneMinusEps<T>, kOneMinusEps<T>}, {1, 1}, {0, 1},
                                     {1, 0}, {nan, 0.5}, {0.5, nan}, {-1, 2}, {0.1, 0.999999}};
    for (const auto& p : param_corners<T>()) {
        const AnalyticBrdfT<T> brdf(p);
        for (const auto& wo : hard_directions<T>())
            for (const auto& u : us)
                for (Strategy s : {Strategy::Cosine, Strategy::Ggx, Strategy::Mis}) {
                    const BrdfSampleT<T> r = sample(s, brdf, wo, u);
                    CAPTURE(wo.x); CAPTURE(wo.y); CAPTURE(wo.z); CAPTURE(u.x); CAPTURE(u.y); CAPTURE(int(s));
                    CAPTURE(p.alpha.x); CAPTURE(p.alpha.y);
                    REQUIRE(std::isfinite(r.pdf));
                    REQUIRE(r.pdf >= 0);
                    REQUIRE(finite_nonneg(r.weight));
                    REQUIRE(std::isfinite(r.wi.x));
                    REQUIRE(std::isfinite(r.wi.y));
                    REQUIRE(std::isfinite(r.wi.z));
                    REQUIRE(glm::length(Vec3<double>(r.wi)) == doctest::Approx(1.0).epsilon(1e-5));
                    if (!is_valid_upper(wo)) REQUIRE(r.pdf == 0);
                    if (r.pdf == 0) REQUIRE((r.weight.x == 0 && r.weight.y == 0 && r.weight.z == 0));
                }
    }
}

// Every kind of hard input the contract names is in the shared table, in this type: an edit
// of tests/data/hard_directions.json cannot drop one unnoticed.
template <typename T> void check_table_coverage() {
    bool nan = false, pos_inf = false, neg_inf = false, subnormal = false, zero = false, below = false,
         grazing = false, huge = false, tiny = false, normal = false;
    for (const auto& w : hard_directions<T>()) {
        for (int c = 0; c < 3; ++c) {
            nan |= std::isnan(w[c]);
            pos_inf |= w[c] == std::numeric_limits<T>::infinity();
            neg_inf |= w[c] == -std::numeric_limits<T>::infinity();
            subnormal |= std::fpclassify(w[c]) == FP_SUBNORMAL;
            huge |= std::isfinite(w[c]) && std::abs(w[c]) >= T(1e10);
            tiny |= w[c] != T(0) && std::abs(w[c]) <= T(1e-20);
        }
        zero |= w.x == T(0) && w.y == T(0) && w.z == T(0);
        below |= w.z < T(0);
        grazing |= w.z >= T(0) && w.z <= T(1e-8) && std::abs(w.x) + std::abs(w.y) > T(0.5);
        normal |= w.x == T(0) && w.y == T(0) && w.z == T(1);
    }
    CHECK(nan);
    CHECK(pos_inf);
    CHECK(neg_inf);
    CHECK(subnormal);
    CHECK(zero);
    CHECK(below);
    CHECK(grazing);
    CHECK(huge);
    CHECK(tiny);
    CHECK(normal);
}

}  // namespace

TEST_CASE("the shared hard-direction table covers every kind of hard input") {
    check_table_coverage<float>();
    check_table_coverage<double>();
}

TEST_CASE("eval and pdf: finite, non-negative, zero for invalid input (float)") { check_eval_hard_cases<float>(); }
TEST_CASE("eval and pdf: finite, non-negative, zero for invalid input (double)") { check_eval_hard_cases<double>(); }
TEST_CASE("sample: finite for any wo and u (float)") { check_sample_hard_cases<float>(); }
TEST_CASE("sample: finite for any wo and u (double)") { check_sample_hard_cases<double>(); }

TEST_CASE("batched kernels keep the hard-case contract") {
    const auto dirs = hard_directions<float>();
    std::vector<float> wi, wo;
    for (const auto& a : dirs)
        for (const auto& b : dirs) {
            wi.insert(wi.end(), {a.x, a.y, a.z});
            wo.insert(wo.end(), {b.x, b.y, b.z});
        }
    const std::size_t n = wi.size() / 3;
    std::vector<float> f(3 * n), f_soa(3 * n), q(n);
    const std::vector<float> soa_in = pairs_to_soa(wi, wo);
    for (const auto& p : param_corners<float>())
        for (bool baseline : {false, true}) {
            force_baseline_simd(baseline);
            eval_analytic_aos(p, n, wi.data(), wo.data(), f.data());
            eval_analytic_soa_planes(p, soa_in, f_soa);
            for (std::size_t i = 0; i < 3 * n; ++i) {
                REQUIRE(std::isfinite(f[i]));
                REQUIRE(f[i] >= 0);
                REQUIRE(std::isfinite(f_soa[i]));
                REQUIRE(f_soa[i] >= 0);
            }
            pdf_aos(Strategy::Mis, p, n, wi.data(), wo.data(), q.data());
            for (float v : q) REQUIRE((std::isfinite(v) && v >= 0));
        }
    force_baseline_simd(false);
}

TEST_CASE("out-of-range parameters are clamped, never NaN") {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    AnalyticParams p;
    p.kd = Vec3<float>(nan, -1.f, inf);
    p.eta = Vec3<float>(0.f, nan, 1e9f);
    p.alpha = Vec2<float>(0.f, nan);
    const AnalyticBrdf brdf(p);
    for (const auto& wi : hard_directions<float>())
        for (const auto& wo : hard_directions<float>()) REQUIRE(finite_nonneg(brdf.eval(wi, wo)));
}
