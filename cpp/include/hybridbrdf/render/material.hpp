// hybridbrdf renderer — materials: one batched evaluation interface over the
// analytic BRDF, fitted hybrid/neural models and measured references, plus the
// importance sampler each material was given.
//
// Evaluation is batched on purpose: the wavefront integrator hands a material
// every pair its paths need at one bounce, so a model material runs the
// vectorised HybridModel::eval_batch (64-pair SIMD chunks) and a measured
// reference implemented in Python is called once per batch, not per ray.
//
// Sampling never evaluates the network (paper Sec. 5.2): cosine, GGX VNDF and
// their MIS mixture come from an *analytic proxy* (the model's own f_a
// parameters, the analytic material itself, or "sampling_params" given for a
// measured one); the tabulated sampler is built once, at scene load, from the
// material's full evaluation.
#pragma once

#include <cstddef>
#include <iterator>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "hybridbrdf/model.hpp"
#include "hybridbrdf/render/frame.hpp"
#include "hybridbrdf/render/limits.hpp"
#include "hybridbrdf/render/ray_cone.hpp"
#include "hybridbrdf/sampling.hpp"
#include "hybridbrdf/svbrdf.hpp"
#include "hybridbrdf/tabulated.hpp"

namespace hbrdf::render {

/// What a material evaluates for a batch. The integrator's selective-evaluation
/// policy picks it per path (see integrator.hpp).
enum class EvalMode {
    Full,      ///< the material as specified (hybrid f_t, neural, measured, analytic)
    Analytic,  ///< the analytic part f_a only; materials without one evaluate Full
};

/// How directions are importance-sampled: one of the analytic strategies of
/// sampling.hpp (under the same names) or the tabulated baseline.
enum class SamplerKind { Cosine, Ggx, Mis, Tabulated };

inline constexpr SamplerKind kSamplerKinds[] = {SamplerKind::Cosine, SamplerKind::Ggx, SamplerKind::Mis,
                                                SamplerKind::Tabulated};

/// The analytic strategy a sampler draws from its proxy; nullopt for Tabulated.
constexpr std::optional<Strategy> sampler_strategy(SamplerKind kind) {
    switch (kind) {
        case SamplerKind::Cosine: return Strategy::Cosine;
        case SamplerKind::Ggx: return Strategy::Ggx;
        case SamplerKind::Mis: return Strategy::Mis;
        default: return std::nullopt;
    }
}

/// "cosine", "ggx", "mis" (the strategies' own names) or "tabulated".
constexpr const char* sampler_name(SamplerKind kind) {
    const std::optional<Strategy> s = sampler_strategy(kind);
    return s ? strategy_name(*s) : "tabulated";
}

/// The sampler called `name`; throws std::invalid_argument
/// "unknown sampler 'x'; expected cosine, ggx, mis or tabulated".
inline SamplerKind parse_sampler(std::string_view name) {
    for (SamplerKind k : kSamplerKinds)
        if (name == sampler_name(k)) return k;
    std::string expected;
    const std::size_t n = std::size(kSamplerKinds);
    for (std::size_t i = 0; i < n; ++i)
        expected += std::string(i == 0 ? "" : i + 1 == n ? " or " : ", ") + sampler_name(kSamplerKinds[i]);
    throw std::invalid_argument("unknown sampler '" + std::string(name) + "'; expected " + expected);
}

class Material {
public:
    virtual ~Material() = default;

    /// f(wi, wo) for n pairs: wi, wo (n, 3) row-major unit directions in the
    /// local frame of docs/CONVENTIONS.md (+z normal, +x tangent; wi toward the
    /// light, wo toward the viewer), f (n, 3) RGB without the cosine. Thread-safe.
    virtual void eval(std::size_t n, const float* wi, const float* wo, float* f, EvalMode mode) const = 0;
    /// f at texture coordinates uv (n, 2; SurfaceHit::uv) and footprints (n, or nullptr for
    /// points; ray_cone.hpp's Footprint): a textured material reads its maps there, at level of
    /// detail cone_log2 + 0.5 log2(W H) of its mip chain (kPointFootprint or below 0 texels reads
    /// level 0), or with an anisotropic footprint (max_probes >= 2) at uv + centre by
    /// Svbrdf::texel(uv, filter, TexelFootprint); the others ignore both (this default calls eval).
    virtual void eval_at(std::size_t n, const float* uv, const Footprint* footprint, const float* wi, const float* wo, float* f,
                         EvalMode mode) const {
        (void)uv, (void)footprint;
        eval(n, wi, wo, f, mode);
    }

    /// True when eval(..., Analytic) differs from Full, i.e. the material has a
    /// network the integrator may skip (hybrid model materials).
    virtual bool has_analytic_part() const { return false; }
    /// True when eval(..., mode) runs a network (for the render statistics).
    virtual bool uses_network(EvalMode) const { return false; }
    virtual bool isotropic() const { return true; }
    /// True when the material varies over the surface (reads uv): no single BRDF to tabulate.
    virtual bool spatially_varying() const { return false; }
    /// "analytic", "model", "measured" or "textured".
    virtual const char* type() const = 0;

