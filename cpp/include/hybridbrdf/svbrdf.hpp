// hybridbrdf — textured (spatially varying) materials in memory: decoded texel maps of a
// model's layers, texel lookup (bilinear or nearest, repeat or clamp) and evaluation
// (docs/SVBRDF.md; spec/model.json, svbrdf). An engine that decodes its own textures fills a
// Svbrdf directly; render::load_svbrdf reads a painted folder (PNG/EXR maps) into one.
//
//   f(uv, wi, wo) = sum_k w_k(uv) f_t(wi, wo; p_k(uv), z_k(uv), material k's output layer and table)
//
// The weights are linear in f, so bilinear filtering of the weights map is exactly the bilinear
// filter of the layers' BRDFs; p and z maps are filtered as values (docs/SVBRDF.md measures the
// difference at edges).
#pragma once

#include <algorithm>
#include <memory>
#include <vector>

#include "hybridbrdf/model.hpp"
#include "hybridbrdf/normal_map.hpp"
#include "hybridbrdf/sampling.hpp"

namespace hbrdf {

enum class TexelFilter { Bilinear, Nearest };
enum class TexelAddressing { Repeat, Clamp };

/// One layer: a material of the model and its optional maps, each empty (the material's own
/// value everywhere) or width * height * components floats, row 0 the top row (glTF's uv origin).
struct SvbrdfLayer {
    int material = 0;
    std::vector<float> kd;      ///< 3 components
    std::vector<float> eta;     ///< 3 components
    std::vector<float> alpha;   ///< 2 components
    std::vector<float> latent;  ///< latent_dim() components
};

/// A pixel's footprint on the texture for an anisotropic lookup (docs/RENDERING.md, "Anisotropic
/// footprints"): the uv derivatives along the pixel's x and y (uv units per pixel, as GLSL's
/// textureGrad takes them) and the most probes along the footprint's major axis.
struct TexelFootprint {
    Vec2<float> duv_dx{0.f, 0.f}, duv_dy{0.f, 0.f};
    int max_probes = 16;
};

/// How an anisotropic lookup reads the chain: `count` trilinear probes at level of detail `lod`,
/// spaced `step` apart in uv along the major axis and centred on the footprint's uv.
struct AnisotropicProbes {
    int count = 1;
    float lod = 0.f;
    Vec2<float> step{0.f, 0.f};
};

/// The probes of a footprint on a W x H level 0 (GPU-style anisotropic filtering, as
/// EXT_texture_filter_anisotropic describes it): with the derivatives' lengths in texels
/// P_max >= P_min, count = min(max_probes, max(1, ceil(P_max / max(P_min, 1)))) probes spread
/// evenly over the major axis, each at lod = log2(max(P_min, P_max / count)): the minor axis, raised
/// where the cap leaves the probes farther apart than it. Lengths below a texel give one probe at
/// lod <= 0 (level 0: magnification unchanged). Non-finite derivatives: one probe, lod +inf.
AnisotropicProbes anisotropic_probes(const TexelFootprint& fp, int width, int height);

/// The layers' values at one uv, ready for HybridModel::eval_texel, and its normal map's filtered
/// tangent-space x, y (normal_map.hpp) when the material has one.
struct Texel {
    int n_layers = 0;
    TexelLayer layers[spec::kSvbrdfMaxLayers];
    float latent[spec::kSvbrdfMaxLayers * spec::kMaxLatent];
    bool has_normal = false;
    Vec2<float> normal_xy{0.f, 0.f};
    /// The shading frame in the geometric frame's coordinates (identity without a normal map).
    ShadingFrame frame() const { return has_normal ? shading_frame(tangent_normal(normal_xy.x, normal_xy.y)) : ShadingFrame(); }
};

class Svbrdf {
public:
    /// Throws std::invalid_argument for a neural model, 0 or more than kSvbrdfMaxLayers layers, a
    /// material index out of range, a size outside 1..kSvbrdfMaxSide, maps of the wrong length,
    /// values that are not finite, or a missing weights map (several layers; width * height * 3
    /// floats: w_1, w_2, w_3 of layers 1-3).
    Svbrdf(std::shared_ptr<const HybridModel> model, int width, int height, TexelAddressing addressing,
           std::vector<SvbrdfLayer> layers, std::vector<float> weights);

    const HybridModel& model() const { return *model_; }
    int width() const { return width_; }
    int height() const { return height_; }
    int layer_count() const { return int(layers_.size()); }
    TexelAddressing addressing() const { return addressing_; }
    const std::vector<SvbrdfLayer>& layers() const { return layers_; }

    struct Taps;  ///< the texels (and their filter weights) under one uv; svbrdf.cpp

