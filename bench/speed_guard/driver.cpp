// The speed guard's native driver (bench/speed_guard.py builds and runs it). Two modes over the
// same kernels and the same direction pairs:
//
//   speed_guard_driver MODEL MATERIAL_INDEX PAIRS ROUNDS time
//       One process, one pinned core, every kernel timed in the same interleaved rounds, so
//       that the ratios it prints compare kernels under the same machine load. Prints one JSON
//       object of rates (evaluations or samples per second, best round of each kernel) and the
//       FMA peak. These ratios depend on the core's SIMD scaling: they are benchmark figures.
//
//   speed_guard_driver MODEL MATERIAL_INDEX PAIRS 0 count      (under valgrind --tool=callgrind)
//       Each kernel runs once on PAIRS pairs and once on 2 x PAIRS, each run between callgrind
//       client requests that zero the counters and dump them under the kernel's name. The
//       difference of the two counts over PAIRS is the kernel's instructions per item in steady
//       state (set-up and remainder loops cancel). Instructions depend on the compiled code and
//       the instruction set chosen, not on the core that runs them: these are what CI guards.
//       Callgrind's CPU has no AVX-512, so the library takes its AVX2+FMA kernels there.
#include <valgrind/callgrind.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
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
    std::size_t items;                     // items per timed call (the scalar paths get a slice)
    std::function<void()> setup;           // selects the instruction set; not timed or counted
    std::function<void(std::size_t)> run;  // runs the kernel on the first n pairs
    double best_s = 1e30;
};

void use_simd(bool baseline, const char* model_cap) {
    hbrdf::force_baseline_simd(baseline);
    hbrdf::limit_model_simd(model_cap);
}

void time_kernels(std::vector<Kernel>& kernels, int rounds) {
    for (int r = 0; r < rounds + 1; ++r)  // round 0 warms caches and page tables, and is not kept
        for (Kernel& k : kernels) {
            k.setup();
            const auto t0 = Clock::now();
            k.run(k.items);
            const double dt = std::chrono::duration<double>(Clock::now() - t0).count();
            if (r > 0 && dt < k.best_s) k.best_s = dt;
        }
}