    const std::string& name() const { return name_; }

    /// Chooses the sampler. Analytic kinds use `proxy`; with no proxy the
    /// material falls back to cosine sampling (documented in docs/RENDERING.md).
    /// Tabulated builds the table now through eval(..., Full), which can take
    /// seconds; `tabulated_resolution_deg` is passed to TabulatedSampler::build.
    /// The build checks `cancel` before every batch and throws Cancelled.
    void set_sampler(SamplerKind kind, const std::optional<AnalyticParams>& proxy, int tabulated_resolution_deg = 1,
                     CancelFlag cancel = nullptr);

    /// A direction wi for wo (both local) from u in [0, 1)^2 and its
    /// whole-sphere solid-angle pdf; pdf == 0 means no sample. The weight of
    /// the returned BrdfSample is *not* the material's (it is the proxy's or 0):
    /// the integrator evaluates the material itself, in a batch.
    BrdfSample sample(const Vec3f& wo, const Vec2<float>& u) const;
    /// Density with which sample() draws wi given wo.
    float pdf(const Vec3f& wi, const Vec3f& wo) const;
    /// sample() and pdf() at texture coordinates uv and footprint (as eval_at's): a textured
    /// material draws from its texel's layers there, at the footprint's level of detail (the same
    /// texel eval_at reads); the others ignore both.
    virtual BrdfSample sample_at(const Vec3f& wo, const Vec2<float>& u, const Vec2<float>& uv, const Footprint& footprint) const {
        (void)uv, (void)footprint;
        return sample(wo, u);
    }
    virtual float pdf_at(const Vec3f& wi, const Vec3f& wo, const Vec2<float>& uv, const Footprint& footprint) const {
        (void)uv, (void)footprint;
        return pdf(wi, wo);
    }