    /// The layers' values at uv: maps decoded then filtered (in double, so that a constant map
    /// gives its value exactly), then the weights normalised (w_0 = 1 - w_1 - w_2 - w_3; divided
    /// by their sum when it is above 1). A non-finite uv reads uv = (0, 0): a tracer never throws
    /// per hit.
    void texel(const Vec2<float>& uv, TexelFilter filter, Texel* out) const;
    /// The same with the weights w_1, w_2, w_3 given (three floats) instead of read from the
    /// weights map, for a renderer that evaluates them itself (the Mitsuba plugin's `weights`
    /// texture): negative and non-finite values count as 0, then the map's normalisation.
    void texel(const Vec2<float>& uv, TexelFilter filter, const float* weights, Texel* out) const;
    /// f(uv, wi, wo) through HybridModel::eval_texel. Every direction argument of this class is in
    /// the geometric frame (local: t = +x, b = +y, n = +z); with a normal map the layers see them
    /// in the texel's shading frame, and f is 0 unless both are above both horizons (normal_map.hpp).
    Vec3<float> eval(const Vec2<float>& uv, TexelFilter filter, const Vec3<float>& wi, const Vec3<float>& wo) const;
    /// f of a texel already looked up: HybridModel::eval_texel in its shading frame, by the rule.
    Vec3<float> eval_texel(const Texel& t, const Vec3<float>& wi, const Vec3<float>& wo) const;

    // ---- normal maps (docs/SVBRDF.md, "Normal maps") -----------------------------------------
    /// Attach a normal map: width * height * 2 floats, the tangent-space x, y of each texel (glTF
    /// 2.0 convention, normal_map.hpp). Throws std::invalid_argument for the wrong length or values
    /// that are not finite. Call before sharing and before set_mips (every level needs its own).
    void set_normal_map(std::vector<float> xy);
    bool has_normal_map() const { return !normal_.empty(); }

    // ---- mip chains (docs/SVBRDF.md, "Mip chains") -------------------------------------------
    /// Attach levels 1 .. 1x1 of a complete mip chain (each a Svbrdf of the same model, layers,
    /// addressing and maps at max(1, width >> L) x max(1, height >> L) texels; power-of-two sides).
    /// Throws std::invalid_argument otherwise. Call before sharing: the chain is read-only after.
    void set_mips(std::vector<std::shared_ptr<const Svbrdf>> levels);
    /// 1 (level 0 alone) or the chain's length.
    int level_count() const { return 1 + int(mips_.size()); }
    /// Level L of the chain (0: this one).
    const Svbrdf& level(int L) const { return L <= 0 ? *this : *mips_[std::size_t(std::min(L, level_count() - 1) - 1)]; }
    /// The isotropic level of detail of a pixel footprint (OpenGL 4.6, 8.14.1): log2 of the longer
    /// of the uv derivatives along the pixel's x and y, measured in level-0 texels.
    float lod(const Vec2<float>& duv_dx, const Vec2<float>& duv_dy) const;
    /// The layers' values at uv and level of detail lod: trilinear, the levels floor(lod) and
    /// floor(lod) + 1 each read by `filter`, their values mixed by the fraction (in double, as
    /// Python's SVBRDF.texels); lod clamped to the chain, lod <= 0 or NaN reads level 0. Every
    /// layer's values are read (a layer of weight 0 on one level may have weight on the other).
    void texel(const Vec2<float>& uv, TexelFilter filter, float lod, Texel* out) const;
    /// The layers' values over a pixel's footprint (anisotropic_probes): the mean of its probes,
    /// each texel(uv_k, filter, lod): every layer's weight averaged (a mean of BRDFs, exact: f is
    /// linear in the weights), its kd, eta and latent code by the weight-weighted mean and its alpha
    /// by that of sqrt(alpha), as the chain's levels are built (docs/SVBRDF.md, "Mip chains"), the
    /// normal map's x, y by the mean. One probe is texel(uv, filter, lod) itself; a material
    /// without a chain reads level 0 at uv.
    void texel(const Vec2<float>& uv, TexelFilter filter, const TexelFootprint& footprint, Texel* out) const;
    /// f at a level of detail through HybridModel::eval_texel.
    Vec3<float> eval(const Vec2<float>& uv, TexelFilter filter, float lod, const Vec3<float>& wi, const Vec3<float>& wo) const;
    /// f for n pairs at once: uv (n, 2), wi, wo (n, 3) row-major, f (n, 3). Pairs on pure texels of
    /// a layer without maps (all filter taps of weight 1 in that layer) are its material: they go to
    /// HybridModel::eval_batch, the uniform material's kernel, in one call per layer. The other
    /// texels' layers of positive weight are sorted by material and evaluated by
    /// HybridModel::eval_batch_layers (per-lane p and latent code), then mixed in layer order: the
    /// batched twin of eval().
    /// With `lod` (n floats, or nullptr: level 0), pairs of positive lod are looked up trilinearly
    /// (texel(uv, filter, lod)) and join the per-layer lists; the others take the path above.
    void eval_batch(std::size_t n, const float* uv, const float* wi, const float* wo, TexelFilter filter, float* f,
                    const float* lod = nullptr) const;
    /// eval_batch with a footprint per pair (n, or nullptr: level 0), read by the anisotropic
    /// texel(uv, filter, footprint); pairs of one probe at lod <= 0 take level 0's path.
    void eval_batch_footprints(std::size_t n, const float* uv, const float* wi, const float* wo, TexelFilter filter,
                               float* f, const TexelFootprint* footprints) const;
    /// sum_k w_k f_a(p_k): the analytic part of the texel.
    Vec3<float> eval_analytic(const Vec2<float>& uv, TexelFilter filter, const Vec3<float>& wi,
                              const Vec3<float>& wo) const;
    /// A direction from the texel's mixture of the layers' f_a samplers (strategy `s`): layer k
    /// chosen with probability w_k by u.x (rescaled), its sample drawn; pdf = sum_k w_k pdf_k.
    BrdfSample sample(const Vec2<float>& uv, TexelFilter filter, Strategy s, const Vec3<float>& wo,
                      const Vec2<float>& u) const;
    /// The density sample() draws wi with.
    float pdf(const Vec2<float>& uv, TexelFilter filter, Strategy s, const Vec3<float>& wi, const Vec3<float>& wo) const;

