// hybridbrdf — the per-value math of fitted models, written once for the scalar
// path (model.cpp) and the batched path (model_batch.cpp). The contract it
// implements (activations, combine rules, the pre-exp bound) is declared in
// spec/model.json and tabulated on hard inputs in spec/activation_combine.json.
// The batched kernels' portable path uses these functions lane by lane; the vector
// kernels repeat the activations and the gated combine as lane-wise intrinsics
// (model_simd.hpp) from the same constants. Both paths are checked against the
// table (tests/python/test_contract_table_cpp.py).
#pragma once

#include <cmath>
#include <limits>

#include "hybridbrdf/model.hpp"

namespace hbrdf::detail {

/// ReLU, or the paper authors' hardGeLU written as x times a hard sigmoid,
/// x * clamp((x + knee) / (2 knee), 0, 1): three branch-free operations, as in
/// the shaders. clamp_nan_lo sends NaN to 0, like max(x, 0) in the SIMD kernels.
HBRDF_INLINE float activate(Activation a, float x) {
    constexpr float kKnee = float(spec::kHardgeluKnee);
    if (a == Activation::Relu) return x > 0.f ? x : 0.f;
    return x * clamp_nan_lo((x + kKnee) * (1.0f / (2.0f * kKnee)), 0.0f, 1.0f);
}

/// The hybrid-reciprocal network inputs (spec/model.json, direction_inputs reciprocal, format 2)
/// of unit wi, wo into x[0], x[stride], ..., x[8 stride]: s = wi + wo, then d.x d.x, d.y d.y,
/// d.z d.z, d.x d.y, d.x d.z, d.y d.z of d = wi - wo (no halves: at half the scale a third of the
/// last hidden layer died in every fit, issue 60). Exchanging wi and wo leaves every value
/// unchanged bit for bit (the sum commutes; d only changes sign, exactly, and the products are even
/// in it), so the network, f_a and the combine all see the same numbers: f(wi, wo) = f(wo, wi).
HBRDF_INLINE void reciprocal_inputs(const Vec3<float>& wi, const Vec3<float>& wo, float* x, int stride) {
    const Vec3<float> s = wi + wo;
    const Vec3<float> d = wi - wo;
    x[0] = s.x, x[stride] = s.y, x[2 * stride] = s.z;
    x[3 * stride] = d.x * d.x, x[4 * stride] = d.y * d.y, x[5 * stride] = d.z * d.z;
    x[6 * stride] = d.x * d.y, x[7 * stride] = d.x * d.z, x[8 * stride] = d.y * d.z;
}

/// exp(min(x, bound)): the file's pre_exp_max keeps every exp() finite in float32.
HBRDF_INLINE float exp_clamped(float x, float bound) { return std::exp(x < bound ? x : bound); }

HBRDF_INLINE float sigmoid(float x) { return 1.0f / (1.0f + std::exp(-x)); }

/// One colour channel of f_t from the network output: `o` is the channel's
/// output o[c], `gate` the gate output o[3 + c] (gated combine only), `fa` the
/// channel of f_a (0 for the neural baseline). The rules: spec/model.json "combines".
HBRDF_INLINE float combine(spec::Combine rule, float o, float gate, float fa, float bound) {
    switch (rule) {
        case spec::Combine::Additive: return max0(fa + o);
        // f_a reaches 3.2e15 (D at alpha_min, grazing) and exp(pre_exp_max_limit = 80) 5.5e34:
        // their product can pass FLT_MAX, so it is held there (as the generated shaders do).
        case spec::Combine::LogMul: return std::fmin(fa * exp_clamped(o, bound), std::numeric_limits<float>::max());
        case spec::Combine::Exp: return exp_clamped(o, bound);
        case spec::Combine::Gated: break;
    }
    return exp_clamped(o, bound) + sigmoid(gate) * fa;
}

// torch.nn.functional.normalize(v, eps=1e-8): v / max(|v|, eps).
HBRDF_INLINE Vec3<float> normalize_eps(const Vec3<float>& v) {
    const float len = std::sqrt(dot(v, v));
    return v / (len > 1e-8f ? len : 1e-8f);
}

/// The neural baseline's shading frames from a latent code (docs/FITTING.md,
/// NeuralBRDF): raw = W z + b gives per frame a normal n and a tangent, made
/// orthonormal by Gram-Schmidt. Writes frames x (t, b, n) x 3 values to `out`.
inline void neural_frames(const DenseLayer& frames, const float* z, float* out) {
    for (int f = 0; f < spec::kNeuralFrames; ++f) {
        float raw[6];
        for (int j = 0; j < 6; ++j) {
            float acc = frames.bias[6 * f + j];
            for (int k = 0; k < frames.n_in; ++k) acc += frames.weight[(6 * f + j) * frames.n_in + k] * z[k];
            raw[j] = acc;
        }
        const Vec3<float> n = normalize_eps(Vec3<float>(raw[0], raw[1], raw[2]));
        const Vec3<float> t_raw(raw[3], raw[4], raw[5]);
        const Vec3<float> t = normalize_eps(t_raw - dot(t_raw, n) * n);
        const Vec3<float> b = glm::cross(n, t);
        for (int c = 0; c < 3; ++c) {
            out[9 * f + c] = t[c];
            out[9 * f + 3 + c] = b[c];
            out[9 * f + 6 + c] = n[c];
        }
    }
}

}  // namespace hbrdf::detail
