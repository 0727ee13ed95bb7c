// hybridbrdf renderer — materials and their samplers.
#include "hybridbrdf/render/material.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "hybridbrdf/batch.hpp"
#include "hybridbrdf/render/ray_cone.hpp"

namespace hbrdf::render {

namespace {

// 0.5 log2(W H) of a textured material's level 0: the texture's share of the ray cones' Delta
// (ray_cone.hpp), which turns a footprint in uv units into a level of detail in its texels.
float texels_log2(const Svbrdf& sv) { return float(0.5 * std::log2(double(sv.width()) * double(sv.height()))); }

}  // namespace

void Material::set_sampler(SamplerKind kind, const std::optional<AnalyticParams>& proxy, int tabulated_resolution_deg,
                           CancelFlag cancel) {
    tabulated_.reset();
    if (kind == SamplerKind::Tabulated) {
        // The table is built through the material's own (batched) evaluation;
        // sampling uses sample_direction(), which never calls it again.
        const Material* self = this;
        const BatchEval eval = [self, cancel](std::size_t n, const float* wi, const float* wo, float* f) {
            throw_if_cancelled(cancel);  // a table of a network or a Python reader takes seconds
            self->eval(n, wi, wo, f, EvalMode::Full);
        };
        tabulated_ = std::make_shared<const TabulatedSampler>(
            TabulatedSampler::build(eval, isotropic(), tabulated_resolution_deg));
        sampler_ = kind;
        return;
    }
    if (!proxy) {
        sampler_ = SamplerKind::Cosine;
        strategy_ = Strategy::Cosine;
        return;
    }
    sampler_ = kind;
    proxy_ = AnalyticBrdf(*proxy);
    strategy_ = *sampler_strategy(kind);  // not Tabulated: handled above
}

BrdfSample Material::sample(const Vec3f& wo, const Vec2<float>& u) const {
    if (tabulated_) return tabulated_->sample_direction(wo, u);
    return hbrdf::sample(strategy_, proxy_, wo, u);
}

float Material::pdf(const Vec3f& wi, const Vec3f& wo) const {
    if (tabulated_) return tabulated_->pdf(wi, wo);
    return hbrdf::pdf(strategy_, proxy_, wi, wo);
}

std::size_t Material::sampler_memory_bytes() const {
    if (tabulated_) return tabulated_->memory_bytes();
    return sampler_ == SamplerKind::Cosine ? 0 : sizeof(AnalyticParams);
}

void AnalyticMaterial::eval(std::size_t n, const float* wi, const float* wo, float* f, EvalMode) const {
    eval_analytic_aos(params_, n, wi, wo, f);
}

ModelMaterial::ModelMaterial(std::string name, std::shared_ptr<const HybridModel> model, int index, bool analytic_only)
    : Material(std::move(name)), model_(std::move(model)), index_(index), analytic_only_(analytic_only) {
    if (index_ < 0 || std::size_t(index_) >= model_->materials().size())
        throw std::invalid_argument("material index out of range");
    has_analytic_ = model_->kind() != ModelKind::Neural;
    if (analytic_only_ && !has_analytic_)
        throw std::invalid_argument("\"evaluate\": \"analytic\" is not possible: the neural baseline has no analytic part");
}

std::optional<AnalyticParams> ModelMaterial::analytic_params() const {
    if (!has_analytic_) return std::nullopt;
    return model_->materials()[std::size_t(index_)].params;
}

void ModelMaterial::eval(std::size_t n, const float* wi, const float* wo, float* f, EvalMode mode) const {
    if (has_analytic_ && (analytic_only_ || mode == EvalMode::Analytic)) {
        eval_analytic_aos(model_->materials()[std::size_t(index_)].params, n, wi, wo, f);
    } else {
        model_->eval_batch(index_, n, wi, wo, f);
    }
}

TexturedMaterial::TexturedMaterial(std::string name, std::shared_ptr<const Svbrdf> svbrdf, TexelFilter filter,
                                   bool analytic_only)
    : Material(std::move(name)), svbrdf_(std::move(svbrdf)), filter_(filter), analytic_only_(analytic_only),
      texels_log2_(texels_log2(*svbrdf_)) {
    // every layer isotropic and no alpha map that could make it otherwise; a normal map tilts the
    // shading frame off the normal, so the tangent matters then too
    isotropic_ = !svbrdf_->has_normal_map();
    for (const SvbrdfLayer& l : svbrdf_->layers()) {
        const AnalyticParams& p = svbrdf_->model().materials()[std::size_t(l.material)].params;
        isotropic_ = isotropic_ && p.isotropic() && svbrdf_->model().materials()[std::size_t(l.material)].isotropic;
        for (std::size_t i = 0; isotropic_ && i + 1 < l.alpha.size(); i += 2) isotropic_ = l.alpha[i] == l.alpha[i + 1];
    }
}

AnalyticParams TexturedMaterial::base_params() const {
    return svbrdf_->model().materials()[std::size_t(svbrdf_->layers()[0].material)].params;
}

void TexturedMaterial::eval(std::size_t n, const float* wi, const float* wo, float* f, EvalMode mode) const {
    const std::vector<float> uv(2 * n, 0.0f);
    eval_at(n, uv.data(), nullptr, wi, wo, f, mode);
}

namespace {

// The texel of a footprint of `sv`: anisotropic (its probes about uv + centre) or the cone's
// trilinear lookup (lod <= 0, magnified or a point footprint, and a material without a chain read
// level 0 at uv).
void footprint_texel(const Svbrdf& sv, TexelFilter filter, float texels_log2, const Vec2<float>& uv,
                     const Footprint& footprint, Texel* out) {
    if (!footprint.anisotropic() || sv.level_count() == 1) return sv.texel(uv, filter, footprint.cone_log2 + texels_log2, out);
    sv.texel(uv + footprint.centre, filter, TexelFootprint{footprint.duv_dx, footprint.duv_dy, footprint.max_probes}, out);
}

// The footprint sample_at and pdf_at read: any density whose value is known keeps the estimator
// unbiased, so with anisotropic footprints the draw uses the cone's isotropic texel (one trilinear
// lookup against up to N probes' worth) and only f, eval_at, reads the anisotropic one. Not with a
// normal map: its frame decides where the draw can land, and f must be drawn wherever it is not 0.
Footprint sampling_footprint(const Svbrdf& sv, const Footprint& footprint) {
    if (!footprint.anisotropic() || sv.has_normal_map()) return footprint;
    Footprint cone = footprint;
    cone.max_probes = 1;
    return cone;
}

}  // namespace

void TexturedMaterial::texel_at(const Vec2<float>& uv, const Footprint& footprint, Texel* out) const {
    footprint_texel(*svbrdf_, filter_, texels_log2_, uv, footprint, out);
}

void TexturedMaterial::eval_at(std::size_t n, const float* uv, const Footprint* footprint, const float* wi, const float* wo,
                               float* f, EvalMode mode) const {
    const bool analytic = analytic_only_ || mode == EvalMode::Analytic;
    const bool mips = footprint && svbrdf_->level_count() > 1;
    if (!analytic) {
        if (!mips) return svbrdf_->eval_batch(n, uv, wi, wo, filter_, f);
        // "anisotropic" is one setting for the whole render: a batch holds anisotropic footprints
        // and points (hits without a uv scale), which read level 0 (zero derivatives: one probe).
        if (std::any_of(footprint, footprint + n, [](const Footprint& fp) { return fp.anisotropic(); })) {
            thread_local std::vector<float> centred;
            thread_local std::vector<TexelFootprint> probes;
            centred.resize(2 * n), probes.resize(n);
            for (std::size_t i = 0; i < n; ++i) {
                const Footprint& fp = footprint[i];
                centred[2 * i] = uv[2 * i] + fp.centre.x, centred[2 * i + 1] = uv[2 * i + 1] + fp.centre.y;
                probes[i] = fp.anisotropic() ? TexelFootprint{fp.duv_dx, fp.duv_dy, fp.max_probes} : TexelFootprint{};
            }
            return svbrdf_->eval_batch_footprints(n, centred.data(), wi, wo, filter_, f, probes.data());
        }
        std::vector<float> lod(n);
        for (std::size_t i = 0; i < n; ++i) lod[i] = footprint[i].cone_log2 + texels_log2_;
        return svbrdf_->eval_batch(n, uv, wi, wo, filter_, f, lod.data());
    }
    Texel t;
    const Footprint point;
    for (std::size_t i = 0; i < n; ++i) {
        texel_at(Vec2<float>(uv[2 * i], uv[2 * i + 1]), mips ? footprint[i] : point, &t);
        const Vec3f a(wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]), b(wo[3 * i], wo[3 * i + 1], wo[3 * i + 2]);
        const Vec3f v = Svbrdf::eval_analytic(t, a, b);
        f[3 * i] = v.x, f[3 * i + 1] = v.y, f[3 * i + 2] = v.z;
    }
}

