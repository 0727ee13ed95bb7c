// hybridbrdf — textured materials in memory: texel lookup and the layered evaluation
// (svbrdf.hpp; docs/SVBRDF.md). Python's hybridbrdf.svbrdf.asset does the same lookup.
#include "hybridbrdf/svbrdf.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace hbrdf {

struct Svbrdf::Taps {
    int n = 0;
    std::size_t index[4];  // texel index row * width + col
    double weight[4];
    std::size_t quad = 0;  // bilinear: the 2x2 block's index in Svbrdf::pure_quad_
    long x0 = 0, y0 = 0;   // bilinear: the block's corner, and the position in it
    double fx = 0.0, fy = 0.0;
};

namespace {

using Taps = Svbrdf::Taps;

// i is within one texel of [0, n) (uv was wrapped into [0, 1) or clamped first): no division.
HBRDF_INLINE long wrap_index(long i, long n, bool repeat) {
    if (repeat) return i < 0 ? i + n : i >= n ? i - n : i;
    return std::clamp(i, 0L, n - 1);
}

// floor() without the libm call a portable build makes of std::floor (no SSE4.1 roundsd): four
// per lookup were a third of a pure texel's cost. Doubles of magnitude 2^52 and above are integers.
HBRDF_INLINE double floor_fast(double x) {
    if (!(std::fabs(x) < 4503599627370496.0)) return x;
    const double t = double(static_cast<long long>(x));  // toward zero
    return t > x ? t - 1.0 : t;
}

// Where uv falls: the nearest texel, or the 2x2 block of bilinear taps (corner and position, not
// yet the four texels: spread_taps). Cheap enough to ask "one layer alone?" of every pair first.
HBRDF_INLINE Taps locate_taps(const Vec2<float>& uv_in, TexelFilter filter, int width, int height, TexelAddressing addressing) {
    const bool repeat = addressing == TexelAddressing::Repeat;
    // Non-finite uv (a degenerate hit) reads (0, 0); huge finite uv wrap in double without overflow.
    double u = std::isfinite(uv_in.x) ? double(uv_in.x) : 0.0, v = std::isfinite(uv_in.y) ? double(uv_in.y) : 0.0;
    if (repeat) u -= floor_fast(u), v -= floor_fast(v);  // in [0, 1): the index arithmetic stays small
    else u = std::clamp(u, 0.0, 1.0), v = std::clamp(v, 0.0, 1.0);
    Taps t;
    if (filter == TexelFilter::Nearest) {
        const long col = wrap_index(long(floor_fast(u * width)), width, repeat);
        const long row = wrap_index(long(floor_fast(v * height)), height, repeat);
        t.n = 1;
        t.index[0] = std::size_t(row) * std::size_t(width) + std::size_t(col);
        t.weight[0] = 1.0;
        return t;
    }
    const double x = u * width - 0.5, y = v * height - 0.5;
    const double x0 = floor_fast(x), y0 = floor_fast(y);  // in [-1, width) x [-1, height)
    t.n = 4;
    t.x0 = long(x0), t.y0 = long(y0);
    t.fx = x - x0, t.fy = y - y0;
    t.quad = std::size_t(t.y0 + 1) * std::size_t(width + 1) + std::size_t(t.x0 + 1);
    return t;
}

// The four texels of a located bilinear lookup and their weights.
void spread_taps(Taps& t, int width, int height, TexelAddressing addressing) {
    if (t.n == 1) return;
    const bool repeat = addressing == TexelAddressing::Repeat;
    int k = 0;
    for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx, ++k) {
            const long row = wrap_index(t.y0 + dy, height, repeat), col = wrap_index(t.x0 + dx, width, repeat);
            t.index[k] = std::size_t(row) * std::size_t(width) + std::size_t(col);
            t.weight[k] = (dx ? t.fx : 1.0 - t.fx) * (dy ? t.fy : 1.0 - t.fy);
        }
}

Taps taps_of(const Vec2<float>& uv, TexelFilter filter, int width, int height, TexelAddressing addressing) {
    Taps t = locate_taps(uv, filter, width, height, addressing);
    spread_taps(t, width, height, addressing);
    return t;
}

// The filtered value of `components` channels of a map (or the material's own value when the map is empty).
void sample_map(const std::vector<float>& map, int components, const Taps& t, const float* own, float* out) {
    if (map.empty()) {
        std::copy(own, own + components, out);
        return;
    }
    for (int c = 0; c < components; ++c) {
        double acc = 0.0;
        for (int k = 0; k < t.n; ++k) acc += double(map[t.index[k] * std::size_t(components) + std::size_t(c)]) * t.weight[k];
        out[c] = float(acc);
    }
}

