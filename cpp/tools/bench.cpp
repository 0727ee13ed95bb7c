// hbrdf_bench — single-core throughput of the batched analytic kernels,
// measured natively (no Python in the timed loop). Prints one JSON object.
//
//   hbrdf_bench [n_pairs] [repeats]
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "direction_pairs.hpp"
#include "hybridbrdf/hybridbrdf.hpp"

namespace {

using Clock = std::chrono::steady_clock;

template <typename F> double best_seconds(int repeats, F&& f) {
    double best = 1e30;
    for (int r = 0; r < repeats; ++r) {
        const auto t0 = Clock::now();
        f();
        const double s = std::chrono::duration<double>(Clock::now() - t0).count();
        best = s < best ? s : best;
    }
    return best;
}

}  // namespace

int main(int argc, char** argv) {
    const std::size_t n = argc > 1 ? std::strtoull(argv[1], nullptr, 10) : (1u << 20);
    const int repeats = argc > 2 ? std::atoi(argv[2]) : 7;

    const hbrdf::bench::DirectionPairs pairs = hbrdf::bench::cosine_direction_pairs(n);
    const std::vector<float> &wi = pairs.wi, &wo = pairs.wo, &u = pairs.u;
    std::vector<float> soa_out(3 * n), aos_out(3 * n), pdf(n), wis(3 * n), weight(3 * n);
    hbrdf::AnalyticParams p;
    p.kd = {0.3f, 0.2f, 0.1f};
    p.eta = {1.5f, 1.6f, 1.7f};
    p.alpha = {0.2f, 0.4f};

    const float* s = pairs.soa.data();
    float* o = soa_out.data();
    std::printf("{\"n\": %zu, \"simd\": \"%s\"", n, hbrdf::simd_path());
    for (int pass = 0; pass < 2; ++pass) {
        hbrdf::force_baseline_simd(pass == 1);
        const char* tag = pass == 0 ? "" : "_baseline";
        const double t_soa = best_seconds(repeats, [&] {
            hbrdf::eval_analytic_soa(p, n, {s, s + n, s + 2 * n}, {s + 3 * n, s + 4 * n, s + 5 * n},
                                     {o, o + n, o + 2 * n});
        });
        const double t_aos = best_seconds(repeats, [&] {
            hbrdf::eval_analytic_aos(p, n, wi.data(), wo.data(), aos_out.data());
        });
        const double t_mis = best_seconds(repeats, [&] {
            hbrdf::sample_aos(hbrdf::Strategy::Mis, p, n, wo.data(), u.data(), wis.data(), pdf.data(), weight.data());
        });
        std::printf(", \"eval_soa%s\": %.6g, \"eval_aos%s\": %.6g, \"sample_mis%s\": %.6g", tag, n / t_soa, tag,
                    n / t_aos, tag, n / t_mis);
    }
    hbrdf::force_baseline_simd(false);
    std::printf("}\n");
    return 0;
}
