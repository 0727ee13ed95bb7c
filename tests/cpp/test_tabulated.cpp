// The tabulated importance sampler (hybridbrdf/tabulated.hpp) on analytic
// materials: its pdf integrates to 1, sample() draws from pdf() (chi-square,
// with a negative control), it beats cosine sampling on a glossy lobe, its
// albedo estimate is unbiased (also for a lobe narrower than a cell), and the
// hard inputs of CONVENTIONS (grazing, below the horizon, NaN, u at the ends).
#include <doctest/doctest.h>

#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "hybridbrdf/tabulated.hpp"
#include "test_util.hpp"

using namespace hbrdf;
using hbrdf::test::spherical;

namespace {

AnalyticParams glossy(float ax, float ay, float kd = 0.1f) {
    AnalyticParams p;
    p.kd = Vec3<float>(kd, kd * 0.8f, kd * 0.6f);
    p.eta = Vec3<float>(1.5f, 1.6f, 1.7f);
    p.alpha = Vec2<float>(ax, ay);
    return p;
}

BatchEval analytic_eval(const AnalyticParams& p) {
    return [p](std::size_t n, const float* wi, const float* wo, float* f) { eval_analytic_aos(p, n, wi, wo, f); };
}

// Samplers are built once per configuration: a 1-degree isotropic build is
// 11.7 M evaluations, and the suite also runs under the sanitizers.
struct Key {
    float ax, ay, kd;
    bool iso;
    int res;
    TabulatedStorage storage;
    bool operator<(const Key& o) const {
        return std::tie(ax, ay, kd, iso, res, storage) < std::tie(o.ax, o.ay, o.kd, o.iso, o.res, o.storage);
    }
};
const TabulatedSampler& cached(float ax, float ay, bool iso, int res, float kd = 0.1f,
                               TabulatedStorage storage = TabulatedStorage::Compact) {
    static std::map<Key, std::unique_ptr<TabulatedSampler>> cache;
    auto& slot = cache[Key{ax, ay, kd, iso, res, storage}];
    if (!slot)
        slot = std::make_unique<TabulatedSampler>(
            TabulatedSampler::build(analytic_eval(glossy(ax, ay, kd)), iso, res, storage));
    return *slot;
}
const TabulatedSampler& cached_full(float ax, float ay, bool iso, int res) {
    return cached(ax, ay, iso, res, 0.1f, TabulatedStorage::Full);
}

// The table's cells are (theta, phi) rectangles of resolution_deg, phi
// measured from wo's azimuth for isotropic samplers (absolute otherwise).
// Quadratures below use a midpoint rule with kSub x kSub points per cell in
// that grid, so that the piecewise-constant table part is integrated exactly
// (a grid not aligned with the cells aliases: +-3% at grazing wo, where the
// mass sits in few cells) and only the smooth cosine part carries an O(h^2)
// error. Solid angles come from the test's own formula, independent of the
// sampler's.
constexpr int kSub = 2;

double frame_azimuth(const TabulatedSampler& s, const Vec3<float>& wo) {
    return s.isotropic() && (wo.x != 0.0f || wo.y != 0.0f) ? std::atan2(double(wo.y), double(wo.x)) : 0.0;
}

// Calls visit(wi, solid_angle, i, j) for the kSub^2 points per (theta, phi)
// cell of the sampler's grid on the upper hemisphere; (i, j) indexes the point
// in the fine grid of kSub x theta_bins rows and kSub x phi_bins columns.
template <typename Visit> void for_each_point(const TabulatedSampler& s, const Vec3<float>& wo, const Visit& visit) {
    const int n_theta = s.theta_bins() * kSub, n_phi = s.phi_bins() * kSub;
    const double dtheta = 0.5 * M_PI / n_theta, dphi = 2.0 * M_PI / n_phi, phi0 = frame_azimuth(s, wo);
    for (int i = 0; i < n_theta; ++i) {
        const double solid_angle = (std::cos(i * dtheta) - std::cos((i + 1) * dtheta)) * dphi;
        const double theta = (i + 0.5) * dtheta;
        for (int j = 0; j < n_phi; ++j) visit(Vec3<float>(spherical(theta, phi0 + (j + 0.5) * dphi)), solid_angle, i, j);
    }
}

double integrate_pdf(const TabulatedSampler& s, const Vec3<float>& wo) {
    double sum = 0;
    for_each_point(s, wo, [&](const Vec3<float>& wi, double d_omega, int, int) { sum += s.pdf(wi, wo) * d_omega; });
    return sum;
}

// Upper tail of the chi-square distribution with k degrees of freedom,
// Wilson-Hilferty normal approximation (good to a few percent of p for k > 30,
// ample for thresholds of 1e-3).
double chi2_sf(double x, int k) {
    const double v = 2.0 / (9.0 * k);
    const double z = (std::cbrt(x / k) - (1.0 - v)) / std::sqrt(v);
    return 0.5 * std::erfc(z / std::sqrt(2.0));
}

// Histogram bins: `group` x `group` points of the fine grid of
// for_each_point each. group = kSub * 6 makes bins of 6 x 6 table cells (the
// table's distribution); group = 1 makes bins of half a cell, which also sees
// where sample() puts directions inside a cell (uniform in solid angle).
struct Binning {
    int n_theta, n_phi, group;  // fine grid and grouping
    int rows() const { return n_theta / group; }
    int cols() const { return n_phi / group; }
    int bins() const { return rows() * cols(); }
    int bin(int i, int j) const { return (i / group) * cols() + j / group; }
};
Binning binning(const TabulatedSampler& s, int group) {
    return Binning{s.theta_bins() * kSub, s.phi_bins() * kSub, group};
}

// Probability of each histogram bin under `pdf` (a function of wi).
template <typename Pdf>
std::vector<double> bin_probabilities(const TabulatedSampler& s, const Vec3<float>& wo, const Binning& b,
                                      const Pdf& pdf) {
    std::vector<double> prob(std::size_t(b.bins()), 0.0);
    for_each_point(s, wo, [&](const Vec3<float>& wi, double d_omega, int i, int j) {
        prob[std::size_t(b.bin(i, j))] += pdf(wi) * d_omega;
    });
    return prob;
}

std::vector<double> histogram(const TabulatedSampler& s, const Vec3<float>& wo, const Binning& bn, int n,
                              std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> uni(0.0f, 1.0f);
    std::vector<double> count(std::size_t(bn.bins()), 0.0);
    const double dtheta = 0.5 * M_PI / bn.n_theta, dphi = 2.0 * M_PI / bn.n_phi;
    const double phi0 = frame_azimuth(s, wo);
    for (int k = 0; k < n; ++k) {
        const BrdfSample b = s.sample(wo, Vec2<float>(uni(rng), uni(rng)));
        REQUIRE(b.pdf > 0.0f);
        const Vec3<double> wi(b.wi);
        double phi = std::atan2(wi.y, wi.x) - phi0;
        phi -= 2.0 * M_PI * std::floor(phi / (2.0 * M_PI));
        const int i = std::min(int(std::acos(std::min(wi.z, 1.0)) / dtheta), bn.n_theta - 1);
        const int j = std::min(int(phi / dphi), bn.n_phi - 1);
        count[std::size_t(bn.bin(i, j))] += 1.0;
    }
    return count;
}

// Pearson chi-square p-value; bins expected to hold fewer than 5 samples are
// pooled into one (Mitsuba's rule).
double chi2_pvalue(const std::vector<double>& count, const std::vector<double>& prob, int n) {
    double stat = 0, pooled_obs = 0, pooled_exp = 0;
    int dof = -1;
    for (std::size_t b = 0; b < count.size(); ++b) {
        const double e = prob[b] * n;
        if (e < 5.0) {
            pooled_obs += count[b], pooled_exp += e;
            continue;
        }
        stat += (count[b] - e) * (count[b] - e) / e;
        ++dof;
    }
    if (pooled_exp >= 5.0) {
        stat += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
        ++dof;
    } else if (pooled_obs > 10.0) {
        return 0.0;  // many samples where the pdf says there are none
    }
    return chi2_sf(stat, std::max(dof, 1));
}

// Mean and standard error of mean_rgb(weight) over n samples of `sample(u)`.
template <typename Sampler> std::pair<double, double> estimate(const Sampler& sample, int n, std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> uni(0.0f, 1.0f);
    double s1 = 0, s2 = 0;
    for (int k = 0; k < n; ++k) {
        const BrdfSample b = sample(Vec2<float>(uni(rng), uni(rng)));
        const double w = mean(Vec3<double>(b.weight));
        s1 += w, s2 += w * w;
    }
    const double m = s1 / n;
    return {m, std::sqrt(std::max(0.0, s2 / n - m * m) / n)};
}

// Directional albedo mean_rgb int f cos dw by a midpoint rule in double over
// (cos theta, phi) with a grid graded toward wo's mirror direction... kept
// simple: uniform and fine (alpha = 0.1 lobes span ~10 degrees).
double albedo_quadrature(const AnalyticParams& p32, const Vec3<double>& wo, int n_mu, int n_phi) {
    AnalyticParamsT<double> p;
    p.kd = Vec3<double>(p32.kd), p.eta = Vec3<double>(p32.eta), p.alpha = Vec2<double>(p32.alpha);
    const AnalyticBrdfT<double> brdf(p);
    double sum = 0;
    for (int i = 0; i < n_mu; ++i) {
        const double mu = (i + 0.5) / n_mu;
        const double st = std::sqrt(1.0 - mu * mu);
        for (int j = 0; j < n_phi; ++j) {
            const double phi = (j + 0.5) * 2.0 * M_PI / n_phi;
            sum += mean(brdf.eval(Vec3<double>(st * std::cos(phi), st * std::sin(phi), mu), wo)) * mu;
        }
    }
    return sum / n_mu * (2.0 * M_PI / n_phi);
}

}  // namespace