    /// eval_analytic, sample and pdf of a texel already looked up (texel()), in its shading frame:
    /// sample draws in it and returns wi in the geometric frame (pdf 0 where the rule zeroes f).
    static Vec3<float> eval_analytic(const Texel& t, const Vec3<float>& wi, const Vec3<float>& wo);
    static BrdfSample sample(const Texel& t, Strategy s, const Vec3<float>& wo, const Vec2<float>& u);
    static float pdf(const Texel& t, Strategy s, const Vec3<float>& wi, const Vec3<float>& wo);

private:
    std::shared_ptr<const HybridModel> model_;
    int width_, height_;
    TexelAddressing addressing_;
    std::vector<SvbrdfLayer> layers_;
    std::vector<float> weights_;
    std::vector<float> normal_;  // width * height * 2 tangent-space x, y, or empty
    // Per texel, the layer whose normalised weight is exactly 1 there, or -1 (mixed): a texel whose
    // filter taps are all pure in one layer is that layer alone, with no weights to interpolate.
    std::vector<signed char> pure_layer_;
    std::vector<signed char> pure_quad_;  // the same for each 2x2 block of bilinear taps (svbrdf.cpp)
    // Whether layer k has no maps: its pure texels are its material, evaluated by the uniform kernel.
    bool plain_[spec::kSvbrdfMaxLayers] = {};

    int pure_layer_at(const Taps& t) const;
    // The normalised weights of all layers under the taps (kSvbrdfMaxLayers doubles).
    void weights_at(const Taps& t, double* w) const;
    // Layer k's material and filtered values (p; latent_dim() floats into `latent`) under the taps.
    void layer_at(const Taps& t, int k, TexelLayer* o, float* latent) const;
    // The normal map's filtered x, y under the taps into out (has_normal false without one).
    void normal_at(const Taps& t, Texel* out) const;
    // The normal map's x, y at uv and lod (trilinear as texel(uv, filter, lod, out)).
    Vec2<float> normal_xy(const Vec2<float>& uv, TexelFilter filter, float lod) const;
    // eval_batch with the directions already in each pair's shading frame (no normal map: the same).
    // With `footprints` (not nullptr) the anisotropic lookup replaces `lod`'s trilinear one.
    void eval_batch_local(std::size_t n, const float* uv, const float* wi, const float* wo, TexelFilter filter, float* f,
                          const float* lod, const TexelFootprint* footprints = nullptr) const;
    // eval_batch's normal-map rotation, then eval_batch_local (lod or footprints).
    void eval_batch_any(std::size_t n, const float* uv, const float* wi, const float* wo, TexelFilter filter, float* f,
                        const float* lod, const TexelFootprint* footprints) const;
    // The mean of the probes' texels (texel(uv, filter, footprint)'s arithmetic).
    void texel_probes(const Vec2<float>& uv, TexelFilter filter, const AnisotropicProbes& probes, Texel* out) const;
    // Every layer's values when `all_layers` (the trilinear lookup mixes two levels' values).
    void texel_at(const Taps& t, Texel* out, bool all_layers = false) const;

    std::vector<std::shared_ptr<const Svbrdf>> mips_;  // levels 1 .. 1x1, or empty
};

}  // namespace hbrdf
