// hybridbrdf — model files (safetensors + JSON metadata) and their evaluation.
// The format is specified in docs/FITTING.md; the Python writer is
// python/hybridbrdf/model_file.py. Every check here mirrors the Python loader.
#include "hybridbrdf/model.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "hybridbrdf/version.hpp"

namespace hbrdf {
namespace {

using json = nlohmann::json;

constexpr int kFormatVersion = 1;
constexpr std::uint64_t kMaxHeaderBytes = 64ull << 20;

struct Tensor {
    std::vector<std::int64_t> shape;
    std::vector<float> data;
};

std::string shape_str(const std::vector<std::int64_t>& s) {
    std::ostringstream o;
    o << "(";
    for (std::size_t i = 0; i < s.size(); ++i) o << (i ? ", " : "") << s[i];
    o << (s.size() == 1 ? ",)" : ")");
    return o.str();
}

// Reads the safetensors container: metadata map and float32 tensors.
void read_safetensors(const std::string& path, std::map<std::string, std::string>& metadata,
                      std::map<std::string, Tensor>& tensors) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw ModelFileError(path, "no such file or not readable");
    const std::vector<char> raw((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (raw.size() < 8)
        throw ModelFileError(path, "truncated: " + std::to_string(raw.size()) +
                                       " bytes, not even a safetensors header length");
    std::uint64_t hlen = 0;
    for (int i = 7; i >= 0; --i) hlen = (hlen << 8) | static_cast<unsigned char>(raw[i]);
    if (hlen > kMaxHeaderBytes || 8 + hlen > raw.size())
        throw ModelFileError(path, "not a safetensors file or truncated (header length " + std::to_string(hlen) +
                                       ", file " + std::to_string(raw.size()) + " bytes)");
    json header;
    try {
        header = json::parse(raw.begin() + 8, raw.begin() + 8 + static_cast<std::ptrdiff_t>(hlen));
    } catch (const json::exception& e) {
        throw ModelFileError(path, std::string("safetensors header is not valid JSON (") + e.what() + ")");
    }
    if (!header.is_object()) throw ModelFileError(path, "safetensors header is not a JSON object");
    const char* data = raw.data() + 8 + hlen;
    const std::uint64_t data_len = raw.size() - 8 - hlen;
    for (auto it = header.begin(); it != header.end(); ++it) {
        if (it.key() == "__metadata__") {
            if (!it->is_object()) throw ModelFileError(path, "__metadata__ is not an object");
            for (auto m = it->begin(); m != it->end(); ++m)
                if (m->is_string()) metadata[m.key()] = m->get<std::string>();
            continue;
        }
        const json& info = *it;
        Tensor t;
        std::uint64_t start = 0, end = 0;
        try {
            if (info.at("dtype").get<std::string>() != "F32")
                throw ModelFileError(path, "tensor '" + it.key() + "': dtype " + info.at("dtype").get<std::string>() +
                                               ", expected F32");
            for (const auto& d : info.at("shape")) t.shape.push_back(d.get<std::int64_t>());
            start = info.at("data_offsets").at(0).get<std::uint64_t>();
            end = info.at("data_offsets").at(1).get<std::uint64_t>();
        } catch (const json::exception&) {
            throw ModelFileError(path, "tensor '" + it.key() + "': malformed entry in the header");
        }
        std::uint64_t count = 1;
        for (auto d : t.shape) {
            if (d < 0) throw ModelFileError(path, "tensor '" + it.key() + "': negative dimension");
            count *= static_cast<std::uint64_t>(d);
        }
        if (!(start <= end && end <= data_len) || end - start != 4 * count)
            throw ModelFileError(path, "tensor '" + it.key() + "': data range [" + std::to_string(start) + ", " +
                                           std::to_string(end) + ") does not fit shape " + shape_str(t.shape) +
                                           " in " + std::to_string(data_len) + " data bytes (truncated?)");
        t.data.resize(count);
        if (count) std::memcpy(t.data.data(), data + start, 4 * count);  // little-endian hosts only
        tensors[it.key()] = std::move(t);
    }
}

template <typename T> T get_field(const std::string& path, const json& obj, const char* key, const char* where) {
    try {
        return obj.at(key).get<T>();
    } catch (const json::exception&) {
        throw ModelFileError(path, std::string(where) + "." + key + " is missing or has the wrong type");
    }
}

ModelKind parse_kind(const std::string& path, const std::string& s) {
    if (s == "hybrid") return ModelKind::Hybrid;
    if (s == "neural") return ModelKind::Neural;
    if (s == "additive") return ModelKind::Additive;
    if (s == "logmul") return ModelKind::LogMul;
    if (s == "analytic-input") return ModelKind::AnalyticInput;
    throw ModelFileError(path, "arch.kind '" + s + "' is not one of hybrid, neural, additive, logmul, analytic-input");
}

Activation parse_activation(const std::string& path, const std::string& s) {
    if (s == "relu") return Activation::Relu;
    if (s == "hardgelu") return Activation::HardGelu;
    throw ModelFileError(path, "arch.activation '" + s + "' is not one of relu, hardgelu");
}

const Tensor& expect(const std::string& path, const std::map<std::string, Tensor>& t, const std::string& name,
                     std::vector<std::int64_t> shape) {
    auto it = t.find(name);
    if (it == t.end()) throw ModelFileError(path, "missing tensors: " + name);
    if (it->second.shape != shape)
        throw ModelFileError(path, "tensor " + name + " has shape " + shape_str(it->second.shape) + ", expected " +
                                       shape_str(shape));
    for (float v : it->second.data)
        if (!std::isfinite(v)) throw ModelFileError(path, "tensor " + name + " holds NaN or Inf");
    return it->second;
}

DenseLayer make_layer(const std::string& path, const std::map<std::string, Tensor>& t, const std::string& prefix,
                      int n_in, int n_out) {
    DenseLayer l;
    l.n_in = n_in;
    l.n_out = n_out;
    l.weight = expect(path, t, prefix + ".weight", {n_out, n_in}).data;
    l.bias = expect(path, t, prefix + ".bias", {n_out}).data;
    return l;
}

HBRDF_INLINE float activate(Activation a, float x) {
    // hardGeLU = x * clamp((x + 1.5) / 3, 0, 1): 0 below -1.5, x above 1.5, x (x + 1.5) / 3 between.
    if (a == Activation::Relu) return x > 0.f ? x : 0.f;
    return x * clamp_nan_lo((x + 1.5f) * (1.0f / 3.0f), 0.0f, 1.0f);
}

HBRDF_INLINE float exp_clamped(float x) { return std::exp(x < kPreExpMax ? x : kPreExpMax); }
HBRDF_INLINE float sigmoid(float x) { return 1.0f / (1.0f + std::exp(-x)); }

// torch.nn.functional.normalize(v, eps=1e-8): v / max(|v|, eps).
HBRDF_INLINE Vec3<float> normalize_eps(const Vec3<float>& v) {
    const float len = std::sqrt(dot(v, v));
    return v / (len > 1e-8f ? len : 1e-8f);
}

}  // namespace

HybridModel HybridModel::load(const std::string& path) {
    std::map<std::string, std::string> metadata;
    std::map<std::string, Tensor> tensors;
    read_safetensors(path, metadata, tensors);
    auto meta = metadata.find("hybridbrdf");
    if (meta == metadata.end())
        throw ModelFileError(path, "safetensors file without 'hybridbrdf' metadata: not a hybridbrdf model");
    json doc;
    try {
        doc = json::parse(meta->second);
    } catch (const json::exception& e) {
        throw ModelFileError(path, std::string("'hybridbrdf' metadata is not valid JSON (") + e.what() + ")");
    }
    if (!doc.is_object()) throw ModelFileError(path, "'hybridbrdf' metadata is not a JSON object");

    HybridModel model;
    const int format = doc.contains("format_version") && doc["format_version"].is_number_integer()
                           ? doc["format_version"].get<int>() : -1;
    if (format != kFormatVersion)
        throw ModelFileError(path, "format_version " + std::to_string(format) + " is not supported (this library reads " +
                                       std::to_string(kFormatVersion) + ")");
    model.conventions_version_ = get_field<int>(path, doc, "conventions_version", "metadata");
    if (model.conventions_version_ != kConventionsVersion)
        throw ModelFileError(path, "conventions_version " + std::to_string(model.conventions_version_) +
                                       " differs from this library's " + std::to_string(kConventionsVersion));
    if (!doc.contains("arch") || !doc["arch"].is_object()) throw ModelFileError(path, "metadata has no 'arch' object");
    const json& arch = doc["arch"];
    model.kind_ = parse_kind(path, get_field<std::string>(path, arch, "kind", "arch"));
    model.activation_ = parse_activation(path, get_field<std::string>(path, arch, "activation", "arch"));
    model.width_ = get_field<int>(path, arch, "width", "arch");
    model.depth_ = get_field<int>(path, arch, "depth", "arch");
    model.latent_ = get_field<int>(path, arch, "latent", "arch");
    model.n_in_ = get_field<int>(path, arch, "n_in", "arch");
    model.n_out_ = get_field<int>(path, arch, "n_out", "arch");
    if (model.width_ < 1 || model.depth_ < 1 || model.latent_ < 0 || model.width_ > kMaxLayerWidth)
        throw ModelFileError(path, "arch has width " + std::to_string(model.width_) + ", depth " +
                                       std::to_string(model.depth_) + ", latent " + std::to_string(model.latent_) +
                                       " (width must be 1.." + std::to_string(kMaxLayerWidth) + ")");
    const bool hybrid_out = model.kind_ == ModelKind::Hybrid || model.kind_ == ModelKind::AnalyticInput;
    const int expected_in = model.kind_ == ModelKind::Neural          ? 18 + model.latent_
                            : model.kind_ == ModelKind::AnalyticInput ? 9 + model.latent_
                                                                      : 6 + model.latent_;
    const int expected_out = hybrid_out ? 6 : 3;
    if (model.n_in_ != expected_in || model.n_out_ != expected_out || model.n_in_ > kMaxLayerWidth)
        throw ModelFileError(path, "arch n_in/n_out " + std::to_string(model.n_in_) + "/" + std::to_string(model.n_out_) +
                                       " do not match its kind and latent (expected " + std::to_string(expected_in) +
                                       "/" + std::to_string(expected_out) + ")");

    if (!doc.contains("materials") || !doc["materials"].is_array() || doc["materials"].empty())
        throw ModelFileError(path, "metadata lists no materials");
    std::set<std::string> seen;
    for (const auto& m : doc["materials"]) {
        ModelMaterial mat;
        if (!m.is_object() || !m.contains("name") || !m["name"].is_string() || m["name"].get<std::string>().empty())
            throw ModelFileError(path, "material " + std::to_string(model.materials_.size()) + " has no name");
        mat.name = m["name"].get<std::string>();
        if (!seen.insert(mat.name).second) throw ModelFileError(path, "duplicate material names: " + mat.name);
        mat.origin = m.contains("origin") && m["origin"].is_string() ? m["origin"].get<std::string>() : "";
        mat.isotropic = !m.contains("isotropic") || !m["isotropic"].is_boolean() || m["isotropic"].get<bool>();
        model.materials_.push_back(std::move(mat));
    }

    // Shared network.
    std::set<std::string> used;
    int n_in = model.n_in_;
    for (int i = 0; i < model.depth_; ++i) {
        const std::string prefix = "mlp.hidden." + std::to_string(i);
        model.layers_.push_back(make_layer(path, tensors, prefix, n_in, model.width_));
        used.insert(prefix + ".weight");
        used.insert(prefix + ".bias");
        n_in = model.width_;
    }
    model.layers_.push_back(make_layer(path, tensors, "mlp.out", model.width_, model.n_out_));
    used.insert({"mlp.out.weight", "mlp.out.bias"});
    if (model.kind_ == ModelKind::Neural) {
        model.frames_ = make_layer(path, tensors, "frames", model.latent_, 18);
        used.insert({"frames.weight", "frames.bias"});
    }

    // Per-material values.
    const std::int64_t n_mat = static_cast<std::int64_t>(model.materials_.size());
    const Tensor& z = expect(path, tensors, "materials.z", {n_mat, model.latent_});
    used.insert("materials.z");
    for (std::int64_t i = 0; i < n_mat; ++i)
        model.materials_[i].latent.assign(z.data.begin() + i * model.latent_, z.data.begin() + (i + 1) * model.latent_);
    if (model.kind_ != ModelKind::Neural) {
        const Tensor& kd = expect(path, tensors, "materials.kd", {n_mat, 3});
        const Tensor& eta = expect(path, tensors, "materials.eta", {n_mat, 3});
        const Tensor& alpha = expect(path, tensors, "materials.alpha", {n_mat, 2});
        used.insert({"materials.kd", "materials.eta", "materials.alpha"});
        for (std::int64_t i = 0; i < n_mat; ++i) {
            AnalyticParams& p = model.materials_[i].params;
            p.kd = Vec3<float>(kd.data[3 * i], kd.data[3 * i + 1], kd.data[3 * i + 2]);
            p.eta = Vec3<float>(eta.data[3 * i], eta.data[3 * i + 1], eta.data[3 * i + 2]);
            p.alpha = Vec2<float>(alpha.data[2 * i], alpha.data[2 * i + 1]);
            try {
                validate(p);  // in float32, as Python checks it
            } catch (const std::invalid_argument& e) {
                throw ModelFileError(path, "material '" + model.materials_[i].name + "': " + e.what());
            }
            if (model.materials_[i].isotropic && p.alpha.x != p.alpha.y)
                throw ModelFileError(path, "material '" + model.materials_[i].name +
                                               "' is marked isotropic but alpha_x != alpha_y");
            model.analytic_.emplace_back(p);
        }
    }
    for (const auto& [name, t] : tensors)
        if (!used.count(name)) throw ModelFileError(path, "unexpected tensors: " + name);
    model.prepare_batch();
    return model;
}

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

void HybridModel::run_mlp(const float* x, float* out) const {
    float a[kMaxLayerWidth], b[kMaxLayerWidth];
    std::copy(x, x + n_in_, a);
    const std::size_t n_layers = layers_.size();
    for (std::size_t l = 0; l < n_layers; ++l) {
        const DenseLayer& L = layers_[l];
        const bool last = l + 1 == n_layers;
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
    const Vec3<float> wi = wi_in * inverse_length_or_zero(wi_in);
    const Vec3<float> wo = wo_in * inverse_length_or_zero(wo_in);
    const bool valid = wi.z > 0.f && wo.z > 0.f;  // false for invalid (zeroed or NaN) input
    if (!valid) return Vec3<float>(0.f);
    const ModelMaterial& mat = materials_[m];
    float x[kMaxLayerWidth];
    float o[6];
    if (kind_ == ModelKind::Neural) {
        // Three shading frames from the latent code (docs/FITTING.md, NeuralBRDF).
        float raw[18];
        for (int j = 0; j < 18; ++j) {
            float s = frames_.bias[j];
            for (int k = 0; k < latent_; ++k) s += frames_.weight[j * latent_ + k] * mat.latent[k];
            raw[j] = s;
        }
        for (int f = 0; f < 3; ++f) {
            const Vec3<float> n = normalize_eps(Vec3<float>(raw[6 * f], raw[6 * f + 1], raw[6 * f + 2]));
            const Vec3<float> t_raw(raw[6 * f + 3], raw[6 * f + 4], raw[6 * f + 5]);
            const Vec3<float> t = normalize_eps(t_raw - dot(t_raw, n) * n);
            const Vec3<float> b = glm::cross(n, t);
            x[3 * f + 0] = dot(t, wi);
            x[3 * f + 1] = dot(b, wi);
            x[3 * f + 2] = dot(n, wi);
            x[9 + 3 * f + 0] = dot(t, wo);
            x[9 + 3 * f + 1] = dot(b, wo);
            x[9 + 3 * f + 2] = dot(n, wo);
        }
        std::copy(mat.latent.begin(), mat.latent.end(), x + 18);
        run_mlp(x, o);
        return Vec3<float>(exp_clamped(o[0]), exp_clamped(o[1]), exp_clamped(o[2]));
    }
    const Vec3<float> fa = analytic_[m].eval(wi, wo);
    x[0] = wi.x, x[1] = wi.y, x[2] = wi.z, x[3] = wo.x, x[4] = wo.y, x[5] = wo.z;
    std::copy(mat.latent.begin(), mat.latent.end(), x + 6);
    if (kind_ == ModelKind::AnalyticInput)
        for (int c = 0; c < 3; ++c) x[6 + latent_ + c] = std::log1p(fa[c]);
    run_mlp(x, o);
    Vec3<float> f;
    for (int c = 0; c < 3; ++c) {
        switch (kind_) {
            case ModelKind::Additive: f[c] = max0(fa[c] + o[c]); break;
            case ModelKind::LogMul: f[c] = fa[c] * exp_clamped(o[c]); break;
            default: f[c] = exp_clamped(o[c]) + sigmoid(o[3 + c]) * fa[c]; break;
        }
    }
    return f;
}

void HybridModel::prepare_batch() {
    // Inputs that vary per pair: the directions (6), the 3 log1p(f_a) of analytic-input,
    // or the 18 frame features of the neural baseline. The latent inputs are constant per
    // material, so W0[:, z] z is added to the first bias once, here, in double.
    const int z_start = kind_ == ModelKind::Neural ? 18 : 6;
    n_dir_inputs_ = n_in_ - latent_;
    const DenseLayer& L0 = layers_[0];
    w0_dirs_.assign(static_cast<std::size_t>(width_) * n_dir_inputs_, 0.f);
    for (int j = 0; j < width_; ++j) {
        int c = 0;
        for (int k = 0; k < n_in_; ++k)
            if (k < z_start || k >= z_start + latent_) w0_dirs_[j * n_dir_inputs_ + c++] = L0.weight[j * n_in_ + k];
    }
    bias0_.clear();
    frame_cache_.clear();
    for (const ModelMaterial& mat : materials_) {
        std::vector<float> b(width_);
        for (int j = 0; j < width_; ++j) {
            double acc = L0.bias[j];
            for (int k = 0; k < latent_; ++k) acc += double(L0.weight[j * n_in_ + z_start + k]) * mat.latent[k];
            b[j] = float(acc);
        }
        bias0_.push_back(std::move(b));
        if (kind_ == ModelKind::Neural) {
            std::vector<float> fr(27);
            for (int f = 0; f < 3; ++f) {
                float raw[6];
                for (int j = 0; j < 6; ++j) {
                    float acc = frames_.bias[6 * f + j];
                    for (int k = 0; k < latent_; ++k) acc += frames_.weight[(6 * f + j) * latent_ + k] * mat.latent[k];
                    raw[j] = acc;
                }
                const Vec3<float> n = normalize_eps(Vec3<float>(raw[0], raw[1], raw[2]));
                const Vec3<float> t_raw(raw[3], raw[4], raw[5]);
                const Vec3<float> t = normalize_eps(t_raw - dot(t_raw, n) * n);
                const Vec3<float> b3 = glm::cross(n, t);
                for (int c = 0; c < 3; ++c) {
                    fr[9 * f + c] = t[c];
                    fr[9 * f + 3 + c] = b3[c];
                    fr[9 * f + 6 + c] = n[c];
                }
            }
            frame_cache_.push_back(std::move(fr));
        }
    }
}

double HybridModel::flops_per_eval() const {
    double fl = 2.0 * width_ * n_dir_inputs_;
    for (std::size_t l = 1; l < layers_.size(); ++l) fl += 2.0 * layers_[l].n_in * layers_[l].n_out;
    return fl;
}

}  // namespace hbrdf