TEST_CASE("tabulated: pdf integrates to 1 over the sphere, including grazing wo") {
    for (int which = 0; which < 3; ++which) {
        const bool iso = which < 2;  // 0: compact isotropic (mirrored), 1: full isotropic, 2: anisotropic
        const TabulatedSampler& s = which == 0 ? cached(0.1f, 0.1f, true, 1)
                                    : which == 1 ? cached_full(0.1f, 0.1f, true, 1)
                                                 : cached(0.05f, 0.3f, false, 3);
        for (double theta_o : {0.0, 0.3, 1.0, 1.4, 1.5607, 0.5 * M_PI - 1e-6}) {
            for (double phi_o : {0.0, 2.2}) {
                const Vec3<float> wo(spherical(theta_o, phi_o));
                CAPTURE(iso); CAPTURE(theta_o); CAPTURE(phi_o);
                CHECK(integrate_pdf(s, wo) == doctest::Approx(1.0).epsilon(1e-3));
            }
        }
        // Nothing below the horizon.
        CHECK(s.pdf(Vec3<float>(0.3f, 0.2f, -0.5f), Vec3<float>(0, 0, 1)) == 0.0f);
    }
}

TEST_CASE("tabulated: sample() draws from pdf() (chi-square), and a wrong pdf is rejected") {
    constexpr int kN = 400000;
    struct Case {
        float ax, ay;
        bool iso;
        int res;
        double theta_o, phi_o;
        int group;  // histogram bin size in fine-grid points (kSub per cell)
        TabulatedStorage storage = TabulatedStorage::Compact;
    };
    const Case cases[] = {
        // The table's distribution, 6 x 6-cell bins.
        {0.1f, 0.1f, true, 1, 0.6, 0.7, 6 * kSub},   {0.1f, 0.1f, true, 1, 1.45, 4.0, 6 * kSub},
        {0.1f, 0.1f, true, 1, 0.0, 0.0, 6 * kSub},   {0.05f, 0.3f, false, 3, 0.9, 1.1, 6 * kSub},
        {0.05f, 0.3f, false, 3, 1.52, 5.5, 6 * kSub},
        // Coarse tables, half-cell bins: placement inside a cell.
        {0.3f, 0.3f, true, 15, 0.7, 1.3, 1},          {0.2f, 0.5f, false, 15, 1.2, 3.9, 1},
        // The uncompressed layout (float CDFs, full azimuth).
        {0.1f, 0.1f, true, 1, 0.6, 0.7, 6 * kSub, TabulatedStorage::Full},
        {0.3f, 0.3f, true, 15, 0.7, 1.3, 1, TabulatedStorage::Full},
    };
    std::uint32_t seed = 11;
    for (const Case& c : cases) {
        const TabulatedSampler& s = cached(c.ax, c.ay, c.iso, c.res, 0.1f, c.storage);
        const Vec3<float> wo(spherical(c.theta_o, c.phi_o));
        const Binning bn = binning(s, c.group);
        CAPTURE(s.mirrored());
        CAPTURE(c.iso); CAPTURE(c.res); CAPTURE(c.theta_o); CAPTURE(c.phi_o);
        const auto count = histogram(s, wo, bn, kN, seed++);
        const auto prob = bin_probabilities(s, wo, bn, [&](const Vec3<float>& wi) { return s.pdf(wi, wo); });
        double total = 0;
        for (double p : prob) total += p;
        CHECK(total == doctest::Approx(1.0).epsilon(1e-3));
        CHECK(chi2_pvalue(count, prob, kN) > 1e-3);
    }
    // Negative controls, same machinery: the pdf of a neighbouring wo, the
    // plain cosine density, and (half-cell bins) directions placed uniformly
    // in theta instead of cos theta inside the cell, which only changes the
    // density inside cells.
    const TabulatedSampler& s = cached(0.1f, 0.1f, true, 1);
    const Vec3<float> wo(spherical(0.6, 0.7)), wo_shifted(spherical(0.6, 0.9));
    const Binning bn = binning(s, 6 * kSub);
    const auto count = histogram(s, wo, bn, kN, 99);
    CHECK(chi2_pvalue(count, bin_probabilities(s, wo, bn, [&](const Vec3<float>& wi) { return s.pdf(wi, wo_shifted); }),
                      kN) < 1e-6);
    CHECK(chi2_pvalue(count, bin_probabilities(s, wo, bn, [](const Vec3<float>& wi) { return max0(wi.z) * kInvPi<float>; }),
                      kN) < 1e-6);

    const TabulatedSampler& coarse = cached(0.3f, 0.3f, true, 15);
    const Vec3<float> wo_c(spherical(0.7, 1.3));
    const Binning fine = binning(coarse, 1);
    const auto count_c = histogram(coarse, wo_c, fine, kN, 98);
    // Density of "uniform in theta inside the cell": the table part scaled by
    // |cell| / (dtheta dphi sin theta) (cosine part unchanged).
    const double dtheta = 0.5 * M_PI / coarse.theta_bins(), dphi = 2.0 * M_PI / coarse.phi_bins();
    const auto wrong = bin_probabilities(coarse, wo_c, fine, [&](const Vec3<float>& wi) {
        const double theta = std::acos(double(wi.z));
        const int row = std::min(int(theta / dtheta), coarse.theta_bins() - 1);
        const double cell = (std::cos(row * dtheta) - std::cos((row + 1) * dtheta)) * dphi;
        const double p_cos = kTabulatedDefensiveFraction * wi.z * kInvPi<double>;
        return p_cos + (coarse.pdf(wi, wo_c) - p_cos) * cell / (dtheta * dphi * std::sin(theta));
    });
    double total = 0;
    for (double p : wrong) total += p;
    CHECK(total == doctest::Approx(1.0).epsilon(2e-3));  // a valid density, just not the sampler's
    CHECK(chi2_pvalue(count_c, wrong, kN) < 1e-6);
}