void check_map(const std::vector<float>& map, std::size_t texels, int components, const char* what, int layer) {
    if (map.empty()) return;
    if (map.size() != texels * std::size_t(components))
        throw std::invalid_argument("layer " + std::to_string(layer) + " " + what + " map has " +
                                    std::to_string(map.size()) + " values, expected " +
                                    std::to_string(texels * std::size_t(components)));
    for (float v : map)
        if (!std::isfinite(v)) throw std::invalid_argument("layer " + std::to_string(layer) + " " + what + " map is not finite");
}

}  // namespace

Svbrdf::Svbrdf(std::shared_ptr<const HybridModel> model, int width, int height, TexelAddressing addressing,
               std::vector<SvbrdfLayer> layers, std::vector<float> weights)
    : model_(std::move(model)), width_(width), height_(height), addressing_(addressing), layers_(std::move(layers)),
      weights_(std::move(weights)) {
    if (!model_) throw std::invalid_argument("a textured material needs a model");
    if (!model_->arch().analytic) throw std::invalid_argument("a textured material needs a hybrid model (f_a per texel)");
    if (layers_.empty() || int(layers_.size()) > spec::kSvbrdfMaxLayers)
        throw std::invalid_argument("a textured material has 1 to " + std::to_string(spec::kSvbrdfMaxLayers) +
                                    " layers, got " + std::to_string(layers_.size()));
    if (width_ < 1 || height_ < 1 || width_ > spec::kSvbrdfMaxSide || height_ > spec::kSvbrdfMaxSide)
        throw std::invalid_argument("size must be 1 to " + std::to_string(spec::kSvbrdfMaxSide) + " texels a side");
    const std::size_t texels = std::size_t(width_) * std::size_t(height_);
    for (std::size_t k = 0; k < layers_.size(); ++k) {
        const SvbrdfLayer& l = layers_[k];
        if (l.material < 0 || std::size_t(l.material) >= model_->materials().size())
            throw std::invalid_argument("layer " + std::to_string(k) + ": material index out of range");
        check_map(l.kd, texels, 3, "kd", int(k));
        check_map(l.eta, texels, 3, "eta", int(k));
        check_map(l.alpha, texels, 2, "alpha", int(k));
        check_map(l.latent, texels, model_->latent_dim(), "latent", int(k));
    }
    if (layers_.size() > 1 && weights_.size() != texels * 3)
        throw std::invalid_argument("a textured material of several layers needs a weights map of width * height * 3 values");
    for (float v : weights_)
        if (!(v >= 0.f && v <= 1.f)) throw std::invalid_argument("weights must lie in [0, 1]");
    for (std::size_t k = 0; k < layers_.size(); ++k) {
        const SvbrdfLayer& l = layers_[k];
        plain_[k] = l.kd.empty() && l.eta.empty() && l.alpha.empty() && l.latent.empty();
    }
    // Exactly the normalisation of texel_at(): w_0 = 1 - sum (clamped), the others divided by the
    // sum above 1. A texel is pure in layer k when w_k is 1 and the others 0 after it.
    const int L = int(layers_.size());
    if (L > 1) {
        pure_layer_.resize(texels);
        for (std::size_t i = 0; i < texels; ++i) {
            double w[spec::kSvbrdfMaxLayers] = {0.0, 0.0, 0.0, 0.0}, total = 0.0;
            for (int c = 0; c < L - 1; ++c) total += w[c + 1] = double(weights_[i * 3 + std::size_t(c)]);
            if (total > 1.0)
                for (int c = 1; c < L; ++c) w[c] /= total;
            w[0] = std::clamp(1.0 - std::min(total, 1.0), 0.0, 1.0);
            int pure = -1, positive = 0;
            for (int k = 0; k < L; ++k)
                if (w[k] > 0.0) ++positive, pure = w[k] == 1.0 ? k : -1;
            pure_layer_[i] = static_cast<signed char>(positive == 1 ? pure : -1);
        }
        // The bilinear footprint's 2x2 blocks, corner (x0, y0) in [-1, width) x [-1, height) (the
        // taps' wrapping or clamping applied): one byte read per lookup says "one layer alone".
        const bool repeat = addressing_ == TexelAddressing::Repeat;
        pure_quad_.resize(std::size_t(width_ + 1) * std::size_t(height_ + 1));
        for (long y0 = -1; y0 < height_; ++y0)
            for (long x0 = -1; x0 < width_; ++x0) {
                int k = -2;
                for (int dy = 0; dy < 2; ++dy)
                    for (int dx = 0; dx < 2; ++dx) {
                        const long row = wrap_index(y0 + dy, height_, repeat), col = wrap_index(x0 + dx, width_, repeat);
                        const int p = pure_layer_[std::size_t(row) * std::size_t(width_) + std::size_t(col)];
                        k = k == -2 || k == p ? p : -1;
                    }
                pure_quad_[std::size_t(y0 + 1) * std::size_t(width_ + 1) + std::size_t(x0 + 1)] = static_cast<signed char>(k);
            }
    }
}