BrdfSample TexturedMaterial::sample_at(const Vec3f& wo, const Vec2<float>& u, const Vec2<float>& uv, const Footprint& footprint) const {
    const std::optional<Strategy> s = sampler_strategy(sampler_kind());
    Texel t;
    texel_at(uv, sampling_footprint(*svbrdf_, footprint), &t);
    return Svbrdf::sample(t, s ? *s : Strategy::Cosine, wo, u);
}

float TexturedMaterial::pdf_at(const Vec3f& wi, const Vec3f& wo, const Vec2<float>& uv, const Footprint& footprint) const {
    const std::optional<Strategy> s = sampler_strategy(sampler_kind());
    Texel t;
    texel_at(uv, sampling_footprint(*svbrdf_, footprint), &t);
    return Svbrdf::pdf(t, s ? *s : Strategy::Cosine, wi, wo);
}

void CallbackMaterial::eval(std::size_t n, const float* wi, const float* wo, float* f, EvalMode) const {
    eval_(n, wi, wo, f);
    for (std::size_t i = 0; i < 3 * n; ++i) f[i] = (f[i] > 0.0f && is_finite(f[i])) ? f[i] : 0.0f;
}

MeasuredMixtureMaterial::MeasuredMixtureMaterial(std::string name, std::vector<BatchEval> layers,
                                                 std::shared_ptr<const Svbrdf> weights, TexelFilter filter, bool isotropic)
    : Material(std::move(name)), layers_(std::move(layers)), weights_(std::move(weights)), filter_(filter),
      isotropic_(isotropic) {
    if (!weights_ || int(layers_.size()) != weights_->layer_count())
        throw std::invalid_argument("a measured mixture needs one source per layer of its weights folder (" +
                                    std::to_string(weights_ ? weights_->layer_count() : 0) + "), got " +
                                    std::to_string(layers_.size()));
    texels_log2_ = texels_log2(*weights_);
}

