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

namespace {

double rel_diff(double a, double b) { return a == b ? 0.0 : std::fabs(a - b) / std::max(std::fabs(a), std::fabs(b)); }

// The hostile corners of the batched sampler's inputs: grazing, normal, below-horizon and
// degenerate wo; u at 0 and just below 1 (and 1, clamped); alpha at its bounds, anisotropic;
// lobe probabilities at both clamps (kd = 0: Fs dominates; eta = 1: Fs = 0).
struct SamplerCase {
    std::vector<float> wo, u;
};

SamplerCase sampler_case(std::mt19937& rng, std::size_t n) {
    std::uniform_real_distribution<float> uni(0.f, 1.f);
    const float us[] = {0.f, 1e-7f, 0.5f, kOneMinusEps<float>, 1.f};
    const Vec3<float> wos[] = {{0.f, 0.f, 1.f}, {1.f, 0.f, 1e-4f}, {0.6f, -0.8f, 1e-7f}, {0.f, 1.f, 3e-3f},
                               {0.3f, 0.2f, -0.5f}, {0.f, 0.f, 0.f}, {2.f, 3.f, 4.f}};
    SamplerCase c;
    for (std::size_t i = 0; i < n; ++i) {
        const unsigned k = rng() % 8;
        Vec3<float> w = k < 7 ? wos[k] : test::spherical(std::acos(uni(rng)), 6.2831853f * uni(rng));
        if (rng() % 2) w = test::spherical(std::acos(uni(rng)), 6.2831853f * uni(rng));
        c.wo.insert(c.wo.end(), {w.x, w.y, w.z});
        for (int j = 0; j < 2; ++j) c.u.push_back(rng() % 4 == 0 ? us[rng() % 5] : uni(rng));
    }
    return c;
}

std::vector<AnalyticParams> sampler_params(std::mt19937& rng) {
    std::vector<AnalyticParams> out = test::param_corners<float>();
    std::uniform_real_distribution<float> uni(0.f, 1.f);
    for (const float kd : {0.f, 1.f}) {  // kd = 0 with eta = 1: Fs + Kd = 0, P_ggx = 1/2
        AnalyticParams p;
        p.kd = Vec3<float>(kd);
        p.eta = Vec3<float>(1.f);
        p.alpha = Vec2<float>(0.05f, 0.7f);
        out.push_back(p);
        p.eta = Vec3<float>(10.f);
        out.push_back(p);
    }
    for (int k = 0; k < 8; ++k) {
        AnalyticParams p;
        p.kd = Vec3<float>(uni(rng), uni(rng), uni(rng));
        p.eta = Vec3<float>(1.f + 3 * uni(rng), 1.f + 3 * uni(rng), 1.f + 3 * uni(rng));
        p.alpha = Vec2<float>(float(kAlphaMin) + uni(rng), float(kAlphaMin) + uni(rng));
        out.push_back(p);
    }
    return out;
}

}  // namespace