HBRDF_INLINE int Svbrdf::pure_layer_at(const Taps& t) const {
    if (pure_layer_.empty()) return 0;  // one layer: every texel is it
    return t.n == 1 ? pure_layer_[t.index[0]] : pure_quad_[t.quad];
}

void Svbrdf::texel(const Vec2<float>& uv, TexelFilter filter, Texel* out) const {
    texel_at(taps_of(uv, filter, width_, height_, addressing_), out);
}

void Svbrdf::normal_at(const Taps& t, Texel* out) const {
    out->has_normal = !normal_.empty();
    if (!out->has_normal) return;
    const float none[2] = {0.f, 0.f};
    float xy[2];
    sample_map(normal_, 2, t, none, xy);
    out->normal_xy = Vec2<float>(xy[0], xy[1]);
}

void Svbrdf::set_normal_map(std::vector<float> xy) {
    if (xy.size() != std::size_t(width_) * std::size_t(height_) * 2)
        throw std::invalid_argument("normal map has " + std::to_string(xy.size()) + " values, expected " +
                                    std::to_string(std::size_t(width_) * std::size_t(height_) * 2));
    for (float v : xy)
        if (!std::isfinite(v)) throw std::invalid_argument("normal map is not finite");
    normal_ = std::move(xy);
}

Vec3<float> Svbrdf::eval_texel(const Texel& t, const Vec3<float>& wi, const Vec3<float>& wo) const {
    if (!t.has_normal) return model_->eval_texel(t.layers, t.n_layers, wi, wo);
    const ShadingFrame s = t.frame();
    if (!above_both_horizons(s, wi, wo)) return Vec3<float>(0.f);
    return model_->eval_texel(t.layers, t.n_layers, s.to_local(wi), s.to_local(wo));
}

void Svbrdf::texel(const Vec2<float>& uv, TexelFilter filter, const float* weights, Texel* out) const {
    const Taps taps = taps_of(uv, filter, width_, height_, addressing_);
    const int L = int(layers_.size()), l = model_->latent_dim();
    double w[spec::kSvbrdfMaxLayers] = {1.0, 0.0, 0.0, 0.0}, total = 0.0;
    for (int c = 0; c + 1 < L; ++c) {
        const float v = weights[c];
        total += w[c + 1] = v > 0.f && std::isfinite(v) ? double(v) : 0.0;
    }
    if (total > 1.0)
        for (int c = 1; c < L; ++c) w[c] /= total;
    w[0] = std::clamp(1.0 - std::min(total, 1.0), 0.0, 1.0);
    out->n_layers = L;
    normal_at(taps, out);
    for (int k = 0; k < L; ++k) {
        TexelLayer& o = out->layers[k];
        float* latent = out->latent + std::size_t(k) * std::size_t(l);
        o.weight = float(w[k]);
        if (o.weight > 0.f) layer_at(taps, k, &o, latent);
        else o.material = layers_[std::size_t(k)].material, o.latent = latent;
    }
}

void Svbrdf::weights_at(const Taps& t, double* w) const {
    const int L = int(layers_.size());
    std::fill(w, w + spec::kSvbrdfMaxLayers, 0.0);
    // Taps all pure in one layer: that layer's weight is 1 exactly (interpolating 1s in double can
    // round to 1 - 1e-16 and leave a layer of weight 1e-16 to evaluate).
    if (const int pure = pure_layer_at(t); pure >= 0) {
        w[pure] = 1.0;
        return;
    }
    double total = 0.0;
    for (int c = 0; c < L - 1; ++c) {
        double acc = 0.0;
        for (int k = 0; k < t.n; ++k) acc += double(weights_[t.index[k] * 3 + std::size_t(c)]) * t.weight[k];
        w[c + 1] = acc;
        total += acc;
    }
    if (total > 1.0)
        for (int c = 1; c < L; ++c) w[c] /= total;
    w[0] = std::clamp(1.0 - std::min(total, 1.0), 0.0, 1.0);
}

void Svbrdf::layer_at(const Taps& t, int k, TexelLayer* o, float* latent) const {
    const SvbrdfLayer& layer = layers_[std::size_t(k)];
    const ModelMaterial& mat = model_->materials()[std::size_t(layer.material)];
    o->material = layer.material;
    o->latent = latent;
    float v[3];
    sample_map(layer.kd, 3, t, &mat.params.kd.x, v);
    o->params.kd = Vec3<float>(v[0], v[1], v[2]);
    sample_map(layer.eta, 3, t, &mat.params.eta.x, v);
    o->params.eta = Vec3<float>(v[0], v[1], v[2]);
    sample_map(layer.alpha, 2, t, &mat.params.alpha.x, v);
    o->params.alpha = Vec2<float>(v[0], v[1]);
    sample_map(layer.latent, model_->latent_dim(), t, mat.latent.data(), latent);
}

