// hybridbrdf — evaluation of fitted models on the scalar path: one (wi, wo) pair at a time,
// scratch space on the stack (thread-safe; the twin of the generated shaders). The file is read
// by HybridModel::load (model_load.cpp), the batched path is model_batch.cpp, and the per-value
// math both paths share is model_math.hpp.
#include "hybridbrdf/model.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "model_math.hpp"

namespace hbrdf {

using detail::activate;

int HybridModel::find(const std::string& name) const {
    for (std::size_t i = 0; i < materials_.size(); ++i)
        if (materials_[i].name == name) return static_cast<int>(i);
    return -1;
}

void HybridModel::check_material(int m) const {
    if (m < 0 || m >= static_cast<int>(materials_.size()))
        throw std::out_of_range("material index " + std::to_string(m) + " out of range (model has " +
                                std::to_string(materials_.size()) + ")");
}

void HybridModel::run_mlp(int m, const float* x, float* out) const {
    float a[kMaxLayerWidth], b[kMaxLayerWidth];
    std::copy(x, x + n_in_, a);
    for (int l = 0; l <= depth_; ++l) {
        const bool last = l == depth_;
        const DenseLayer& L = last ? output_layer(m) : layers_[l];
        float* dst = last ? out : b;
        for (int j = 0; j < L.n_out; ++j) {
            const float* w = L.weight.data() + static_cast<std::size_t>(j) * L.n_in;
            float s = L.bias[j];
            for (int k = 0; k < L.n_in; ++k) s += w[k] * a[k];
            dst[j] = last ? s : activate(activation_, s);
        }
        if (!last) std::copy(b, b + L.n_out, a);
    }
}

Vec3<float> HybridModel::eval_analytic(int m, const Vec3<float>& wi, const Vec3<float>& wo) const {
    check_material(m);
    if (kind_ == ModelKind::Neural) throw std::logic_error("the neural baseline has no analytic part");
    return analytic_[m].eval(wi, wo);
}

Vec3<float> HybridModel::eval(int m, const Vec3<float>& wi_in, const Vec3<float>& wo_in) const {
    check_material(m);
    static const AnalyticBrdf kNoAnalytic{AnalyticParams{}};  // the neural baseline has no f_a
    return eval_with(m, analytic_.empty() ? kNoAnalytic : analytic_[m], materials_[m].latent.data(), wi_in, wo_in);
}

Vec3<float> HybridModel::eval_texel(const TexelLayer* layers, int n_layers, const Vec3<float>& wi,
                                    const Vec3<float>& wo) const {
    if (kind_ == ModelKind::Neural) throw std::logic_error("textured materials need a hybrid model (f_a per texel)");
    if (n_layers < 0 || n_layers > spec::kSvbrdfMaxLayers)
        throw std::invalid_argument("a texel has 0 to " + std::to_string(spec::kSvbrdfMaxLayers) + " layers, got " +
                                    std::to_string(n_layers));
    Vec3<float> f(0.f);
    for (int k = 0; k < n_layers; ++k) {
        const TexelLayer& layer = layers[k];
        check_material(layer.material);
        if (!std::isfinite(layer.weight)) throw std::invalid_argument("texel layer weight is not finite");
        if (!layer.latent) throw std::invalid_argument("texel layer has no latent code");
        if (!(layer.weight > 0.f)) continue;  // a pure texel costs one evaluation
        const Vec3<float> fk = eval_with(layer.material, AnalyticBrdf(layer.params), layer.latent, wi, wo);
        f = f + fk * layer.weight;  // 0 + fk * 1 is fk: a pure texel is its material's value
    }
    return f;
}

Vec3<float> HybridModel::eval_with(int m, const AnalyticBrdf& analytic, const float* latent,
                                   const Vec3<float>& wi_in, const Vec3<float>& wo_in) const {
    const Vec3<float> wi = wi_in * inverse_length_or_zero(wi_in);
    const Vec3<float> wo = wo_in * inverse_length_or_zero(wo_in);
    const bool valid = wi.z > 0.f && wo.z > 0.f;  // false for invalid (zeroed or NaN) input
    if (!valid) return Vec3<float>(0.f);
    const ModelMaterial& mat = materials_[m];
    const spec::ArchSpec& as = arch();
    // Network input (spec/model.json): direction inputs, the latent code, extra inputs.
    float x[kMaxLayerWidth];
    float o[6];
    if (as.directions == spec::DirectionInputs::Frames) {
        // wi, then wo, in the material's shading frames (t, b, n each), prepared at load.
        const float* fr = frame_cache_[m].data();
        for (int side = 0; side < 2; ++side)
            for (int k = 0; k < 3 * spec::kNeuralFrames; ++k)
                x[9 * side + k] = dot(Vec3<float>(fr[3 * k], fr[3 * k + 1], fr[3 * k + 2]), side ? wo : wi);
    } else if (as.directions == spec::DirectionInputs::Reciprocal) {
        detail::reciprocal_inputs(wi, wo, x, 1);
    } else {
        x[0] = wi.x, x[1] = wi.y, x[2] = wi.z, x[3] = wo.x, x[4] = wo.y, x[5] = wo.z;
        if (as.directions == spec::DirectionInputs::LocalHalf) {
            const Vec3<float> h = half_vector(wi, wo);
            x[6] = h.z, x[7] = cos_theta_d(wi, wo, h);
        }
    }
    std::copy(latent, latent + latent_, x + as.direction_count);
    const Vec3<float> fa = as.analytic ? analytic.eval(wi, wo) : Vec3<float>(0.f);
    if (as.extra == spec::ExtraInputs::Log1pFa)
        for (int c = 0; c < 3; ++c) x[as.direction_count + latent_ + c] = std::log1p(fa[c]);
    run_mlp(m, x, o);
    Vec3<float> f;
    for (int c = 0; c < 3; ++c)
        f[c] = detail::combine(as.combine, o[c], as.n_out == 6 ? o[3 + c] : 0.f, fa[c], pre_exp_max_);
    if (energy_bound_ == EnergyBound::AlbedoTable)  // k(wi.z) k(wo.z): one product, symmetric in wi and wo
        f = f * (energy_bound_scale(mat.energy_bound, wi.z) * energy_bound_scale(mat.energy_bound, wo.z));
    return f;
}

float energy_bound_scale(const std::vector<float>& table, float cos_theta) {
    if (table.empty()) return 1.f;
    const float t = cos_theta * float(table.size() - 1);
    float k = 0.f, node = 0.f;
    for (float kj : table) {
        k += kj * std::max(0.f, 1.f - std::fabs(t - node));
        node += 1.f;
    }
    return k;
}

double HybridModel::flops_per_eval() const {
    double fl = 2.0 * width_ * n_dir_inputs_;
    for (int l = 1; l < depth_; ++l) fl += 2.0 * layers_[l].n_in * layers_[l].n_out;
    const DenseLayer& out = output_layer(0);  // every material's has the same shape
    return fl + 2.0 * out.n_in * out.n_out;
}

}  // namespace hbrdf
