// hybridbrdf renderer — a glTF 2.0 material with its own textures (docs/GLTF.md, "Textures").
//
// An unbound glTF material renders as f_a whose parameters come, per hit, from its factors times
// its textures through the mapping of docs/GLTF.md ("The mapping"):
//   baseColor = baseColorFactor * baseColorTexture (sRGB decoded to linear per texel, then filtered)
//   metallic  = metallicFactor  * metallicRoughnessTexture.B (linear)
//   roughness = roughnessFactor * metallicRoughnessTexture.G (linear)
// each texture read at TEXCOORD_0 through its sampler (wrap S and T: REPEAT, CLAMP_TO_EDGE,
// MIRRORED_REPEAT; magFilter NEAREST or LINEAR; level 0 only: the tracer builds no mip chain for
// glTF images). A normalTexture tilts the shading frame: n_t = normalize((2 rgb - 1) (scale, scale,
// 1)) in the geometric frame (t = +x, b = n x t = +y, n = +z; glTF's +Y up in the image with
// w = +1), then normal_map.hpp's frame and horizon rule, as a textured folder's normal map.
// A glTF material bound to another material keeps the asset's normalTexture through
// NormalMappedMaterial (unless the bound textured folder has a normal map of its own).
#pragma once

#include <array>
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

/// A glTF texture as one material slot reads it: its image and its sampler.
struct GltfTexture {
    std::shared_ptr<const GltfImage> image;
    GltfWrap wrap_s = GltfWrap::Repeat, wrap_t = GltfWrap::Repeat;
    bool nearest = false;   ///< magFilter NEAREST (9728): the texel under uv; otherwise bilinear
    int min_filter = 9987;  ///< glTF minFilter (the raster frame's mip chain; the tracer reads level 0)
    bool srgb = false;      ///< the texel's RGB is sRGB-encoded (baseColorTexture): decoded before filtering

    /// The filtered RGBA at uv in [0, 1] (double; sRGB decoded when `srgb`; alpha always linear).
    /// A non-finite uv reads (0, 0).
    std::array<double, 4> sample(double u, double v) const;
};

/// The texel index that `wrap` gives integer coordinate i on a side of `size` texels (Vulkan's
/// addressing: repeat i mod size, clamp to [0, size - 1], mirrored repeat of period 2 size).
int wrap_texel(int i, int size, GltfWrap wrap);

/// sRGB's electro-optical transfer function (IEC 61966-2-1), x in [0, 1].
double srgb_to_linear(double x);

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
    /// The shading frame at uv in the geometric frame's coordinates.
    ShadingFrame frame(const Vec2<float>& uv) const;
};

/// An unbound glTF material whose textures vary over the surface: f_a of each hit's parameters.
class GltfMaterial final : public Material {
public:
    GltfMaterial(std::string name, const GltfFactors& factors, std::optional<GltfTexture> base_color,
                 std::optional<GltfTexture> metallic_roughness, std::optional<GltfNormalTexture> normal);
    /// At uv (0, 0).
    void eval(std::size_t n, const float* wi, const float* wo, float* f, EvalMode mode) const override;
    void eval_at(std::size_t n, const float* uv, const float* footprint, const float* wi, const float* wo, float* f,
                 EvalMode mode) const override;
    BrdfSample sample_at(const Vec3f& wo, const Vec2<float>& u, const Vec2<float>& uv, float footprint) const override;
    float pdf_at(const Vec3f& wi, const Vec3f& wo, const Vec2<float>& uv, float footprint) const override;
    bool isotropic() const override { return isotropic_; }
    bool spatially_varying() const override { return true; }
    const char* type() const override { return "analytic"; }

    /// f_a's parameters at uv (the textures looked up, then the mapping).
    AnalyticParams params_at(const Vec2<float>& uv) const;
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
    void eval_at(std::size_t n, const float* uv, const float* footprint, const float* wi, const float* wo, float* f,
                 EvalMode mode) const override;
    BrdfSample sample_at(const Vec3f& wo, const Vec2<float>& u, const Vec2<float>& uv, float footprint) const override;
    float pdf_at(const Vec3f& wi, const Vec3f& wo, const Vec2<float>& uv, float footprint) const override;
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