void Svbrdf::texel_at(const Taps& t, Texel* out, bool all_layers) const {
    const int L = int(layers_.size()), l = model_->latent_dim();
    out->n_layers = L;
    normal_at(t, out);
    double w[spec::kSvbrdfMaxLayers];
    weights_at(t, w);
    for (int k = 0; k < L; ++k) {
        TexelLayer& o = out->layers[k];
        float* latent = out->latent + std::size_t(k) * std::size_t(l);
        o.weight = float(w[k]);
        if (o.weight > 0.f || all_layers) layer_at(t, k, &o, latent);  // a layer of weight 0 is not evaluated: not read
        else o.material = layers_[std::size_t(k)].material, o.latent = latent;
    }
}

Vec3<float> Svbrdf::eval(const Vec2<float>& uv, TexelFilter filter, const Vec3<float>& wi, const Vec3<float>& wo) const {
    Texel t;
    texel(uv, filter, &t);
    return eval_texel(t, wi, wo);
}

void Svbrdf::set_mips(std::vector<std::shared_ptr<const Svbrdf>> levels) {
    if (levels.empty()) return mips_.clear();
    const auto pow2 = [](int n) { return n > 0 && (n & (n - 1)) == 0; };
    if (!pow2(width_) || !pow2(height_))
        throw std::invalid_argument("a mip chain needs power-of-two sides, the size is " + std::to_string(width_) + "x" +
                                    std::to_string(height_));
    int complete = 0;
    for (int side = std::max(width_, height_); side > 0; side >>= 1) ++complete;
    if (int(levels.size()) + 1 != complete)
        throw std::invalid_argument("a " + std::to_string(width_) + "x" + std::to_string(height_) + " material's mip chain has 1 or " +
                                    std::to_string(complete) + " levels (down to 1x1), got " + std::to_string(levels.size() + 1));
    for (std::size_t i = 0; i < levels.size(); ++i) {
        const Svbrdf* m = levels[i].get();
        const int L = int(i) + 1;
        bool same = m && m->model_ == model_ && m->addressing_ == addressing_ && m->layers_.size() == layers_.size() &&
                    m->width_ == std::max(1, width_ >> L) && m->height_ == std::max(1, height_ >> L) &&
                    m->weights_.empty() == weights_.empty() && m->normal_.empty() == normal_.empty() && m->mips_.empty();
        for (std::size_t k = 0; same && k < layers_.size(); ++k) {
            const SvbrdfLayer &a = layers_[k], &b = m->layers_[k];
            same = a.material == b.material && a.kd.empty() == b.kd.empty() && a.eta.empty() == b.eta.empty() &&
                   a.alpha.empty() == b.alpha.empty() && a.latent.empty() == b.latent.empty();
        }
        if (!same)
            throw std::invalid_argument("mip level " + std::to_string(L) + " must hold level 0's model, layers, addressing and maps at " +
                                        std::to_string(std::max(1, width_ >> L)) + "x" + std::to_string(std::max(1, height_ >> L)) + " texels");
    }
    mips_ = std::move(levels);
}

float Svbrdf::lod(const Vec2<float>& duv_dx, const Vec2<float>& duv_dy) const {
    const double ax = double(duv_dx.x) * width_, ay = double(duv_dx.y) * height_;
    const double bx = double(duv_dy.x) * width_, by = double(duv_dy.y) * height_;
    const double rho2 = std::max(ax * ax + ay * ay, bx * bx + by * by);
    return float(0.5 * std::log2(std::max(rho2, 1e-300)));
}

void Svbrdf::texel(const Vec2<float>& uv, TexelFilter filter, float lod, Texel* out) const {
    const int levels = level_count();
    if (!(lod > 0.f) || levels == 1) return texel(uv, filter, out);
    const double d = std::min(double(lod), double(levels - 1));
    const int fine = std::min(int(d), levels - 1);
    const double t = d - fine;
    const Svbrdf& a = level(fine);
    a.texel_at(taps_of(uv, filter, a.width_, a.height_, addressing_), out, true);
    if (t == 0.0 || fine + 1 >= levels) return;
    const Svbrdf& b = level(fine + 1);
    Texel next;
    b.texel_at(taps_of(uv, filter, b.width_, b.height_, addressing_), &next, true);
    const auto mix = [t](float x, float y) { return float(double(x) * (1.0 - t) + double(y) * t); };
    const std::size_t l = std::size_t(model_->latent_dim());
    out->normal_xy = Vec2<float>(mix(out->normal_xy.x, next.normal_xy.x), mix(out->normal_xy.y, next.normal_xy.y));
    for (int k = 0; k < out->n_layers; ++k) {
        TexelLayer &o = out->layers[k], &n = next.layers[k];
        o.weight = mix(o.weight, n.weight);
        for (int c = 0; c < 3; ++c) {
            o.params.kd[c] = mix(o.params.kd[c], n.params.kd[c]);
            o.params.eta[c] = mix(o.params.eta[c], n.params.eta[c]);
        }
        for (int c = 0; c < 2; ++c) o.params.alpha[c] = mix(o.params.alpha[c], n.params.alpha[c]);
        for (std::size_t c = 0; c < l; ++c) out->latent[std::size_t(k) * l + c] = mix(out->latent[std::size_t(k) * l + c], next.latent[std::size_t(k) * l + c]);
    }
}