void MeasuredMixtureMaterial::texel_at(const Vec2<float>& uv, const Footprint& footprint, Texel* out) const {
    footprint_texel(*weights_, filter_, texels_log2_, uv, footprint, out);
}

AnalyticParams MeasuredMixtureMaterial::base_params() const {
    return weights_->model().materials()[std::size_t(weights_->layers()[0].material)].params;
}

void MeasuredMixtureMaterial::eval(std::size_t n, const float* wi, const float* wo, float* f, EvalMode mode) const {
    const std::vector<float> uv(2 * n, 0.0f);
    eval_at(n, uv.data(), nullptr, wi, wo, f, mode);
}

void MeasuredMixtureMaterial::eval_at(std::size_t n, const float* uv, const Footprint* footprint, const float* wi,
                                      const float* wo, float* f, EvalMode) const {
    const int L = weights_->layer_count();
    std::vector<float> w(n * std::size_t(L));
    Texel t;
    for (std::size_t i = 0; i < n; ++i) {
        texel_at(Vec2<float>(uv[2 * i], uv[2 * i + 1]), footprint ? footprint[i] : Footprint(), &t);
        for (int k = 0; k < L; ++k) w[i * std::size_t(L) + std::size_t(k)] = t.layers[k].weight;
    }
    std::fill(f, f + 3 * n, 0.0f);
    std::vector<std::size_t> pairs;
    std::vector<float> di, dw, g;
    for (int k = 0; k < L; ++k) {  // one callback per layer: the readers are batched
        pairs.clear();
        for (std::size_t i = 0; i < n; ++i)
            if (w[i * std::size_t(L) + std::size_t(k)] > 0.0f) pairs.push_back(i);
        if (pairs.empty()) continue;
        di.resize(3 * pairs.size()), dw.resize(3 * pairs.size()), g.resize(3 * pairs.size());
        for (std::size_t r = 0; r < pairs.size(); ++r) {
            std::copy(wi + 3 * pairs[r], wi + 3 * pairs[r] + 3, &di[3 * r]);
            std::copy(wo + 3 * pairs[r], wo + 3 * pairs[r] + 3, &dw[3 * r]);
        }
        layers_[std::size_t(k)](pairs.size(), di.data(), dw.data(), g.data());
        for (std::size_t r = 0; r < pairs.size(); ++r)
            for (int c = 0; c < 3; ++c) {
                const float v = g[3 * r + std::size_t(c)];
                f[3 * pairs[r] + std::size_t(c)] += (v > 0.0f && is_finite(v) ? v : 0.0f) * w[pairs[r] * std::size_t(L) + std::size_t(k)];
            }
    }
}

BrdfSample MeasuredMixtureMaterial::sample_at(const Vec3f& wo, const Vec2<float>& u, const Vec2<float>& uv,
                                              const Footprint& footprint) const {
    const std::optional<Strategy> s = sampler_strategy(sampler_kind());
    Texel t;
    texel_at(uv, sampling_footprint(*weights_, footprint), &t);
    return Svbrdf::sample(t, s ? *s : Strategy::Cosine, wo, u);
}

float MeasuredMixtureMaterial::pdf_at(const Vec3f& wi, const Vec3f& wo, const Vec2<float>& uv, const Footprint& footprint) const {
    const std::optional<Strategy> s = sampler_strategy(sampler_kind());
    Texel t;
    texel_at(uv, sampling_footprint(*weights_, footprint), &t);
    return Svbrdf::pdf(t, s ? *s : Strategy::Cosine, wi, wo);
}

}  // namespace hbrdf::render