TEST_CASE("tabulated: sample() reports pdf() of its direction and weight = f cos / pdf") {
    const AnalyticParams p = glossy(0.1f, 0.1f);
    const AnalyticBrdf brdf(p);
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> uni(0.0f, 1.0f);
    for (bool iso : {true, false}) {
        const TabulatedSampler& s = iso ? cached(0.1f, 0.1f, true, 1) : cached(0.1f, 0.1f, false, 3);
        int table_part = 0;
        for (int k = 0; k < 20000; ++k) {
            const Vec3<float> wo(spherical(std::acos(double(uni(rng))), 2 * M_PI * uni(rng)));
            const Vec2<float> u(uni(rng), uni(rng));
            const BrdfSample b = s.sample(wo, u);
            REQUIRE(b.pdf > 0.0f);
            CHECK(std::abs(dot(b.wi, b.wi) - 1.0f) < 1e-5f);
            CHECK(b.wi.z > 0.0f);
            CHECK(b.pdf == s.pdf(b.wi, wo));
            const Vec3<float> w = brdf.eval(b.wi, wo) * (b.wi.z / b.pdf);
            for (int c = 0; c < 3; ++c) CHECK(b.weight[c] == doctest::Approx(w[c]).epsilon(1e-5));
            table_part += u.x >= kTabulatedDefensiveFraction;
        }
        CHECK(table_part > 17000);
    }
}