AnisotropicProbes anisotropic_probes(const TexelFootprint& fp, int width, int height) {
    const double ax = double(fp.duv_dx.x) * width, ay = double(fp.duv_dx.y) * height;
    const double bx = double(fp.duv_dy.x) * width, by = double(fp.duv_dy.y) * height;
    double p_max = std::sqrt(ax * ax + ay * ay), p_min = std::sqrt(bx * bx + by * by);
    Vec2<float> major = fp.duv_dx;
    if (p_min > p_max) std::swap(p_max, p_min), major = fp.duv_dy;
    AnisotropicProbes out;
    if (!std::isfinite(p_max) || !std::isfinite(p_min)) {  // a degenerate hit: the coarsest level
        out.lod = std::numeric_limits<float>::infinity();
        return out;
    }
    const double count = std::clamp(std::ceil(p_max / std::max(p_min, 1.0)), 1.0, double(std::max(fp.max_probes, 1)));
    out.count = int(count);
    out.lod = float(std::log2(std::max(std::max(p_min, p_max / count), 1e-300)));
    out.step = Vec2<float>(float(double(major.x) / count), float(double(major.y) / count));
    return out;
}

void Svbrdf::texel(const Vec2<float>& uv, TexelFilter filter, const TexelFootprint& footprint, Texel* out) const {
    if (mips_.empty()) return texel(uv, filter, out);
    texel_probes(uv, filter, anisotropic_probes(footprint, width_, height_), out);
}

void Svbrdf::texel_probes(const Vec2<float>& uv, TexelFilter filter, const AnisotropicProbes& probes, Texel* out) const {
    if (probes.count <= 1) return texel(uv, filter, probes.lod, out);
    const int L = layer_count();
    const std::size_t l = std::size_t(model_->latent_dim());
    // Per layer: the sum of its weights, and of its values times the weight (kd 3, eta 3, sqrt
    // alpha 2, latent l), in double; the normal's x, y summed.
    double w_sum[spec::kSvbrdfMaxLayers] = {};
    double sums[spec::kSvbrdfMaxLayers * (8 + spec::kMaxLatent)] = {};
    double nx = 0.0, ny = 0.0;
    Texel t;
    for (int p = 0; p < probes.count; ++p) {
        const double s = (p + 0.5) - 0.5 * probes.count;  // probe offsets, in steps, symmetric about uv
        const Vec2<float> at(float(uv.x + s * probes.step.x), float(uv.y + s * probes.step.y));
        texel(at, filter, probes.lod, &t);
        nx += t.normal_xy.x, ny += t.normal_xy.y;
        for (int k = 0; k < L; ++k) {
            const TexelLayer& tl = t.layers[k];
            const double w = tl.weight;
            if (!(w > 0.0)) continue;
            w_sum[k] += w;
            double* v = &sums[std::size_t(k) * (8 + l)];
            for (int c = 0; c < 3; ++c) v[c] += w * tl.params.kd[c], v[3 + c] += w * tl.params.eta[c];
            for (int c = 0; c < 2; ++c) v[6 + c] += w * std::sqrt(double(tl.params.alpha[c]));
            for (std::size_t c = 0; c < l; ++c) v[8 + c] += w * t.latent[std::size_t(k) * l + c];
        }
    }
    const double inv = 1.0 / probes.count;
    *out = t;  // n_layers, materials, has_normal
    out->normal_xy = Vec2<float>(float(nx * inv), float(ny * inv));
    for (int k = 0; k < L; ++k) {
        TexelLayer& o = out->layers[k];
        o.material = layers_[std::size_t(k)].material;
        o.latent = out->latent + std::size_t(k) * l;
        o.weight = float(w_sum[k] * inv);
        if (!(w_sum[k] > 0.0)) continue;  // weight 0 over the footprint: not evaluated
        const double* v = &sums[std::size_t(k) * (8 + l)];
        const double iw = 1.0 / w_sum[k];
        for (int c = 0; c < 3; ++c) o.params.kd[c] = float(v[c] * iw), o.params.eta[c] = float(v[3 + c] * iw);
        for (int c = 0; c < 2; ++c) o.params.alpha[c] = float((v[6 + c] * iw) * (v[6 + c] * iw));
        for (std::size_t c = 0; c < l; ++c) out->latent[std::size_t(k) * l + c] = float(v[8 + c] * iw);
    }
}