    SamplerKind sampler_kind() const { return sampler_; }
    /// Bytes the sampler keeps for this material (the analytic proxy: its parameters).
    std::size_t sampler_memory_bytes() const;

protected:
    explicit Material(std::string name) : name_(std::move(name)) {}

private:
    std::string name_;
    SamplerKind sampler_ = SamplerKind::Cosine;
    Strategy strategy_ = Strategy::Cosine;
    AnalyticBrdf proxy_{AnalyticParams{}};
    std::shared_ptr<const TabulatedSampler> tabulated_;
};

/// f_a with fixed parameters ({"type": "analytic"}).
class AnalyticMaterial final : public Material {
public:
    AnalyticMaterial(std::string name, const AnalyticParams& params) : Material(std::move(name)), params_(params) {}
    void eval(std::size_t n, const float* wi, const float* wo, float* f, EvalMode mode) const override;
    bool isotropic() const override { return params_.isotropic(); }
    const char* type() const override { return "analytic"; }
    const AnalyticParams& params() const { return params_; }

private:
    AnalyticParams params_;
};

/// One material of a fitted model file ({"type": "model"}). With
/// `analytic_only` the material always evaluates its f_a ("evaluate": "analytic").
class ModelMaterial final : public Material {
public:
    /// Throws std::invalid_argument when `index` is out of range, or when
    /// analytic_only is asked of the neural baseline (it has no f_a).
    ModelMaterial(std::string name, std::shared_ptr<const HybridModel> model, int index, bool analytic_only);
    void eval(std::size_t n, const float* wi, const float* wo, float* f, EvalMode mode) const override;
    bool has_analytic_part() const override { return has_analytic_ && !analytic_only_; }
    bool uses_network(EvalMode mode) const override {
        return !(has_analytic_ && (analytic_only_ || mode == EvalMode::Analytic));
    }
    bool isotropic() const override { return model_->materials()[std::size_t(index_)].isotropic; }
    const char* type() const override { return "model"; }
    /// The analytic parameters (nullopt for the neural baseline).
    std::optional<AnalyticParams> analytic_params() const;

private:
    std::shared_ptr<const HybridModel> model_;
    int index_;
    bool analytic_only_, has_analytic_;
};

/// A textured material ({"type": "textured", "svbrdf": FOLDER}; docs/SVBRDF.md): per hit, the
/// texel of its uv, the layers' mixture sum_k w_k f_t (libhybridbrdf's scalar texel path); with a
/// mip chain, the texel at the hit's footprint (trilinear; docs/RENDERING.md, "Texture footprints"). Its
/// analytic part is sum_k w_k f_a(p_k); it samples the mixture of its layers' f_a samplers with the
/// scene's strategy (cosine, ggx or mis; the tabulated sampler tabulates one BRDF and is refused).
class TexturedMaterial final : public Material {
public:
    TexturedMaterial(std::string name, std::shared_ptr<const Svbrdf> svbrdf, TexelFilter filter, bool analytic_only);
    /// At uv (0, 0) (callers without texture coordinates).
    void eval(std::size_t n, const float* wi, const float* wo, float* f, EvalMode mode) const override;
    void eval_at(std::size_t n, const float* uv, const Footprint* footprint, const float* wi, const float* wo, float* f,
                 EvalMode mode) const override;
    BrdfSample sample_at(const Vec3f& wo, const Vec2<float>& u, const Vec2<float>& uv, const Footprint& footprint) const override;
    float pdf_at(const Vec3f& wi, const Vec3f& wo, const Vec2<float>& uv, const Footprint& footprint) const override;
    bool has_analytic_part() const override { return !analytic_only_; }
    bool uses_network(EvalMode mode) const override { return !(analytic_only_ || mode == EvalMode::Analytic); }
    bool isotropic() const override { return isotropic_; }
    bool spatially_varying() const override { return true; }
    const char* type() const override { return "textured"; }
    const Svbrdf& svbrdf() const { return *svbrdf_; }
    /// The analytic parameters of the base layer's material: what set_sampler records the strategy with.
    AnalyticParams base_params() const;

private:
    std::shared_ptr<const Svbrdf> svbrdf_;
    TexelFilter filter_;
    bool analytic_only_, isotropic_;
    float texels_log2_;  // 0.5 log2(W H) of level 0: a footprint in uv units becomes a level of detail
    // The texel at uv and footprint (level 0 without a mip chain or for a point footprint).
    void texel_at(const Vec2<float>& uv, const Footprint& footprint, Texel* out) const;
};

/// A measured reference behind a batched callback ({"type": "measured"}; the
/// Python front end passes hybridbrdf.open_source(...).eval).
class CallbackMaterial final : public Material {
public:
    CallbackMaterial(std::string name, BatchEval eval, bool isotropic) : Material(std::move(name)), eval_(std::move(eval)), isotropic_(isotropic) {}
    /// Calls the callback; negative and non-finite values (measurement noise)
    /// become 0, since a renderer cannot use negative reflectance.
    void eval(std::size_t n, const float* wi, const float* wo, float* f, EvalMode mode) const override;
    bool isotropic() const override { return isotropic_; }
    const char* type() const override { return "measured"; }

private:
    BatchEval eval_;
    bool isotropic_;
};

/// The exact mixture of measured references under a painted folder's weights map ({"type":
/// "measured", "layers": [SOURCE, ...], "weights": FOLDER}): f(uv) = sum_k w_k(uv) g_k(wi, wo), g_k
/// a batched callback per layer, w_k the folder's weights with its lookup and filter. A convex
/// combination of measurements is a measured BRDF: the ground truth of the textured material
/// `hbrdf paint` fitted from the same files (docs/SVBRDF.md). It samples as the folder's textured
/// material does (the mixture of its fitted layers' f_a samplers, the scene's strategy): for one seed
/// both renders trace the same paths and differ by the BRDF values alone.
class MeasuredMixtureMaterial final : public Material {
public:
    /// `layers`: one callback per layer of `weights` (std::invalid_argument otherwise).
    MeasuredMixtureMaterial(std::string name, std::vector<BatchEval> layers, std::shared_ptr<const Svbrdf> weights,
                            TexelFilter filter, bool isotropic);
    /// At uv (0, 0) (callers without texture coordinates).
    void eval(std::size_t n, const float* wi, const float* wo, float* f, EvalMode mode) const override;
    /// Each layer's callback once for the pairs where its weight is positive; negative and
    /// non-finite values become 0 (as CallbackMaterial's), then the weighted sum in layer order.
    /// With a mip chain in the folder, the weights at the footprint's level of detail (averaged
    /// weights: the mean of the footprint's measured mixtures, exact).
    void eval_at(std::size_t n, const float* uv, const Footprint* footprint, const float* wi, const float* wo, float* f,
                 EvalMode mode) const override;
    BrdfSample sample_at(const Vec3f& wo, const Vec2<float>& u, const Vec2<float>& uv, const Footprint& footprint) const override;
    float pdf_at(const Vec3f& wi, const Vec3f& wo, const Vec2<float>& uv, const Footprint& footprint) const override;
    bool isotropic() const override { return isotropic_; }
    bool spatially_varying() const override { return true; }
    const char* type() const override { return "measured"; }
    /// The folder's base layer material's f_a: what set_sampler records the strategy with.
    AnalyticParams base_params() const;

private:
    std::vector<BatchEval> layers_;
    std::shared_ptr<const Svbrdf> weights_;
    TexelFilter filter_;
    bool isotropic_;
    float texels_log2_;  // 0.5 log2(W H) of the folder's level 0
    void texel_at(const Vec2<float>& uv, const Footprint& footprint, Texel* out) const;
};

}  // namespace hbrdf::render