TEST_CASE("tabulated: sample_direction() is sample() without the BRDF call") {
    int calls = 0;
    const AnalyticBrdf brdf(glossy(0.2f, 0.2f));
    const TabulatedSampler s = TabulatedSampler::build(
        [&](std::size_t n, const float* wi, const float* wo, float* f) {
            ++calls;
            for (std::size_t i = 0; i < n; ++i) {
                const Vec3<float> v = brdf.eval(Vec3<float>(wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]),
                                                Vec3<float>(wo[3 * i], wo[3 * i + 1], wo[3 * i + 2]));
                f[3 * i] = v.x, f[3 * i + 1] = v.y, f[3 * i + 2] = v.z;
            }
        },
        true, 3);
    std::mt19937 rng(4);
    std::uniform_real_distribution<float> uni(0.0f, 1.0f);
    const int after_build = calls;
    for (int k = 0; k < 2000; ++k) {
        const Vec3<float> wo(spherical(std::acos(double(uni(rng))), 2 * M_PI * uni(rng)));
        const Vec2<float> u(uni(rng), uni(rng));
        const BrdfSample d = s.sample_direction(wo, u);
        const BrdfSample b = s.sample(wo, u);
        CHECK(d.wi == b.wi);
        CHECK(d.pdf == b.pdf);
        CHECK(d.weight == Vec3<float>(0.0f));
    }
    CHECK(calls == after_build + 2000);  // only sample() evaluated
}