Vec3<float> Svbrdf::eval(const Vec2<float>& uv, TexelFilter filter, float lod, const Vec3<float>& wi, const Vec3<float>& wo) const {
    Texel t;
    texel(uv, filter, lod, &t);
    return eval_texel(t, wi, wo);
}

Vec2<float> Svbrdf::normal_xy(const Vec2<float>& uv, TexelFilter filter, float lod) const {
    Texel t;  // only has_normal and normal_xy are written
    const int levels = level_count();
    const bool between = lod > 0.f && levels > 1;
    const double d = between ? std::min(double(lod), double(levels - 1)) : 0.0;
    const int fine = std::min(int(d), levels - 1);
    const Svbrdf& a = level(fine);
    a.normal_at(taps_of(uv, filter, a.width_, a.height_, addressing_), &t);
    const double frac = d - fine;
    if (!between || frac == 0.0 || fine + 1 >= levels) return t.normal_xy;
    const Svbrdf& b = level(fine + 1);
    Texel u;
    b.normal_at(taps_of(uv, filter, b.width_, b.height_, addressing_), &u);
    const auto mix = [frac](float x, float y) { return float(double(x) * (1.0 - frac) + double(y) * frac); };
    return Vec2<float>(mix(t.normal_xy.x, u.normal_xy.x), mix(t.normal_xy.y, u.normal_xy.y));
}

void Svbrdf::eval_batch(std::size_t n, const float* uv, const float* wi, const float* wo, TexelFilter filter,
                        float* f, const float* lod) const {
    eval_batch_any(n, uv, wi, wo, filter, f, lod, nullptr);
}

void Svbrdf::eval_batch_footprints(std::size_t n, const float* uv, const float* wi, const float* wo, TexelFilter filter,
                                   float* f, const TexelFootprint* footprints) const {
    if (mips_.empty()) footprints = nullptr;  // no chain: level 0 everywhere
    eval_batch_any(n, uv, wi, wo, filter, f, nullptr, footprints);
}

void Svbrdf::eval_batch_any(std::size_t n, const float* uv, const float* wi, const float* wo, TexelFilter filter,
                            float* f, const float* lod, const TexelFootprint* footprints) const {
    if (normal_.empty()) return eval_batch_local(n, uv, wi, wo, filter, f, lod, footprints);
    // A normal map: every pair's directions into its texel's shading frame first (the same lookup
    // and arithmetic as texel() and eval_texel()), then the batched layers; the rule zeroes after.
    thread_local std::vector<float> rot_i, rot_o;
    thread_local std::vector<unsigned char> visible;
    rot_i.resize(3 * n), rot_o.resize(3 * n), visible.resize(n);
    const bool mips = lod && !mips_.empty();
    Texel probed;  // the anisotropic lookup's normal: the mean of its probes'
    for (std::size_t i = 0; i < n; ++i) {
        const Vec2<float> at(uv[2 * i], uv[2 * i + 1]);
        if (footprints) texel(at, filter, footprints[i], &probed);
        const Vec2<float> xy = footprints ? probed.normal_xy : normal_xy(at, filter, mips ? lod[i] : 0.f);
        const ShadingFrame s = shading_frame(tangent_normal(xy.x, xy.y));
        const Vec3<float> a(wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]), b(wo[3 * i], wo[3 * i + 1], wo[3 * i + 2]);
        visible[i] = above_both_horizons(s, a, b);
        const Vec3<float> la = s.to_local(a), lb = s.to_local(b);
        for (int c = 0; c < 3; ++c) rot_i[3 * i + std::size_t(c)] = la[c], rot_o[3 * i + std::size_t(c)] = lb[c];
    }
    eval_batch_local(n, uv, rot_i.data(), rot_o.data(), filter, f, lod, footprints);
    for (std::size_t i = 0; i < n; ++i)
        if (!visible[i]) std::fill(f + 3 * i, f + 3 * i + 3, 0.f);
}

