// hybridbrdf renderer — glTF materials with their own textures (gltf_material.hpp).
#include "hybridbrdf/render/gltf_material.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "hybridbrdf/analytic.hpp"
#include "hybridbrdf/params.hpp"
#include "hybridbrdf/render/ray_cone.hpp"

namespace hbrdf::render {

int wrap_texel(int i, int size, GltfWrap wrap) {
    switch (wrap) {
        case GltfWrap::ClampToEdge: return std::clamp(i, 0, size - 1);
        case GltfWrap::MirroredRepeat: {
            const int period = 2 * size;
            int m = i % period;
            if (m < 0) m += period;
            return m < size ? m : period - 1 - m;
        }
        default: {
            const int m = i % size;
            return m < 0 ? m + size : m;
        }
    }
}

double srgb_to_linear(double x) { return x <= 0.04045 ? x / 12.92 : std::pow((x + 0.055) / 1.055, 2.4); }

double linear_to_srgb(double x) { return x <= 0.0031308 ? x * 12.92 : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055; }

namespace {

// One level's filtered RGBA at uv: the texel under it (`nearest`) or the bilinear mix of the four
// around it, each decoded (sRGB first: the texture unit's order, Vulkan 1.3, 16.3.2 before 16.7).
std::array<double, 4> sample_level(const GltfImage& im, const GltfTexture& t, double u, double v, bool nearest) {
    auto texel = [&](int x, int y) {
        const unsigned char* p = &im.rgba[(std::size_t(y) * std::size_t(im.width) + std::size_t(x)) * 4];
        std::array<double, 4> out;
        for (int c = 0; c < 4; ++c) out[c] = p[c] / 255.0;
        if (t.srgb)
            for (int c = 0; c < 3; ++c) out[c] = srgb_to_linear(out[c]);
        return out;
    };
    // Far-away uv would lose the fraction in int: repeat modes are periodic, clamp saturates.
    const double su = u * im.width, sv = v * im.height;
    const double lim = 1 << 30;
    if (nearest) {
        const int x = int(std::floor(std::clamp(su, -lim, lim))), y = int(std::floor(std::clamp(sv, -lim, lim)));
        return texel(wrap_texel(x, im.width, t.wrap_s), wrap_texel(y, im.height, t.wrap_t));
    }
    const double fx = std::clamp(su - 0.5, -lim, lim), fy = std::clamp(sv - 0.5, -lim, lim);
    const double x0 = std::floor(fx), y0 = std::floor(fy), ax = fx - x0, ay = fy - y0;
    const int xa = wrap_texel(int(x0), im.width, t.wrap_s), xb = wrap_texel(int(x0) + 1, im.width, t.wrap_s);
    const int ya = wrap_texel(int(y0), im.height, t.wrap_t), yb = wrap_texel(int(y0) + 1, im.height, t.wrap_t);
    const auto t00 = texel(xa, ya), t10 = texel(xb, ya), t01 = texel(xa, yb), t11 = texel(xb, yb);
    std::array<double, 4> out;
    for (int c = 0; c < 4; ++c)
        out[c] = (t00[c] * (1 - ax) + t10[c] * ax) * (1 - ay) + (t01[c] * (1 - ax) + t11[c] * ax) * ay;
    return out;
}

}  // namespace

double GltfTexture::texels_log2() const { return 0.5 * std::log2(double(image->width) * double(image->height)); }

std::array<double, 4> GltfTexture::sample(double u, double v, double lod) const {
    if (!std::isfinite(u) || !std::isfinite(v)) u = v = 0.0;
    if (!(lod > 0.0)) return sample_level(*image, *this, u, v, nearest);  // magnified (or NaN): magFilter
    const int m = min_filter;
    const bool in_level_nearest = m == 9728 || m == 9984 || m == 9986;
    const int top = gltf_mipmapped(m) && mips ? int(mips->size()) : 0;  // the last level
    auto level = [&](int l) -> const GltfImage& { return l == 0 ? *image : (*mips)[std::size_t(l - 1)]; };
    const double lambda = std::min(lod, double(top));
    if (top == 0) return sample_level(*image, *this, u, v, in_level_nearest);
    if (m == 9984 || m == 9985)  // mipmap NEAREST: d = ceil(lambda + 1/2) - 1 (Vulkan 1.3, 16.6.1)
        return sample_level(level(int(std::ceil(lambda + 0.5)) - 1), *this, u, v, in_level_nearest);
    const int d = std::min(int(std::floor(lambda)), top);
    const double frac = lambda - d;
    const auto lo = sample_level(level(d), *this, u, v, in_level_nearest);
    if (d == top || frac == 0.0) return lo;
    const auto hi = sample_level(level(d + 1), *this, u, v, in_level_nearest);
    std::array<double, 4> out;
    for (int c = 0; c < 4; ++c) out[c] = lo[c] * (1.0 - frac) + hi[c] * frac;
    return out;
}

AnalyticParams gltf_fa(const Vec3<double>& base, double metallic, double roughness, const Vec3<double>& dielectric_f0,
                       double anisotropy) {
    AnalyticParams p;
    for (int c = 0; c < 3; ++c) {
        // F0 near 1 makes (1 + sqrt F0) / (1 - sqrt F0) steep: double, rounded once.
        const double f0 = std::clamp(dielectric_f0[c] * (1.0 - metallic) + base[c] * metallic, 0.0, 1.0);
        const double s = std::sqrt(f0);
        p.kd[c] = float(std::clamp(base[c] * (1.0 - metallic), 0.0, 1.0));
        p.eta[c] = float(s < 1.0 ? std::clamp((1.0 + s) / (1.0 - s), kEtaMin, kEtaMax) : kEtaMax);
    }
    const double alpha = roughness * roughness, s2 = anisotropy * anisotropy;
    p.alpha.x = float(std::clamp(alpha * (1.0 - s2) + s2, kAlphaMin, kAlphaMax));
    p.alpha.y = float(std::clamp(alpha, kAlphaMin, kAlphaMax));
    return p;
}

Vec3<float> gltf_tangent_normal(const std::array<double, 4>& rgb, double scale) {
    const double x = (2.0 * rgb[0] - 1.0) * scale, y = (2.0 * rgb[1] - 1.0) * scale, z = 2.0 * rgb[2] - 1.0;
    const double len = std::sqrt(x * x + y * y + z * z);
    if (!(len > 0.0) || !std::isfinite(len)) return Vec3<float>(0.f, 0.f, 1.f);
    return Vec3<float>(float(x / len), float(y / len), float(z / len));
}

ShadingFrame GltfNormalTexture::frame(const Vec2<float>& uv, float footprint) const {
    return shading_frame(gltf_tangent_normal(texture.sample(uv.x, uv.y, texture.lod(footprint)), scale));
}

// ---- GltfMaterial ------------------------------------------------------------------------------

GltfMaterial::GltfMaterial(std::string name, const GltfFactors& factors, std::optional<GltfTexture> base_color,
                           std::optional<GltfTexture> metallic_roughness, std::optional<GltfNormalTexture> normal)
    : Material(std::move(name)), factors_(factors), base_color_(std::move(base_color)),
      metallic_roughness_(std::move(metallic_roughness)), normal_(std::move(normal)) {
    for (const auto* t : {base_color_ ? &base_color_->image : nullptr, metallic_roughness_ ? &metallic_roughness_->image : nullptr,
                          normal_ ? &normal_->texture.image : nullptr})
        if (t && (!*t || (*t)->width < 1 || (*t)->height < 1 ||
                  (*t)->rgba.size() != std::size_t((*t)->width) * std::size_t((*t)->height) * 4))
            throw std::invalid_argument("a glTF texture without its decoded image");
    isotropic_ = !normal_ && factors_.anisotropy == 0.0;
}

AnalyticParams GltfMaterial::factor_params() const {
    return gltf_fa(factors_.base, factors_.metallic, factors_.roughness, factors_.dielectric_f0, factors_.anisotropy);
}

AnalyticParams GltfMaterial::params_at(const Vec2<float>& uv, float footprint) const {
    Vec3<double> base = factors_.base;
    double metallic = factors_.metallic, roughness = factors_.roughness;
    if (base_color_) {
        const auto t = base_color_->sample(uv.x, uv.y, base_color_->lod(footprint));
        for (int c = 0; c < 3; ++c) base[c] *= t[c];
    }
    if (metallic_roughness_) {  // glTF: G roughness, B metallic (linear)
        const auto t = metallic_roughness_->sample(uv.x, uv.y, metallic_roughness_->lod(footprint));
        roughness *= t[1];
        metallic *= t[2];
    }
    return gltf_fa(base, metallic, roughness, factors_.dielectric_f0, factors_.anisotropy);
}

void GltfMaterial::eval(std::size_t n, const float* wi, const float* wo, float* f, EvalMode mode) const {
    const std::vector<float> uv(2 * n, 0.0f);
    eval_at(n, uv.data(), nullptr, wi, wo, f, mode);
}

void GltfMaterial::eval_at(std::size_t n, const float* uv, const Footprint* footprint, const float* wi, const float* wo,
                           float* f, EvalMode) const {
    for (std::size_t i = 0; i < n; ++i) {
        const Vec2<float> at(uv[2 * i], uv[2 * i + 1]);
        const float fp = footprint ? footprint[i].cone_log2 : kPointFootprint;  // glTF textures: the cone's lod
        Vec3f a(wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]), b(wo[3 * i], wo[3 * i + 1], wo[3 * i + 2]);
        Vec3f v(0.0f);
        bool above = true;
        if (normal_) {
            const ShadingFrame s = normal_->frame(at, fp);
            above = above_both_horizons(s, a, b);
            a = s.to_local(a), b = s.to_local(b);
        }
        if (above) v = AnalyticBrdf(params_at(at, fp)).eval(a, b);
        f[3 * i] = v.x, f[3 * i + 1] = v.y, f[3 * i + 2] = v.z;
    }
}