TEST_CASE("tabulated: lower variance than cosine sampling on a glossy GGX lobe, unbiased albedo") {
    const AnalyticParams p = glossy(0.1f, 0.1f);
    const AnalyticBrdf brdf(p);
    const TabulatedSampler& s = cached(0.1f, 0.1f, true, 1);
    constexpr int kN = 200000;
    for (double theta_o : {0.2, 0.8, 1.3}) {
        const Vec3<float> wo(spherical(theta_o, 0.9));
        const auto tab = estimate([&](const Vec2<float>& u) { return s.sample(wo, u); }, kN, 21);
        const auto cosine = estimate([&](const Vec2<float>& u) { return sample<Strategy::Cosine>(brdf, wo, u); }, kN, 22);
        const double reference = albedo_quadrature(p, Vec3<double>(wo), 2000, 2000);
        const double var_tab = tab.second * tab.second * kN, var_cos = cosine.second * cosine.second * kN;
        MESSAGE("theta_o " << theta_o << ": albedo " << reference << ", tabulated " << tab.first << " +- "
                           << tab.second << " (var " << var_tab << "), cosine var " << var_cos);
        CAPTURE(theta_o);
        CHECK(var_tab < 0.25 * var_cos);
        CHECK(std::abs(tab.first - reference) < 4.0 * tab.second + 1e-4 * reference);
    }
}