void Svbrdf::eval_batch_local(std::size_t n, const float* uv, const float* wi, const float* wo, TexelFilter filter,
                              float* f, const float* lod, const TexelFootprint* footprints) const {
    const int L = layer_count();
    const std::size_t l = std::size_t(model_->latent_dim());
    // Per layer, the pairs where it has positive weight, and for a layer with maps its texel values
    // there. The buffers are the thread's own and kept between calls: a tracer calls this once per
    // bounce and material, and fresh pages from the kernel cost more than the lookups.
    struct LayerPairs {
        std::vector<std::uint32_t> pair;
        std::vector<float> weight;
        std::vector<TexelLayer> values;  // layers with maps only
        std::vector<float> latent;
    };
    thread_local LayerPairs lists[spec::kSvbrdfMaxLayers];
    thread_local std::vector<float> dir_i, dir_o, out;
    // Consecutive pairs pure in one plain layer (a renderer's tile in texture order, a region of
    // one layer) are evaluated where they lie, by the layer material's kernel writing f: no copies.
    // Whole kernel chunks of a run go there; the rest of the run (a partial chunk would idle lanes)
    // joins the layer's list like any other pair.
    constexpr std::size_t kChunk = HybridModel::kBatchChunk;
    thread_local std::vector<std::size_t> runs;  // (first pair, count, layer) triples
    runs.clear();
    for (LayerPairs& p : lists) p.pair.clear(), p.weight.clear(), p.values.clear(), p.latent.clear();
    std::size_t run_start = 0;
    int run_layer = -1;
    auto close_run = [&](std::size_t end) {
        if (run_layer < 0) return;
        const std::size_t in_place = (end - run_start) / kChunk * kChunk;
        if (in_place) runs.insert(runs.end(), {run_start, in_place, std::size_t(run_layer)});
        for (std::size_t i = run_start + in_place; i < end; ++i) {
            lists[run_layer].pair.push_back(std::uint32_t(i));
            lists[run_layer].weight.push_back(1.f);
        }
        run_layer = -1;
    };
    double w[spec::kSvbrdfMaxLayers];
    if (mips_.empty()) lod = nullptr, footprints = nullptr;
    Texel trilinear;
    for (std::size_t i = 0; i < n; ++i) {
        // Several probes, or one between two levels: every layer of positive weight, its values.
        // One probe at lod <= 0 is level 0 at uv: the path below, bit for bit.
        const AnisotropicProbes probes = footprints ? anisotropic_probes(footprints[i], width_, height_) : AnisotropicProbes{};
        if (footprints ? probes.count > 1 || probes.lod > 0.f : lod && lod[i] > 0.f) {
            close_run(i);
            if (footprints) texel_probes(Vec2<float>(uv[2 * i], uv[2 * i + 1]), filter, probes, &trilinear);
            else texel(Vec2<float>(uv[2 * i], uv[2 * i + 1]), filter, lod[i], &trilinear);
            for (int k = 0; k < L; ++k) {
                const TexelLayer& tl = trilinear.layers[k];
                if (!(tl.weight > 0.f)) continue;
                LayerPairs& lp = lists[k];
                lp.pair.push_back(std::uint32_t(i));
                lp.weight.push_back(tl.weight);
                if (plain_[k]) continue;
                lp.values.push_back(tl);
                lp.latent.insert(lp.latent.end(), trilinear.latent + std::size_t(k) * l, trilinear.latent + std::size_t(k + 1) * l);
            }
            continue;
        }
        Taps taps = locate_taps(Vec2<float>(uv[2 * i], uv[2 * i + 1]), filter, width_, height_, addressing_);
        if (const int k = pure_layer_at(taps); k >= 0 && plain_[k]) {  // one layer alone, its material's values
            if (k != run_layer) close_run(i), run_start = i, run_layer = k;
            continue;
        }
        close_run(i);
        spread_taps(taps, width_, height_, addressing_);
        weights_at(taps, w);
        for (int k = 0; k < L; ++k) {
            const float wk = float(w[k]);
            if (!(wk > 0.f)) continue;
            LayerPairs& lp = lists[k];
            lp.pair.push_back(std::uint32_t(i));
            lp.weight.push_back(wk);
            if (plain_[k]) continue;
            lp.values.emplace_back();
            lp.latent.resize(lp.latent.size() + l);
            layer_at(taps, k, &lp.values.back(), lp.latent.data() + lp.latent.size() - l);  // pointer set again below
        }
    }
    close_run(n);
    for (std::size_t r = 0; r < runs.size(); r += 3)
        model_->eval_batch(layers_[runs[r + 2]].material, runs[r + 1], wi + 3 * runs[r], wo + 3 * runs[r], f + 3 * runs[r]);
    for (const LayerPairs& lp : lists)
        for (std::uint32_t p : lp.pair) std::fill(f + 3 * std::size_t(p), f + 3 * std::size_t(p) + 3, 0.f);
    // Layer by layer, in layer order (the scalar path's sum order): a layer without maps is its
    // material at every pair, the uniform kernel with the latent code folded into the first layer's
    // bias; a layer with maps runs the kernels with per-lane p and latent code. One material per
    // call either way: no sorting.
    for (int k = 0; k < L; ++k) {
        LayerPairs& lp = lists[k];
        const std::size_t m = lp.pair.size();
        if (m == 0) continue;
        const float* di = wi;
        const float* dw = wo;
        if (m != n) {
            dir_i.resize(3 * m), dir_o.resize(3 * m);
            for (std::size_t r = 0; r < m; ++r) {
                std::copy(wi + 3 * lp.pair[r], wi + 3 * lp.pair[r] + 3, &dir_i[3 * r]);
                std::copy(wo + 3 * lp.pair[r], wo + 3 * lp.pair[r] + 3, &dir_o[3 * r]);
            }
            di = dir_i.data(), dw = dir_o.data();
        }
        out.resize(3 * m);
        if (plain_[k]) {
            model_->eval_batch(layers_[std::size_t(k)].material, m, di, dw, out.data());
        } else {
            for (std::size_t r = 0; r < m; ++r) lp.values[r].latent = &lp.latent[r * l];
            model_->eval_batch_layers(m, di, dw, lp.values.data(), out.data());
        }
        for (std::size_t r = 0; r < m; ++r) {
            float* fp = f + 3 * std::size_t(lp.pair[r]);
            for (int c = 0; c < 3; ++c) fp[c] = fp[c] + out[3 * r + std::size_t(c)] * lp.weight[r];
        }
    }
}