// Dumps are named "<kernel>@<items>"; bench/speed_guard.py reads them back.
void count_kernels(std::vector<Kernel>& kernels, std::size_t n) {
    if (!RUNNING_ON_VALGRIND) {
        std::fprintf(stderr, "speed_guard_driver: count mode needs valgrind --tool=callgrind\n");
        std::exit(2);
    }
    for (Kernel& k : kernels) {
        k.setup();
        for (const std::size_t items : {n, 2 * n}) {
            const std::string label = k.name + "@" + std::to_string(items);
            CALLGRIND_ZERO_STATS;
            CALLGRIND_START_INSTRUMENTATION;
            k.run(items);
            CALLGRIND_STOP_INSTRUMENTATION;
            CALLGRIND_DUMP_STATS_AT(label.c_str());
        }
    }
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 6 || (std::strcmp(argv[5], "time") != 0 && std::strcmp(argv[5], "count") != 0)) {
        std::fprintf(stderr, "usage: speed_guard_driver MODEL MATERIAL_INDEX PAIRS ROUNDS time|count\n");
        return 2;
    }
    const bool counting = std::strcmp(argv[5], "count") == 0;
    const hbrdf::HybridModel model = hbrdf::HybridModel::load(argv[1]);
    const int mat = std::atoi(argv[2]);
    const std::size_t n = std::strtoull(argv[3], nullptr, 10);
    const int rounds = std::atoi(argv[4]);

    // Counting runs every kernel on 2 x PAIRS pairs at most.
    const std::size_t capacity = counting ? 2 * n : n;
    const hbrdf::bench::DirectionPairs pairs = hbrdf::bench::cosine_direction_pairs(capacity);
    const std::vector<float> &wi = pairs.wi, &wo = pairs.wo, &u = pairs.u;
    std::vector<float> out(3 * capacity), pdf(capacity), wis(3 * capacity), weight(3 * capacity);
    const hbrdf::AnalyticParams p = model.materials().at(mat).params;
    const float* s = pairs.soa.data();
    float* o = out.data();
    const std::size_t plane = capacity;  // the SoA planes' stride
    // The scalar paths are 5-50x slower than the batched ones: when timed they get a slice.
    const std::size_t n_scalar = counting ? n : n / 8;

    const auto fa_soa = [&](std::size_t k) {
        hbrdf::eval_analytic_soa(p, k, {s, s + plane, s + 2 * plane}, {s + 3 * plane, s + 4 * plane, s + 5 * plane},
                                 {o, o + plane, o + 2 * plane});
    };
    const auto fa_aos = [&](std::size_t k) { hbrdf::eval_analytic_aos(p, k, wi.data(), wo.data(), o); };
    const auto mis = [&](std::size_t k) {
        hbrdf::sample_aos(hbrdf::Strategy::Mis, p, k, wo.data(), u.data(), wis.data(), pdf.data(), weight.data());
    };
    const auto model_batch = [&](std::size_t k) { model.eval_batch(mat, k, wi.data(), wo.data(), o); };
    const auto model_scalar = [&](std::size_t k) {
        for (std::size_t i = 0; i < k; ++i) {
            const hbrdf::Vec3<float> v =
                model.eval(mat, hbrdf::Vec3<float>(wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]),
                           hbrdf::Vec3<float>(wo[3 * i], wo[3 * i + 1], wo[3 * i + 2]));
            o[3 * i] = v.x, o[3 * i + 1] = v.y, o[3 * i + 2] = v.z;
        }
    };
    const auto header = [&](std::size_t k) { header_eval(k, wi.data(), wo.data(), o); };
    // Textured materials (docs/SVBRDF.md): two layers over a 64x64 weights map, uv sweeping the
    // texture in order as a renderer's tile does; all texels pure base (the uniform kernel's
    // path), or every texel half and half (both layers at every pair).
    const auto shared = std::make_shared<const hbrdf::HybridModel>(model);
    const int other = (mat + 1) % int(model.materials().size());
    std::vector<hbrdf::SvbrdfLayer> layers(2);
    layers[0].material = mat, layers[1].material = other;
    const hbrdf::Svbrdf pure(shared, 64, 64, hbrdf::TexelAddressing::Repeat, layers, std::vector<float>(64 * 64 * 3, 0.f));
    std::vector<float> halves(64 * 64 * 3, 0.f);
    for (std::size_t i = 0; i < halves.size(); i += 3) halves[i] = 0.5f;
    const hbrdf::Svbrdf mixed(shared, 64, 64, hbrdf::TexelAddressing::Repeat, layers, halves);
    std::vector<float> uv(2 * capacity);
    for (std::size_t i = 0; i < capacity; ++i) uv[2 * i] = float((double(i) + 0.5) / double(capacity)), uv[2 * i + 1] = 0.37f;
    const auto svbrdf_pure = [&](std::size_t k) { pure.eval_batch(k, uv.data(), wi.data(), wo.data(), hbrdf::TexelFilter::Bilinear, o); };
    const auto svbrdf_mixed = [&](std::size_t k) { mixed.eval_batch(k, uv.data(), wi.data(), wo.data(), hbrdf::TexelFilter::Bilinear, o); };

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
        {"svbrdf_pure", n, simd, svbrdf_pure},
        {"svbrdf_mixed", n, simd, svbrdf_mixed},
    };
    if (counting) {
        count_kernels(kernels, n);
        use_simd(false, "avx512");
        std::printf("{\"simd\": \"%s\", \"model_simd\": \"%s\", \"pairs\": %zu, \"flops_per_eval\": %.1f}\n",
                    hbrdf::simd_path(), hbrdf::model_simd_path(), n, model.flops_per_eval());
        return 0;
    }
    time_kernels(kernels, rounds);
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