TEST_CASE("tabulated: the compact tables sample as well as the full ones (same u, same material)") {
    // Common random numbers: both samplers see the same u sequence, so the
    // variance ratio measures the tables, not the luck of the draw.
    constexpr int kN = 200000;
    struct Case {
        float ax, ay;
        double theta_o;
    };
    for (const Case& c : {Case{0.1f, 0.1f, 0.2}, Case{0.1f, 0.1f, 0.8}, Case{0.1f, 0.1f, 1.3}, Case{0.3f, 0.3f, 0.8},
                          Case{0.01f, 0.01f, 0.5}}) {
        const TabulatedSampler& compact = cached(c.ax, c.ay, true, 1);
        const TabulatedSampler& full = cached_full(c.ax, c.ay, true, 1);
        const Vec3<float> wo(spherical(c.theta_o, 0.9));
        const auto a = estimate([&](const Vec2<float>& u) { return compact.sample(wo, u); }, kN, 41);
        const auto b = estimate([&](const Vec2<float>& u) { return full.sample(wo, u); }, kN, 41);
        const double ratio = (a.second * a.second) / (b.second * b.second);
        MESSAGE("alpha " << c.ax << " theta_o " << c.theta_o << ": variance compact / full " << ratio << " (compact "
                         << a.first << " +- " << a.second << ", full " << b.first << " +- " << b.second << ")");
        CAPTURE(c.ax); CAPTURE(c.theta_o);
        CHECK(ratio < 1.1);
        CHECK(std::abs(a.first - b.first) < 4.0 * std::hypot(a.second, b.second));
    }
}

TEST_CASE("tabulated: unbiased where the lobe is narrower than a cell (alpha 0.01) and anisotropic") {
    // The reference is the library's MIS sampler (unbiased, low variance on
    // these lobes); the two estimates must agree within their standard errors.
    constexpr int kN = 400000;
    struct Case {
        float ax, ay;
        bool iso;
        int res;
    };
    for (const Case& c : {Case{0.01f, 0.01f, true, 1}, Case{0.05f, 0.3f, false, 3}}) {
        const AnalyticParams p = glossy(c.ax, c.ay);
        const AnalyticBrdf brdf(p);
        const TabulatedSampler& s = cached(c.ax, c.ay, c.iso, c.res);
        for (double theta_o : {0.5, 1.2}) {
            const Vec3<float> wo(spherical(theta_o, 2.5));
            const auto tab = estimate([&](const Vec2<float>& u) { return s.sample(wo, u); }, kN, 31);
            const auto mis = estimate([&](const Vec2<float>& u) { return sample<Strategy::Mis>(brdf, wo, u); }, kN, 32);
            const auto cosine = estimate([&](const Vec2<float>& u) { return sample<Strategy::Cosine>(brdf, wo, u); }, kN, 33);
            MESSAGE("alpha " << c.ax << "x" << c.ay << " theta_o " << theta_o << ": tabulated " << tab.first << " +- "
                             << tab.second << ", mis " << mis.first << " +- " << mis.second << ", cosine +- "
                             << cosine.second);
            CAPTURE(c.ax); CAPTURE(theta_o);
            CHECK(std::abs(tab.first - mis.first) < 4.0 * std::hypot(tab.second, mis.second));
            CHECK(tab.second < 0.5 * cosine.second);
        }
    }
}