Vec3<float> Svbrdf::eval_analytic(const Texel& t, const Vec3<float>& wi_g, const Vec3<float>& wo_g) {
    const ShadingFrame s = t.frame();
    if (t.has_normal && !above_both_horizons(s, wi_g, wo_g)) return Vec3<float>(0.f);
    const Vec3<float> wi = t.has_normal ? s.to_local(wi_g) : wi_g, wo = t.has_normal ? s.to_local(wo_g) : wo_g;
    Vec3<float> f(0.f);
    for (int k = 0; k < t.n_layers; ++k)
        if (t.layers[k].weight > 0.f) f = f + AnalyticBrdf(t.layers[k].params).eval(wi, wo) * t.layers[k].weight;
    return f;
}

Vec3<float> Svbrdf::eval_analytic(const Vec2<float>& uv, TexelFilter filter, const Vec3<float>& wi,
                                  const Vec3<float>& wo) const {
    Texel t;
    texel(uv, filter, &t);
    return eval_analytic(t, wi, wo);
}

BrdfSample Svbrdf::sample(const Texel& t, Strategy s, const Vec3<float>& wo_g, const Vec2<float>& u_in) {
    if (t.has_normal) {  // drawn in the shading frame, returned in the geometric one; rotations keep solid angle
        const ShadingFrame fr = t.frame();
        Texel flat = t;
        flat.has_normal = false;
        BrdfSample b = sample(flat, s, fr.to_local(wo_g), u_in);
        b.wi = fr.to_world(b.wi);
        if (!above_both_horizons(fr, b.wi, wo_g)) b.pdf = 0.f;
        return b;
    }
    const Vec3<float>& wo = wo_g;
    Vec2<float> u = clamp_unit_square(u_in);
    int chosen = 0;
    float start = 0.f, chosen_start = 0.f;
    for (int k = 0; k < t.n_layers; ++k) {  // the layer whose weight interval holds u.x (the last positive one past 1)
        const float w = t.layers[k].weight;
        if (!(w > 0.f)) continue;
        chosen = k;
        chosen_start = start;
        if (u.x < start + w) break;
        start += w;
    }
    const float wc = t.layers[chosen].weight;
    u.x = clamp_nan_lo(wc > 0.f ? (u.x - chosen_start) / wc : u.x, 0.f, kOneMinusEps<float>);
    BrdfSample b = hbrdf::sample(s, AnalyticBrdf(t.layers[chosen].params), wo, u);
    if (!(b.pdf > 0.f)) return b;
    b.pdf = pdf(t, s, b.wi, wo);
    b.weight = Vec3<float>(0.f);  // the integrator evaluates the texel itself
    return b;
}

BrdfSample Svbrdf::sample(const Vec2<float>& uv, TexelFilter filter, Strategy s, const Vec3<float>& wo,
                          const Vec2<float>& u) const {
    Texel t;
    texel(uv, filter, &t);
    return sample(t, s, wo, u);
}

float Svbrdf::pdf(const Texel& t, Strategy s, const Vec3<float>& wi_g, const Vec3<float>& wo_g) {
    const ShadingFrame fr = t.frame();
    if (t.has_normal && !above_both_horizons(fr, wi_g, wo_g)) return 0.f;
    const Vec3<float> wi = t.has_normal ? fr.to_local(wi_g) : wi_g, wo = t.has_normal ? fr.to_local(wo_g) : wo_g;
    float pdf = 0.f;
    for (int k = 0; k < t.n_layers; ++k)
        if (t.layers[k].weight > 0.f) pdf += t.layers[k].weight * hbrdf::pdf(s, AnalyticBrdf(t.layers[k].params), wi, wo);
    return pdf;
}

float Svbrdf::pdf(const Vec2<float>& uv, TexelFilter filter, Strategy s, const Vec3<float>& wi,
                  const Vec3<float>& wo) const {
    Texel t;
    texel(uv, filter, &t);
    return pdf(t, s, wi, wo);
}

}  // namespace hbrdf
