// Where a textured material's batched evaluation spends its time (docs/SVBRDF.md, "What texturing
// costs"): Svbrdf::eval_batch on a 512x512 two-layer material (weights 0: every texel the base
// layer; or 0.5: every texel two layers) against
// HybridModel::eval_batch of the base material, random uv, 131,072 pairs x 30.
//
//   cmake --build build --target hybridbrdf
//   g++ -O2 -g -std=c++17 -Icpp/include bench/svbrdf_profile.cpp build/libhybridbrdf.a -o /tmp/svbrdf_profile
//   /tmp/svbrdf_profile python/hybridbrdf/data/prior.safetensors 0   # uniform, M evaluations/s
//   /tmp/svbrdf_profile python/hybridbrdf/data/prior.safetensors 1   # textured, pure texels
//   /tmp/svbrdf_profile python/hybridbrdf/data/prior.safetensors 2   # textured, every texel two layers
//   /tmp/svbrdf_profile python/hybridbrdf/data/prior.safetensors 3   # textured, base layer with kd and z maps
//   perf record -o /tmp/p.data /tmp/svbrdf_profile python/hybridbrdf/data/prior.safetensors 1 && perf report -i /tmp/p.data
#include <chrono>
#include <cstdio>
#include <random>
#include "hybridbrdf/hybridbrdf.hpp"
using namespace hbrdf;
int main(int argc, char** argv) {
    auto model = std::make_shared<const HybridModel>(HybridModel::load(argv[1]));
    std::vector<SvbrdfLayer> layers(2); layers[0].material = 3; layers[1].material = 4;
    const int W = 512;
    int mode = atoi(argv[2]);
    std::vector<float> weights(W * W * 3, 0.f);
    if (mode == 2)  // every texel mixed: half layer 0, half layer 1
        for (int i = 0; i < W * W; ++i) weights[3 * i] = 0.5f;
    if (mode == 3) {  // every texel the base layer, with kd and latent maps (the per-lane kernels)
        const ModelMaterial& m = model->materials()[3];
        layers[0].kd.resize(std::size_t(W) * W * 3);
        layers[0].latent.resize(std::size_t(W) * W * std::size_t(model->latent_dim()));
        for (std::size_t i = 0; i < layers[0].kd.size(); ++i) layers[0].kd[i] = (&m.params.kd.x)[i % 3] * (0.8f + 0.2f * float(i % 7) / 7.f);
        for (std::size_t i = 0; i < layers[0].latent.size(); ++i) layers[0].latent[i] = m.latent[i % m.latent.size()] + 0.01f * float(i % 5);
    }
    Svbrdf sv(model, W, W, TexelAddressing::Repeat, layers, weights);
    const std::size_t n = 1 << 17;
    std::mt19937 rng(1); std::uniform_real_distribution<float> U(0, 1);
    std::vector<float> wi(3 * n), wo(3 * n), uv(2 * n), f(3 * n);
    for (std::size_t i = 0; i < n; ++i) {
        for (int c = 0; c < 2; ++c) uv[2 * i + c] = U(rng);
        float a = U(rng), b = U(rng);
        wi[3*i] = 0.3f*a; wi[3*i+1] = 0.2f*b; wi[3*i+2] = 0.9f; wo[3*i] = -0.2f*b; wo[3*i+1] = 0.4f*a; wo[3*i+2] = 0.8f;
    }
    auto t0 = std::chrono::steady_clock::now();
    for (int r = 0; r < 30; ++r) {
        if (mode == 0) model->eval_batch(3, n, wi.data(), wo.data(), f.data());
        else sv.eval_batch(n, uv.data(), wi.data(), wo.data(), TexelFilter::Bilinear, f.data());
    }
    double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("%s %.2f M/s\n", mode == 3 ? "textured, kd and latent maps" : mode == 2 ? "textured, mixed" : mode ? "textured" : "uniform", 30.0 * n / dt / 1e6);
}
