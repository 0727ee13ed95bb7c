// hybridbrdf renderer — a glTF 2.0 material with its own textures (docs/GLTF.md, "Textures").
//
// An unbound glTF material renders as f_a whose parameters come, per hit, from its factors times
// its textures through the mapping of docs/GLTF.md ("The mapping"):
//   baseColor = baseColorFactor * baseColorTexture (sRGB decoded to linear per texel, then filtered)
//   metallic  = metallicFactor  * metallicRoughnessTexture.B (linear)
//   roughness = roughnessFactor * metallicRoughnessTexture.G (linear)
// each texture read at TEXCOORD_0 through its sampler (wrap S and T: REPEAT, CLAMP_TO_EDGE,
// MIRRORED_REPEAT; magFilter and minFilter; with a mipmap minFilter, the level of detail of the
// ray cone's footprint in gltf_mip_chain's levels, the same levels hbrdf_raster uploads). A normalTexture tilts the shading frame: n_t = normalize((2 rgb - 1) (scale, scale,
// 1)) in the geometric frame (t = +x, b = n x t = +y, n = +z; glTF's +Y up in the image with
// w = +1), then normal_map.hpp's frame and horizon rule, as a textured folder's normal map.
// A glTF material bound to another material keeps the asset's normalTexture through
// NormalMappedMaterial (unless the bound textured folder has a normal map of its own).
#pragma once

#include <array>
#include <limits>
#include <memory>
#include <vector>

#include "hybridbrdf/normal_map.hpp"
#include "hybridbrdf/render/material.hpp"

namespace hbrdf::render {

/// glTF sampler wrap modes (their JSON values).
enum class GltfWrap { Repeat = 10497, ClampToEdge = 33071, MirroredRepeat = 33648 };

/// One decoded glTF image: 8-bit RGBA as stored (alpha 255 where the file has none), row 0 the top
/// row (uv (0, 0) is the image's top-left corner, as glTF's).
struct GltfImage {
    int width = 0, height = 0;
    std::vector<unsigned char> rgba;
};

/// The mip chain of a glTF image, levels 1, 2, ... (level 0 is the image itself), as both the
/// tracer and hbrdf_raster read it (the raster uploads these levels instead of blitting its own):
/// level l is max(1, floor(W / 2^l)) x max(1, floor(H / 2^l)) texels (Vulkan's level sizes, down to
/// 1 x 1), and each of its texels is the area average of the level l - 1 texels under it: the 2 x 2
/// mean on an even side; on an odd side of n texels, the footprint of n / floor(n / 2) texels
/// (1 on a side that stays 1), each texel weighed by its overlap (a box filter where a blit's
/// bilinear tap would drop part of the edge texel). Averages are of linear values: an `srgb`
/// image's RGB is decoded first (srgb_to_linear) and re-encoded per level; alpha and a linear
/// image's channels are averaged as stored. Each level is computed in double from the previous
/// one's unrounded values, then rounded to 8 bits (nearest).
std::vector<GltfImage> gltf_mip_chain(const GltfImage& level0, bool srgb);

/// True for glTF minFilter values with a mipmap mode (9984-9987): the texture has a chain.
constexpr bool gltf_mipmapped(int min_filter) { return min_filter >= 9984 && min_filter <= 9987; }

/// A glTF texture as one material slot reads it: its image, its mip chain and its sampler.
struct GltfTexture {
    std::shared_ptr<const GltfImage> image;
    /// Levels 1, 2, ... (gltf_mip_chain) when min_filter is a mipmap mode; null or empty: level 0 only.
    std::shared_ptr<const std::vector<GltfImage>> mips;
    GltfWrap wrap_s = GltfWrap::Repeat, wrap_t = GltfWrap::Repeat;
    bool nearest = false;   ///< magFilter NEAREST (9728): the texel under uv; otherwise bilinear
    int min_filter = 9987;  ///< glTF minFilter: the filter in a level and between levels when minified
    bool srgb = false;      ///< the texel's RGB is sRGB-encoded (baseColorTexture): decoded before filtering

