// hybridbrdf — textured materials in memory: texel lookup and the layered evaluation
// (svbrdf.hpp; docs/SVBRDF.md). Python's hybridbrdf.svbrdf.asset does the same lookup.
#include "hybridbrdf/svbrdf.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <cstdint>
#include <string>
#include <vector>

namespace hbrdf {

namespace {

struct Taps {
    int n = 0;
    std::size_t index[4];  // texel index row * width + col
    double weight[4];
};

// i is within one texel of [0, n) (uv was wrapped into [0, 1) or clamped first): no division.
long wrap_index(long i, long n, bool repeat) {
    if (repeat) return i < 0 ? i + n : i >= n ? i - n : i;
    return std::clamp(i, 0L, n - 1);
}

Taps taps_of(const Vec2<float>& uv_in, TexelFilter filter, int width, int height, TexelAddressing addressing) {
    const bool repeat = addressing == TexelAddressing::Repeat;
    // Non-finite uv (a degenerate hit) reads (0, 0); huge finite uv wrap in double without overflow.
    double u = std::isfinite(uv_in.x) ? double(uv_in.x) : 0.0, v = std::isfinite(uv_in.y) ? double(uv_in.y) : 0.0;
    if (repeat) u -= std::floor(u), v -= std::floor(v);  // in [0, 1): the index arithmetic stays small
    else u = std::clamp(u, 0.0, 1.0), v = std::clamp(v, 0.0, 1.0);
    Taps t;
    if (filter == TexelFilter::Nearest) {
        const long col = wrap_index(long(std::floor(u * width)), width, repeat);
        const long row = wrap_index(long(std::floor(v * height)), height, repeat);
        t.n = 1;
        t.index[0] = std::size_t(row) * std::size_t(width) + std::size_t(col);
        t.weight[0] = 1.0;
        return t;
    }
    const double x = u * width - 0.5, y = v * height - 0.5;
    const double x0 = std::floor(x), y0 = std::floor(y);
    const double fx = x - x0, fy = y - y0;
    t.n = 4;
    int k = 0;
    for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx, ++k) {
            const long row = wrap_index(long(y0) + dy, height, repeat), col = wrap_index(long(x0) + dx, width, repeat);
            t.index[k] = std::size_t(row) * std::size_t(width) + std::size_t(col);
            t.weight[k] = (dx ? fx : 1.0 - fx) * (dy ? fy : 1.0 - fy);
        }
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
}

void Svbrdf::texel(const Vec2<float>& uv, TexelFilter filter, Texel* out) const {
    const Taps t = taps_of(uv, filter, width_, height_, addressing_);
    const int L = int(layers_.size()), l = model_->latent_dim();
    out->n_layers = L;
    double w[spec::kSvbrdfMaxLayers] = {1.0, 0.0, 0.0, 0.0};
    if (L > 1) {
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
    for (int k = 0; k < L; ++k) {
        const SvbrdfLayer& layer = layers_[std::size_t(k)];
        const ModelMaterial& mat = model_->materials()[std::size_t(layer.material)];
        TexelLayer& o = out->layers[k];
        o.material = layer.material;
        o.weight = float(w[k]);
        o.latent = out->latent + std::size_t(k) * std::size_t(l);
        if (!(o.weight > 0.f)) continue;  // not evaluated: its values are not read
        float v[3];
        sample_map(layer.kd, 3, t, &mat.params.kd.x, v);
        o.params.kd = Vec3<float>(v[0], v[1], v[2]);
        sample_map(layer.eta, 3, t, &mat.params.eta.x, v);
        o.params.eta = Vec3<float>(v[0], v[1], v[2]);
        sample_map(layer.alpha, 2, t, &mat.params.alpha.x, v);
        o.params.alpha = Vec2<float>(v[0], v[1]);
        sample_map(layer.latent, l, t, mat.latent.data(), out->latent + std::size_t(k) * std::size_t(l));
    }
}

Vec3<float> Svbrdf::eval(const Vec2<float>& uv, TexelFilter filter, const Vec3<float>& wi, const Vec3<float>& wo) const {
    Texel t;
    texel(uv, filter, &t);
    return model_->eval_texel(t.layers, t.n_layers, wi, wo);
}

void Svbrdf::eval_batch(std::size_t n, const float* uv, const float* wi, const float* wo, TexelFilter filter,
                        float* f) const {
    const int L = layer_count();
    const std::size_t l = std::size_t(model_->latent_dim());
    // Every (pair, layer) of positive weight with its texel values, in (pair, layer) order. The
    // buffers are the thread's own and kept between calls: a tracer calls this once per bounce
    // and material, and fresh pages from the kernel cost more than the lookups.
    thread_local std::vector<std::uint32_t> entry_pair;
    thread_local std::vector<TexelLayer> entries, sorted;
    thread_local std::vector<float> latent, dir_i, dir_o, out;
    thread_local std::vector<std::size_t> start, order, row_of;
    entry_pair.clear(), entries.clear(), latent.clear();
    Texel t;
    for (std::size_t i = 0; i < n; ++i) {
        texel(Vec2<float>(uv[2 * i], uv[2 * i + 1]), filter, &t);
        for (int k = 0; k < L; ++k)
            if (t.layers[k].weight > 0.f) {
                entries.push_back(t.layers[k]);
                entry_pair.push_back(std::uint32_t(i));
                latent.insert(latent.end(), t.layers[k].latent, t.layers[k].latent + l);
            }
    }
    const std::size_t m = entries.size();
    for (std::size_t e = 0; e < m; ++e) entries[e].latent = &latent[e * l];
    // The kernels run over runs of one material: in texture order a renderer's pairs already come
    // in long runs (a region of one layer, or the same few layers pair after pair); only when the
    // material changes often are the entries sorted by it (a counting sort).
    std::size_t switches = 0;
    for (std::size_t e = 1; e < m; ++e) switches += entries[e].material != entries[e - 1].material;
    out.resize(3 * m), row_of.resize(m);
    if (switches * 64 <= m) {
        const float* di = wi;
        const float* dw = wo;
        if (m != n) {  // some pairs have several layers: their directions once per layer
            dir_i.resize(3 * m), dir_o.resize(3 * m);
            for (std::size_t e = 0; e < m; ++e) {
                const std::size_t p = entry_pair[e];
                std::copy(wi + 3 * p, wi + 3 * p + 3, &dir_i[3 * e]);
                std::copy(wo + 3 * p, wo + 3 * p + 3, &dir_o[3 * e]);
            }
            di = dir_i.data(), dw = dir_o.data();
        }
        model_->eval_batch_layers(m, di, dw, entries.data(), out.data());
        for (std::size_t e = 0; e < m; ++e) row_of[e] = e;
    } else {
        const std::size_t n_mat = model_->materials().size();
        start.assign(n_mat + 1, 0), order.resize(m);
        for (const TexelLayer& e : entries) ++start[std::size_t(e.material) + 1];
        for (std::size_t k = 0; k < n_mat; ++k) start[k + 1] += start[k];
        for (std::size_t e = 0; e < m; ++e) order[start[std::size_t(entries[e].material)]++] = e;
        dir_i.resize(3 * m), dir_o.resize(3 * m), sorted.resize(m);
        for (std::size_t r = 0; r < m; ++r) {
            const std::size_t e = order[r], p = entry_pair[e];
            std::copy(wi + 3 * p, wi + 3 * p + 3, &dir_i[3 * r]);
            std::copy(wo + 3 * p, wo + 3 * p + 3, &dir_o[3 * r]);
            sorted[r] = entries[e];  // its latent pointer still into `latent`
            row_of[e] = r;
        }
        model_->eval_batch_layers(m, dir_i.data(), dir_o.data(), sorted.data(), out.data());
    }
    std::fill(f, f + 3 * n, 0.f);
    for (std::size_t e = 0; e < m; ++e) {  // (pair, layer) order: the scalar path's sum order
        const std::size_t p = entry_pair[e], r = row_of[e];
        const float w = entries[e].weight;
        for (int c = 0; c < 3; ++c) f[3 * p + std::size_t(c)] = f[3 * p + std::size_t(c)] + out[3 * r + std::size_t(c)] * w;
    }
}

Vec3<float> Svbrdf::eval_analytic(const Vec2<float>& uv, TexelFilter filter, const Vec3<float>& wi,
                                  const Vec3<float>& wo) const {
    Texel t;
    texel(uv, filter, &t);
    Vec3<float> f(0.f);
    for (int k = 0; k < t.n_layers; ++k)
        if (t.layers[k].weight > 0.f) f = f + AnalyticBrdf(t.layers[k].params).eval(wi, wo) * t.layers[k].weight;
    return f;
}

BrdfSample Svbrdf::sample(const Vec2<float>& uv, TexelFilter filter, Strategy s, const Vec3<float>& wo,
                          const Vec2<float>& u_in) const {
    Texel t;
    texel(uv, filter, &t);
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
    float pdf = 0.f;
    for (int k = 0; k < t.n_layers; ++k)
        if (t.layers[k].weight > 0.f) pdf += t.layers[k].weight * hbrdf::pdf(s, AnalyticBrdf(t.layers[k].params), b.wi, wo);
    b.pdf = pdf;
    b.weight = Vec3<float>(0.f);  // the integrator evaluates the texel itself
    return b;
}

float Svbrdf::pdf(const Vec2<float>& uv, TexelFilter filter, Strategy s, const Vec3<float>& wi,
                  const Vec3<float>& wo) const {
    Texel t;
    texel(uv, filter, &t);
    float pdf = 0.f;
    for (int k = 0; k < t.n_layers; ++k)
        if (t.layers[k].weight > 0.f) pdf += t.layers[k].weight * hbrdf::pdf(s, AnalyticBrdf(t.layers[k].params), wi, wo);
    return pdf;
}

}  // namespace hbrdf