TEST_CASE("batched sample_aos and pdf_aos (AVX2 and baseline, every lane remainder) agree with sample() and pdf()") {
    std::mt19937 rng(31);
    const std::vector<AnalyticParams> params = sampler_params(rng);
    std::vector<std::size_t> sizes;
    for (std::size_t n = 1; n <= 17; ++n) sizes.push_back(n);
    sizes.push_back(600);  // three chunks, the last one partial
    // [0]: every lane; [1]: well-conditioned lanes, min(alpha) >= 0.01 and wi.z, wo.z >= 0.01
    // (D amplifies a direction's rounding by ~1/alpha, and reflection near the horizon cancels).
    double worst_wi[2] = {0, 0}, worst_pdf[2] = {0, 0}, worst_weight[2] = {0, 0}, worst_pdf_self[2] = {0, 0};
    std::size_t lanes = 0, flips = 0, rim = 0, pole = 0;
    for (bool baseline : {false, true}) {
        force_baseline_simd(baseline);
        for (const AnalyticParams& p : params) {
            const AnalyticBrdf brdf(p);
            for (std::size_t n : sizes) {
                const SamplerCase c = sampler_case(rng, n);
                std::vector<float> wi(3 * n, -9.f), pdf_v(n, -9.f), weight(3 * n, -9.f), pdf_again(n, -9.f);
                for (Strategy s : kStrategies) {
                    CAPTURE(baseline); CAPTURE(n); CAPTURE(int(s));
                    CAPTURE(p.alpha.x); CAPTURE(p.alpha.y); CAPTURE(p.eta.x); CAPTURE(p.kd.x);
                    sample_aos(s, p, n, c.wo.data(), c.u.data(), wi.data(), pdf_v.data(), weight.data());
                    pdf_aos(s, p, n, wi.data(), c.wo.data(), pdf_again.data());
                    for (std::size_t i = 0; i < n; ++i) {
                        const Vec3<float> wo(c.wo[3 * i], c.wo[3 * i + 1], c.wo[3 * i + 2]);
                        const Vec2<float> u(c.u[2 * i], c.u[2 * i + 1]);
                        const Vec3<float> w(wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]);
                        CAPTURE(i); CAPTURE(wo.x); CAPTURE(wo.y); CAPTURE(wo.z); CAPTURE(u.x); CAPTURE(u.y);
                        REQUIRE(std::isfinite(pdf_v[i]));
                        REQUIRE(pdf_v[i] >= 0.f);
                        for (int k = 0; k < 3; ++k) REQUIRE((std::isfinite(weight[3 * i + k]) && weight[3 * i + k] >= 0.f));
                        // The batch's pdf is pdf_aos() of its own direction.
                        const Vec3<float> won = wo * inverse_length_or_zero(wo);
                        const int cls = std::min(p.alpha.x, p.alpha.y) >= 0.01f && won.z >= 0.01f && wi[3 * i + 2] >= 0.01f;
                        // (A lane with no sample returns +z, whose pdf_aos() need not be 0.)
                        for (int k = 0; k <= cls && pdf_v[i] > 0.f; ++k)
                            worst_pdf_self[k] = std::max(worst_pdf_self[k], rel_diff(pdf_v[i], pdf_again[i]));
                        const BrdfSample ref = sample(s, brdf, wo, u);
                        ++lanes;
                        if (s == Strategy::Mis && wo.z > 0.f) {
                            // A u.x within rounding of P_ggx may pick the other lobe (FMA in P_ggx).
                            if (std::fabs(clamp_unit_square(u).x - ggx_lobe_probability(brdf, won)) < 1e-6f) {
                                ++flips;
                                continue;
                            }
                        }
                        if (s != Strategy::Cosine && clamp_unit_square(u).y == kOneMinusEps<float>) {
                            // The cap's far pole: h_std has length ~sqrt(eps) there and the
                            // rounding of either path decides its direction (finite, checked above).
                            ++pole;
                            continue;
                        }
                        if ((pdf_v[i] > 0.f) != (ref.pdf > 0.f)) {
                            // u on the square's edge: a direction on the horizon (the cosine
                            // warp's rim) whose z rounds to 0 on one path and above it on the
                            // other, or a half vector on the horizon (GGX at u.y = 1) whose
                            // density rounds to 0 on one path and a negligible one on the other.
                            CAPTURE(ref.pdf); CAPTURE(pdf_v[i]); CAPTURE(ref.wi.z); CAPTURE(w.z);
                            REQUIRE(wo.z > 0.f);
                            REQUIRE((std::fabs(ref.pdf > 0.f ? ref.wi.z : w.z) < 1e-3f ||
                                     std::max(ref.pdf, pdf_v[i]) < 1e-4f));
                            ++rim;
                            continue;
                        }
                        if (ref.pdf == 0.f) {
                            CHECK(w == Vec3<float>(0.f, 0.f, 1.f));
                            continue;
                        }
                        for (int j = 0; j <= cls; ++j)
                            for (int k = 0; k < 3; ++k) worst_wi[j] = std::max(worst_wi[j], double(std::fabs(w[k] - ref.wi[k])));
                        // pdf and weight of the batch's own wi by the scalar functions: the
                        // sampled direction's rounding (sincos) is compared above, not amplified by D here.
                        const float q = pdf(s, brdf, w, wo);
                        for (int j = 0; j <= cls; ++j) worst_pdf[j] = std::max(worst_pdf[j], rel_diff(pdf_v[i], q));
                        const Vec3<float> f = brdf.eval(w, wo);
                        for (int j = 0; j <= cls; ++j)
                            for (int k = 0; k < 3; ++k)
                                worst_weight[j] = std::max(worst_weight[j], rel_diff(weight[3 * i + k], f[k] * std::max(w.z, 0.f) / q));
                    }
                }
            }
        }
    }
    force_baseline_simd(false);
    for (int j = 0; j < 2; ++j)
        MESSAGE(std::string(j ? "well-conditioned lanes" : "all lanes") << ": worst |wi - wi_ref| " << worst_wi[j] << ", pdf rel "
                << worst_pdf[j] << ", weight rel " << worst_weight[j] << ", pdf vs pdf_aos rel " << worst_pdf_self[j]);
    MESSAGE("lanes " << lanes << ", lobe-boundary lanes skipped " << flips << ", horizon lanes " << rim
            << ", u.y = 1 lanes " << pole);
    CHECK(flips * 1000 < lanes);
    CHECK(rim * 50 < lanes);
    CHECK(worst_wi[0] < 1e-3);
    CHECK(worst_wi[1] < 1e-3);
    CHECK(worst_pdf[1] < 2e-3);
    CHECK(worst_weight[1] < 2e-3);
    CHECK(worst_pdf_self[1] < 1e-3);
}
