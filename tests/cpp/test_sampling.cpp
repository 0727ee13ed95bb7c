// Samplers against their own pdf: the pdf integrates to 1 over the sphere,
// sample() reports the pdf that pdf() computes, and weight = f cos / pdf.
// (Chi-square goodness-of-fit and albedo checks live in tests/python.)
#include <doctest/doctest.h>

#include <random>

#include "test_util.hpp"

using namespace hbrdf;
using hbrdf::test::spherical;

namespace {

// Midpoint rule over (cos theta, phi) in [-1, 1] x [0, 2 pi): the measure
// d(cos theta) d(phi) is exactly solid angle.
double integrate_pdf_over_sphere(Strategy s, const AnalyticBrdfT<double>& brdf, const Vec3<double>& wo, int n_mu,
                                 int n_phi) {
    double sum = 0;
    for (int i = 0; i < n_mu; ++i) {
        const double mu = -1.0 + (i + 0.5) * 2.0 / n_mu;
        const double sin_t = std::sqrt(1.0 - mu * mu);
        for (int j = 0; j < n_phi; ++j) {
            const double phi = (j + 0.5) * 2.0 * M_PI / n_phi;
            sum += pdf(s, brdf, Vec3<double>(sin_t * std::cos(phi), sin_t * std::sin(phi), mu), wo);
        }
    }
    return sum * (2.0 / n_mu) * (2.0 * M_PI / n_phi);
}

}  // namespace

TEST_CASE("pdf integrates to 1 over the sphere for every strategy") {
    for (double ax : {0.2, 0.5, 1.0})
        for (double ay : {0.2, 0.6})
            for (double theta_o : {0.0, 0.7, 1.45}) {
                AnalyticParamsT<double> p;
                p.kd = Vec3<double>(0.4);
                p.eta = Vec3<double>(1.5);
                p.alpha = Vec2<double>(ax, ay);
                const AnalyticBrdfT<double> brdf(p);
                const Vec3<double> wo = spherical(theta_o, 0.4);
                for (Strategy s : {Strategy::Cosine, Strategy::Ggx, Strategy::Mis}) {
                    CAPTURE(ax); CAPTURE(ay); CAPTURE(theta_o); CAPTURE(int(s));
                    CHECK(integrate_pdf_over_sphere(s, brdf, wo, 1500, 1500) == doctest::Approx(1.0).epsilon(3e-3));
                }
            }
}

TEST_CASE("sample() reports pdf() of its direction and weight = f cos / pdf") {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    for (int trial = 0; trial < 20000; ++trial) {
        AnalyticParamsT<double> p;
        p.kd = Vec3<double>(uni(rng), uni(rng), uni(rng));
        p.eta = Vec3<double>(1.0 + 3 * uni(rng), 1.0 + 3 * uni(rng), 1.0 + 3 * uni(rng));
        p.alpha = Vec2<double>(0.01 + uni(rng), 0.01 + uni(rng));
        const AnalyticBrdfT<double> brdf(p);
        const Vec3<double> wo = spherical(std::acos(uni(rng)), 2 * M_PI * uni(rng));
        const Vec2<double> u(uni(rng), uni(rng));
        for (Strategy s : {Strategy::Cosine, Strategy::Ggx, Strategy::Mis}) {
            const BrdfSampleT<double> r = sample(s, brdf, wo, u);
            if (r.pdf == 0) continue;
            CHECK(glm::length(r.wi) == doctest::Approx(1.0).epsilon(1e-12));
            CHECK(r.pdf == doctest::Approx(pdf(s, brdf, r.wi, wo)).epsilon(1e-9));
            const Vec3<double> f = brdf.eval(r.wi, wo);
            for (int c = 0; c < 3; ++c)
                CHECK(r.weight[c] == doctest::Approx(f[c] * std::max(r.wi.z, 0.0) / r.pdf).epsilon(1e-9));
        }
    }
}

TEST_CASE("GGX visible normals lie on the upper hemisphere and reflect wo") {
    std::mt19937 rng(6);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    const GgxAlpha<double> a(0.05, 0.7);
    for (int i = 0; i < 10000; ++i) {
        const Vec3<double> wo = spherical(std::acos(uni(rng)), 2 * M_PI * uni(rng));
        const Vec3<double> h = sample_ggx_vndf(wo, Vec2<double>(uni(rng), uni(rng)), a);
        CHECK(h.z >= 0);
        CHECK(glm::dot(wo, h) >= -1e-12);  // visible normals face the viewer
        CHECK(glm::length(h) == doctest::Approx(1.0).epsilon(1e-12));
    }
}

TEST_CASE("strategy names: one list, parsed and printed by one pair of functions") {
    // The names are the documented ones (docs/CONVENTIONS.md, the Python API), written out here.
    const char* names[] = {"cosine", "ggx", "mis"};
    REQUIRE(std::size(kStrategies) == 3);
    for (std::size_t i = 0; i < 3; ++i) {
        CHECK(std::string(strategy_name(kStrategies[i])) == names[i]);
        CHECK(parse_strategy(names[i]) == kStrategies[i]);
    }
    CHECK(!find_strategy("MIS"));
    CHECK(!find_strategy("tabulated"));  // a renderer sampler, not an analytic strategy
    try {
        parse_strategy("vndf");
        FAIL("no exception");
    } catch (const std::invalid_argument& e) {
        CHECK(std::string(e.what()) == "unknown sampling strategy 'vndf'; expected cosine, ggx or mis");
    }
}
