// The speed guard's timing driver (bench/speed_guard.py builds and runs it): one process, one
// pinned core, every kernel timed in the same interleaved rounds, so that the ratios it
// prints compare kernels under the same machine load. Prints one JSON object of rates
// (evaluations or samples per second, best round of each kernel) and the FMA peak.
//
//   speed_guard_driver MODEL MATERIAL_INDEX PAIRS ROUNDS
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <string>
#include <vector>

#include "hybridbrdf/hybridbrdf.hpp"
#include "../../cpp/tools/direction_pairs.hpp"
#include "../../cpp/tools/fma_peak.hpp"

void header_eval(std::size_t n, const float* wi, const float* wo, float* f);  // header_kernel.cpp

namespace {

using Clock = std::chrono::steady_clock;

struct Kernel {
    std::string name;
    std::size_t items;              // evaluations per call
    std::function<void()> setup;    // selects the instruction set; not timed
    std::function<void()> run;
    double best_s = 1e30;
};

void use_simd(bool baseline, const char* model_cap) {
    hbrdf::force_baseline_simd(baseline);
    hbrdf::limit_model_simd(model_cap);
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 5) {
        std::fprintf(stderr, "usage: speed_guard_driver MODEL MATERIAL_INDEX PAIRS ROUNDS\n");
        return 2;
    }
    const hbrdf::HybridModel model = hbrdf::HybridModel::load(argv[1]);
    const int mat = std::atoi(argv[2]);
    const std::size_t n = std::strtoull(argv[3], nullptr, 10);
    const int rounds = std::atoi(argv[4]);

    const hbrdf::bench::DirectionPairs pairs = hbrdf::bench::cosine_direction_pairs(n);
    const std::vector<float> &wi = pairs.wi, &wo = pairs.wo, &u = pairs.u;
    std::vector<float> out(3 * n), pdf(n), wis(3 * n), weight(3 * n);
    const hbrdf::AnalyticParams p = model.materials().at(mat).params;
    const float* s = pairs.soa.data();
    float* o = out.data();
    // The scalar paths are 5-50x slower than the batched ones: they get a slice.
    const std::size_t n_scalar = n / 8;

    const auto fa_soa = [&] {
        hbrdf::eval_analytic_soa(p, n, {s, s + n, s + 2 * n}, {s + 3 * n, s + 4 * n, s + 5 * n}, {o, o + n, o + 2 * n});
    };
    const auto fa_aos = [&] { hbrdf::eval_analytic_aos(p, n, wi.data(), wo.data(), o); };
    const auto mis = [&] {
        hbrdf::sample_aos(hbrdf::Strategy::Mis, p, n, wo.data(), u.data(), wis.data(), pdf.data(), weight.data());
    };
    const auto model_batch = [&] { model.eval_batch(mat, n, wi.data(), wo.data(), o); };
    const auto model_scalar = [&] {
        for (std::size_t i = 0; i < n_scalar; ++i) {
            const hbrdf::Vec3<float> v =
                model.eval(mat, hbrdf::Vec3<float>(wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]),
                           hbrdf::Vec3<float>(wo[3 * i], wo[3 * i + 1], wo[3 * i + 2]));
            o[3 * i] = v.x, o[3 * i + 1] = v.y, o[3 * i + 2] = v.z;
        }
    };
    const auto header = [&] { header_eval(n_scalar, wi.data(), wo.data(), o); };

    const auto simd = [] { use_simd(false, "avx512"); };
    const auto baseline = [] { use_simd(true, "avx512"); };
    const auto model_avx2 = [] { use_simd(false, "avx2+fma"); };
    std::vector<Kernel> kernels = {
        {"fa_soa", n, simd, fa_soa},
        {"fa_soa_baseline", n, baseline, fa_soa},
        {"fa_aos", n, simd, fa_aos},
        {"fa_aos_baseline", n, baseline, fa_aos},
        {"mis", n, simd, mis},
        {"mis_baseline", n, baseline, mis},
        {"model_batch", n, simd, model_batch},
        {"model_batch_avx2", n, model_avx2, model_batch},
        {"model_batch_baseline", n, baseline, model_batch},
        {"model_scalar", n_scalar, simd, model_scalar},
        {"header", n_scalar, simd, header},
    };
    for (int r = 0; r < rounds + 1; ++r)  // round 0 warms caches and page tables, and is not kept
        for (Kernel& k : kernels) {
            k.setup();
            const auto t0 = Clock::now();
            k.run();
            const double dt = std::chrono::duration<double>(Clock::now() - t0).count();
            if (r > 0 && dt < k.best_s) k.best_s = dt;
        }
    use_simd(false, "avx512");
    const hbrdf::fma_peak::Peak peak = hbrdf::fma_peak::measure(0.3);

    std::printf("{\"simd\": \"%s\", \"model_simd\": \"%s\", \"pairs\": %zu, \"rounds\": %d, \"flops_per_eval\": %.1f",
                hbrdf::simd_path(), hbrdf::model_simd_path(), n, rounds, model.flops_per_eval());
    std::printf(", \"fma_peak_gflops\": {\"avx2_fma\": %.3f, \"avx512\": %.3f}", peak.avx2_fma, peak.avx512);
    std::printf(", \"rates\": {");
    for (std::size_t i = 0; i < kernels.size(); ++i)
        std::printf("%s\"%s\": %.6g", i ? ", " : "", kernels[i].name.c_str(), kernels[i].items / kernels[i].best_s);
    std::printf("}}\n");
    return 0;
}