TEST_CASE("tabulated: hard inputs") {
    const TabulatedSampler& s = cached(0.1f, 0.1f, true, 1);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    const float one_minus = kOneMinusEps<float>;
    const Vec2<float> us[] = {{0, 0}, {one_minus, one_minus}, {1, 1}, {0, one_minus}, {one_minus, 0},
                              {0.1f, 0.5f}, {nan, nan}, {-1, 2}, {0.0999999f, 0.3f}};
    const Vec3<float> upper = Vec3<float>(spherical(0.5, 0.3));

    SUBCASE("wo below the horizon, on it, or invalid: no sample, pdf 0") {
        // Squared lengths that under- or overflow float cannot be normalised (CONVENTIONS).
        for (const Vec3<float>& wo : {Vec3<float>(0, 0, -1), Vec3<float>(0.6f, 0, -0.8f), Vec3<float>(1, 0, 0),
                                      Vec3<float>(0, 0, 0), Vec3<float>(nan, 0, 1), Vec3<float>(0, 0, nan),
                                      Vec3<float>(inf, 0, 1), Vec3<float>(0, 0, inf),
                                      Vec3<float>(0, 0, std::numeric_limits<float>::denorm_min()),
                                      Vec3<float>(1e-30f, 0, 1e-30f), Vec3<float>(1e20f, 1e20f, 1e20f)}) {
            for (const Vec2<float>& u : us) {
                const BrdfSample b = s.sample(wo, u);
                CHECK(b.pdf == 0.0f);
                CHECK(b.wi == Vec3<float>(0, 0, 1));
                CHECK(b.weight == Vec3<float>(0.0f));
            }
            CHECK(s.pdf(upper, wo) == 0.0f);
        }
    }
    SUBCASE("invalid or lower wi: pdf 0") {
        for (const Vec3<float>& wi : {Vec3<float>(0, 0, -1), Vec3<float>(1, 0, 0), Vec3<float>(0, 0, 0),
                                      Vec3<float>(nan, 0, 1), Vec3<float>(0, nan, 1), Vec3<float>(inf, 0, 1)})
            CHECK(s.pdf(wi, upper) == 0.0f);
    }
    SUBCASE("grazing, normal and unnormalised wo; u at 0 and 1 - eps: a valid sample") {
        const float g = 1e-8f;
        for (const Vec3<float>& wo : {Vec3<float>(1, 0, g), Vec3<float>(0, -1, g), Vec3<float>(-0.6f, 0.8f, g),
                                      Vec3<float>(0, 0, 1), Vec3<float>(1e15f, 1e15f, 1e15f),
                                      Vec3<float>(1e-15f, 0, 1e-15f)}) {
            for (const Vec2<float>& u : us) {
                CAPTURE(wo.x); CAPTURE(wo.z); CAPTURE(u.x); CAPTURE(u.y);
                const BrdfSample b = s.sample(wo, u);
                REQUIRE(b.pdf > 0.0f);
                CHECK(std::isfinite(b.pdf));
                CHECK(b.wi.z > 0.0f);
                CHECK(test::finite_nonneg(b.weight));
                CHECK(b.pdf == s.pdf(b.wi, wo));
            }
        }
    }
    SUBCASE("an empty sampler gives no sample") {
        const TabulatedSampler empty;
        CHECK(empty.sample(upper, Vec2<float>(0.5f)).pdf == 0.0f);
        CHECK(empty.pdf(upper, upper) == 0.0f);
        CHECK(empty.memory_bytes() == 0);
    }
    SUBCASE("bad arguments to build") {
        CHECK_THROWS_AS(TabulatedSampler::build(BatchEval{}, true, 1), std::invalid_argument);
        for (int r : {0, -1, 4, 7, 91, 360})
            CHECK_THROWS_AS(TabulatedSampler::build(analytic_eval(glossy(0.3f, 0.3f)), true, r), std::invalid_argument);
    }
}

TEST_CASE("tabulated: black material falls back to cosine; misbehaving eval output is ignored") {
    AnalyticParams black;
    black.kd = Vec3<float>(0.0f);
    black.eta = Vec3<float>(1.0f);  // F = 0: no specular lobe either
    const TabulatedSampler s = TabulatedSampler::build(analytic_eval(black), true, 5);
    const Vec3<float> wo(spherical(0.7, 0.2));
    CHECK(integrate_pdf(s, wo) == doctest::Approx(1.0).epsilon(1e-3));
    const BrdfSample b = s.sample(wo, Vec2<float>(0.5f, 0.5f));
    CHECK(b.pdf > 0.0f);
    CHECK(b.weight == Vec3<float>(0.0f));

    // NaN, Inf and negative values are not probabilities: treated as 0.
    const TabulatedSampler junk = TabulatedSampler::build(
        [](std::size_t n, const float* wi, const float*, float* f) {
            for (std::size_t k = 0; k < n; ++k) {
                const float v = wi[3 * k] > 0.5f ? std::numeric_limits<float>::quiet_NaN()
                                : wi[3 * k] < -0.5f ? -1.0f
                                : wi[3 * k + 1] > 0.9f ? std::numeric_limits<float>::infinity() : 1.0f;
                f[3 * k] = f[3 * k + 1] = f[3 * k + 2] = v;
            }
        },
        false, 5);
    CHECK(integrate_pdf(junk, wo) == doctest::Approx(1.0).epsilon(1e-3));
    // Where the table is 0 only the defensive cosine lobe is left.
    const Vec3<float> wi_nan(spherical(0.9, 0.1));  // wi.x > 0.5
    CHECK(junk.pdf(wi_nan, wo) == doctest::Approx(kTabulatedDefensiveFraction * wi_nan.z * kInvPi<double>).epsilon(1e-5));
}