BrdfSample GltfMaterial::sample_at(const Vec3f& wo, const Vec2<float>& u, const Vec2<float>& uv, const Footprint& footprint) const {
    const std::optional<Strategy> s = sampler_strategy(sampler_kind());
    const AnalyticBrdf proxy(params_at(uv, footprint.cone_log2));
    if (!normal_) return hbrdf::sample(s ? *s : Strategy::Cosine, proxy, wo, u);
    const ShadingFrame fr = normal_->frame(uv, footprint.cone_log2);  // drawn in the shading frame; rotations keep solid angle
    BrdfSample b = hbrdf::sample(s ? *s : Strategy::Cosine, proxy, fr.to_local(wo), u);
    b.wi = fr.to_world(b.wi);
    if (!above_both_horizons(fr, b.wi, wo)) b.pdf = 0.f;
    return b;
}

float GltfMaterial::pdf_at(const Vec3f& wi, const Vec3f& wo, const Vec2<float>& uv, const Footprint& footprint) const {
    const std::optional<Strategy> s = sampler_strategy(sampler_kind());
    const AnalyticBrdf proxy(params_at(uv, footprint.cone_log2));
    if (!normal_) return hbrdf::pdf(s ? *s : Strategy::Cosine, proxy, wi, wo);
    const ShadingFrame fr = normal_->frame(uv, footprint.cone_log2);
    if (!above_both_horizons(fr, wi, wo)) return 0.f;
    return hbrdf::pdf(s ? *s : Strategy::Cosine, proxy, fr.to_local(wi), fr.to_local(wo));
}