    /// The filtered RGBA at uv in [0, 1] (double; sRGB decoded when `srgb`; alpha always linear)
    /// at level of detail `lod` (log2 of the footprint in level-0 texels), as Vulkan's sampler does
    /// (1.3, 16.5-16.6): lambda = lod clamped to [0, levels - 1]; lod <= 0 (or NaN) is magnified
    /// (magFilter, level 0); above, minFilter: NEAREST_MIPMAP_* the level round(lambda) (ties
    /// down), LINEAR_MIPMAP_* the mix of levels floor(lambda) and floor(lambda) + 1, NEAREST or
    /// LINEAR level 0; in each level nearest (NEAREST, *_MIPMAP_NEAREST's first word) or bilinear.
    /// A non-finite uv reads (0, 0).
    std::array<double, 4> sample(double u, double v, double lod = -std::numeric_limits<double>::infinity()) const;
    /// 0.5 log2(W H) of level 0: a footprint (log2, uv units) plus this is the level of detail.
    double texels_log2() const;
    /// The level of detail of a ray cone's footprint (ray_cone.hpp): footprint + texels_log2().
    double lod(float footprint) const { return double(footprint) + texels_log2(); }
};

/// The texel index that `wrap` gives integer coordinate i on a side of `size` texels (Vulkan's
/// addressing: repeat i mod size, clamp to [0, size - 1], mirrored repeat of period 2 size).
int wrap_texel(int i, int size, GltfWrap wrap);

/// sRGB's electro-optical transfer function (IEC 61966-2-1), x in [0, 1].
double srgb_to_linear(double x);
/// Its inverse (the encoding), x in [0, 1].
double linear_to_srgb(double x);

/// What of a glTF material is not texture: its factors, reduced to what the mapping needs.
struct GltfFactors {
    Vec3<double> base{1.0};           ///< baseColorFactor rgb
    double metallic = 1.0, roughness = 1.0;
    Vec3<double> dielectric_f0{0.04};  ///< min(((ior - 1) / (ior + 1))^2 specularColor, 1) specular
    double anisotropy = 0.0;          ///< KHR_materials_anisotropy's strength
};

/// The mapping of docs/GLTF.md: f_a's (kd, eta, alpha) of base colour `base`, `metallic` and
/// `roughness` (each in [0, 1]) with the factors' dielectric F0 and anisotropy strength. Double
/// inside, rounded once.
AnalyticParams gltf_fa(const Vec3<double>& base, double metallic, double roughness, const Vec3<double>& dielectric_f0,
                       double anisotropy);

/// The tangent-space normal glTF's normalTexture stores at one texel (linear RGB in [0, 1]), its
/// x and y scaled: normalize((2 rgb - 1) * (scale, scale, 1)); (0, 0, 1) when that is not finite
/// or zero.
Vec3<float> gltf_tangent_normal(const std::array<double, 4>& rgb, double scale);

/// A normal texture and its scale.
struct GltfNormalTexture {
    GltfTexture texture;
    double scale = 1.0;
    /// The shading frame at uv and ray-cone footprint (log2, uv units; the point footprint reads
    /// level 0) in the geometric frame's coordinates.
    ShadingFrame frame(const Vec2<float>& uv, float footprint = -std::numeric_limits<float>::infinity()) const;
};

/// An unbound glTF material whose textures vary over the surface: f_a of each hit's parameters.
class GltfMaterial final : public Material {
public:
    GltfMaterial(std::string name, const GltfFactors& factors, std::optional<GltfTexture> base_color,
                 std::optional<GltfTexture> metallic_roughness, std::optional<GltfNormalTexture> normal);
    /// At uv (0, 0).
    void eval(std::size_t n, const float* wi, const float* wo, float* f, EvalMode mode) const override;
    void eval_at(std::size_t n, const float* uv, const Footprint* footprint, const float* wi, const float* wo, float* f,
                 EvalMode mode) const override;
    BrdfSample sample_at(const Vec3f& wo, const Vec2<float>& u, const Vec2<float>& uv, const Footprint& footprint) const override;
    float pdf_at(const Vec3f& wi, const Vec3f& wo, const Vec2<float>& uv, const Footprint& footprint) const override;
    bool isotropic() const override { return isotropic_; }
    bool spatially_varying() const override { return true; }
    const char* type() const override { return "analytic"; }

    /// f_a's parameters at uv and footprint (the textures looked up at their level of detail,
    /// then the mapping).
    AnalyticParams params_at(const Vec2<float>& uv, float footprint = -std::numeric_limits<float>::infinity()) const;
    /// The parameters at uv (0, 0) of an untextured texel: the factors' f_a (the sampler's record).
    AnalyticParams factor_params() const;
    const GltfFactors& factors() const { return factors_; }
    const std::optional<GltfTexture>& base_color() const { return base_color_; }
    const std::optional<GltfTexture>& metallic_roughness() const { return metallic_roughness_; }
    const std::optional<GltfNormalTexture>& normal() const { return normal_; }

private:
    GltfFactors factors_;
    std::optional<GltfTexture> base_color_, metallic_roughness_;
    std::optional<GltfNormalTexture> normal_;
    bool isotropic_;
};

/// Another material seen through a glTF asset's normalTexture: wi, wo turned into the texel's
/// shading frame, f = 0 unless both are above both horizons (normal_map.hpp), then the inner
/// material at the same uv and footprint. Sampling draws from the inner material in the
/// shading frame. The inner material is another material of the same scene (not owned: the scene
/// sets its sampler and keeps it alive).
class NormalMappedMaterial final : public Material {
public:
    NormalMappedMaterial(std::string name, const Material* inner, GltfNormalTexture normal);
    void eval(std::size_t n, const float* wi, const float* wo, float* f, EvalMode mode) const override;
    void eval_at(std::size_t n, const float* uv, const Footprint* footprint, const float* wi, const float* wo, float* f,
                 EvalMode mode) const override;
    BrdfSample sample_at(const Vec3f& wo, const Vec2<float>& u, const Vec2<float>& uv, const Footprint& footprint) const override;
    float pdf_at(const Vec3f& wi, const Vec3f& wo, const Vec2<float>& uv, const Footprint& footprint) const override;
    bool has_analytic_part() const override { return inner_->has_analytic_part(); }
    bool uses_network(EvalMode mode) const override { return inner_->uses_network(mode); }
    bool isotropic() const override { return false; }
    bool spatially_varying() const override { return true; }
    const char* type() const override { return inner_->type(); }
    const Material& inner() const { return *inner_; }
    const GltfNormalTexture& normal() const { return normal_; }

private:
    const Material* inner_;
    GltfNormalTexture normal_;
};

}  // namespace hbrdf::render