TEST_CASE("tabulated: memory_bytes counts the tables") {
    const TabulatedSampler& iso = cached(0.1f, 0.1f, true, 1);
    CHECK(iso.table_count() == 90);
    CHECK(iso.theta_bins() == 90);
    CHECK(iso.phi_bins() == 360);
    // Compact: 90 tables x (90 float marginal + 90 x 180 mirrored 16-bit conditional
    // entries); per row constants: 91 cos bounds (double) and 90 inverse solid angles (float).
    const std::size_t expected = 90 * 90 * 4 + 90 * 90 * 180 * 2 + 91 * 8 + 90 * 4;
    CHECK(iso.mirrored());
    CHECK(iso.memory_bytes() == expected);
    CHECK(iso.memory_bytes() <= 5620000);  // the paper's 1-degree table: 5.62 MB
    MESSAGE("isotropic 1-degree tables: " << iso.memory_bytes() << " bytes");
    // Full: float CDFs over the whole azimuth.
    const TabulatedSampler& full = cached_full(0.1f, 0.1f, true, 1);
    CHECK(!full.mirrored());
    CHECK(full.memory_bytes() == std::size_t(90) * (90 + 90 * 360) * 4 + 91 * 8 + 90 * 4);
    MESSAGE("isotropic 1-degree tables, full: " << full.memory_bytes() << " bytes");

    const TabulatedSampler& aniso = cached(0.05f, 0.3f, false, 3);
    CHECK(aniso.phi_o_bins() == 12);
    CHECK(aniso.table_count() == 30 * 12);
    CHECK(!aniso.mirrored());  // no mirror symmetry without isotropy: 16-bit CDFs only
    CHECK(aniso.memory_bytes() == std::size_t(360) * (30 * 4 + 30 * 120 * 2) + 31 * 8 + 30 * 4);

    // table_bytes() predicts memory_bytes() without building (the renderer's budget uses it).
    CHECK(TabulatedSampler::table_bytes(true, 1) == iso.memory_bytes());
    CHECK(TabulatedSampler::table_bytes(true, 1, TabulatedStorage::Full) == full.memory_bytes());
    CHECK(TabulatedSampler::table_bytes(false, 3) == aniso.memory_bytes());
    CHECK(TabulatedSampler::table_bytes(false, 1) == std::size_t(90 * 36) * (90 * 4 + 90 * 360 * 2) + 91 * 8 + 90 * 4);
    CHECK(TabulatedSampler::table_bytes(true, 7) == 0);
    // 129600 sub-sample directions and cosines, two 65536-pair batches, 32400 cell means and 2 x 90 row values.
    CHECK(TabulatedSampler::build_scratch_bytes(1) == 129600 * 4 * 4 + 6 * 65536 * 4 + (32400 + 180) * 8);
}

// Not run by default (420 MB and tens of seconds): doctest --no-skip
// --test-case='*memory and build time*' prints the figures of docs/SAMPLING.md.
TEST_CASE("tabulated: memory and build time at 1 degree" * doctest::skip()) {
    for (bool iso : {true, false}) {
        const auto t0 = std::chrono::steady_clock::now();
        const TabulatedSampler s = TabulatedSampler::build(analytic_eval(glossy(0.1f, iso ? 0.1f : 0.3f)), iso, 1);
        const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        MESSAGE(std::string(iso ? "isotropic" : "anisotropic") << " 1 degree: " << s.table_count() << " tables, "
                                                    << s.memory_bytes() << " bytes, build " << sec << " s");
    }
}