// ---- NormalMappedMaterial ----------------------------------------------------------------------

NormalMappedMaterial::NormalMappedMaterial(std::string name, const Material* inner, GltfNormalTexture normal)
    : Material(std::move(name)), inner_(inner), normal_(std::move(normal)) {
    if (!inner_ || !normal_.texture.image) throw std::invalid_argument("a normal-mapped material needs its material and map");
}

void NormalMappedMaterial::eval(std::size_t n, const float* wi, const float* wo, float* f, EvalMode mode) const {
    const std::vector<float> uv(2 * n, 0.0f);
    eval_at(n, uv.data(), nullptr, wi, wo, f, mode);
}

void NormalMappedMaterial::eval_at(std::size_t n, const float* uv, const Footprint* footprint, const float* wi,
                                   const float* wo, float* f, EvalMode mode) const {
    // Every pair turned into its texel's shading frame, then one batch to the inner material (its
    // network runs batched); pairs below a horizon evaluate there too and are zeroed after.
    std::vector<float> a(3 * n), b(3 * n);
    std::vector<char> above(n);
    for (std::size_t i = 0; i < n; ++i) {
        const ShadingFrame s = normal_.frame(Vec2<float>(uv[2 * i], uv[2 * i + 1]), footprint ? footprint[i].cone_log2 : kPointFootprint);
        const Vec3f x(wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]), y(wo[3 * i], wo[3 * i + 1], wo[3 * i + 2]);
        above[i] = above_both_horizons(s, x, y);
        const Vec3f xs = s.to_local(x), ys = s.to_local(y);
        for (int c = 0; c < 3; ++c) a[3 * i + std::size_t(c)] = xs[c], b[3 * i + std::size_t(c)] = ys[c];
    }
    inner_->eval_at(n, uv, footprint, a.data(), b.data(), f, mode);
    for (std::size_t i = 0; i < n; ++i)
        if (!above[i]) f[3 * i] = f[3 * i + 1] = f[3 * i + 2] = 0.0f;
}

BrdfSample NormalMappedMaterial::sample_at(const Vec3f& wo, const Vec2<float>& u, const Vec2<float>& uv, const Footprint& footprint) const {
    const ShadingFrame fr = normal_.frame(uv, footprint.cone_log2);
    BrdfSample b = inner_->sample_at(fr.to_local(wo), u, uv, footprint);
    b.wi = fr.to_world(b.wi);
    if (!above_both_horizons(fr, b.wi, wo)) b.pdf = 0.f;
    return b;
}

float NormalMappedMaterial::pdf_at(const Vec3f& wi, const Vec3f& wo, const Vec2<float>& uv, const Footprint& footprint) const {
    const ShadingFrame fr = normal_.frame(uv, footprint.cone_log2);
    if (!above_both_horizons(fr, wi, wo)) return 0.f;
    return inner_->pdf_at(fr.to_local(wi), fr.to_local(wo), uv, footprint);
}

}  // namespace hbrdf::render
