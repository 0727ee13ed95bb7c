// hybridbrdf — the model contract's checks of a model file (spec/model.json): the metadata
// document, the versions, the arch table, the material records and names, the tensors the
// architecture needs, the parameter ranges, and the interval-propagation bound that keeps every
// network value inside float32. HybridModel::load (model_load.cpp) runs them in the Python
// loader's order (python/hybridbrdf/model/file.py), with its words.
#include "model_validate.hpp"

#include "hybridbrdf/text.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <set>

namespace hbrdf::model_file {
namespace {

// "%.9g": the number format of every value quoted in a message, the same in the Python loader.
std::string num(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.9g", v);
    return buf;
}

std::string json_type(const json& v) {
    if (v.is_number_integer()) return "an integer";
    if (v.is_number_float()) return "a number";
    if (v.is_string()) return "a string";
    if (v.is_boolean()) return "a boolean";
    if (v.is_null()) return "null";
    if (v.is_array()) return "an array";
    return "an object";
}

std::string join_names(const std::vector<std::string>& names) {
    std::string s;
    for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
    return s;
}


// arch.<key> checked against its row of the contract's table (spec::kArchFields);
// returns the value as a double (an Enum: its index). Integers are compared as
// 64-bit (unsigned: the largest JSON integers) before any narrowing.
double read_arch_field(const std::string& path, const json& arch, const spec::ArchField& f) {
    const std::string where = std::string("arch.") + f.key;
    if (!arch.contains(f.key)) {
        if (f.has_default) return f.default_value;
        throw ModelFileError(path, where + " is missing");
    }
    const json& v = arch.at(f.key);
    auto range_error = [&](const std::string& value) {
        return ModelFileError(path, where + " = " + value + " is outside [" + num(f.min) + ", " + num(f.max) + "]");
    };
    switch (f.type) {
        case spec::FieldType::Enum: {
            if (!v.is_string()) throw ModelFileError(path, where + " must be a string, got " + json_type(v));
            const std::string s = v.get<std::string>();
            std::string names;
            for (int i = 0; i < f.n_values; ++i) {
                if (s == f.values[i]) return i;
                names += std::string(i ? ", " : "") + f.values[i];
            }
            throw ModelFileError(path, where + " '" + s + "' is not one of " + names);
        }
        case spec::FieldType::Int: {
            if (!v.is_number_integer()) throw ModelFileError(path, where + " must be an integer, got " + json_type(v));
            if (v.is_number_unsigned()) {
                const std::uint64_t u = v.get<std::uint64_t>();
                // JSON's non-negative integers arrive here (0 included): the lower bound counts too.
                if (double(u) < f.min || double(u) > f.max) throw range_error(std::to_string(u));
                return double(u);
            }
            const std::int64_t i = v.get<std::int64_t>();
            if (double(i) < f.min || double(i) > f.max) throw range_error(std::to_string(i));
            return double(i);
        }
        case spec::FieldType::Number: {
            if (!v.is_number()) throw ModelFileError(path, where + " must be a number, got " + json_type(v));
            const double d = v.get<double>();
            if (!(d >= f.min && d <= f.max)) throw range_error(num(d));
            return d;
        }
    }
    return 0.0;
}

// A character of a name as messages show it: 'x' when printable ASCII, else U+XXXX (never
// raw). `s` is valid UTF-8 (the JSON parser rejects anything else); `i` is advanced past it.
std::string describe_character(const std::string& s, std::size_t& i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c >= 0x20 && c <= 0x7e) {
        ++i;
        return std::string("'") + char(c) + "'";
    }
    const int extra = c < 0x80 ? 0 : c < 0xe0 ? 1 : c < 0xf0 ? 2 : 3;
    std::uint32_t cp = extra == 0 ? c : extra == 1 ? (c & 0x1fu) : extra == 2 ? (c & 0x0fu) : (c & 0x07u);
    for (int k = 1; k <= extra && i + k < s.size(); ++k) cp = (cp << 6) | (static_cast<unsigned char>(s[i + k]) & 0x3fu);
    i += 1 + extra;
    char buf[16];
    std::snprintf(buf, sizeof buf, "U+%04X", cp);
    return buf;
}

// <NAME> of the shader constant HBRDF_MATERIAL_<NAME> (python/hybridbrdf/names.py): upper case,
// each run of characters other than ASCII letters and digits one '_', none at either end, so the
// constant never holds "__" (reserved in GLSL, an error in GLSL ES, and in C++).
std::string shader_constant_key(const std::string& name) {
    std::string key;
    bool gap = false;
    for (unsigned char c : name) {
        if (c < 0x80 && std::isalnum(c)) {
            if (gap && !key.empty()) key += '_';
            key += char(std::toupper(c));
            gap = false;
        } else {
            gap = true;
        }
    }
    return key;
}

// The material-name rule (spec::kNameRule; python/hybridbrdf/names.py): empty when valid.
// Characters first, so that a length is only ever counted over ASCII (bytes = characters).
std::string name_problem(const std::string& name) {
    std::size_t i = 0, n_chars = 0;
    while (i < name.size()) {
        const unsigned char c = static_cast<unsigned char>(name[i]);
        const bool ok = c < 0x80 && (std::isalnum(c) || std::strchr(spec::kNamePunctuation, char(c)) != nullptr) && c != 0;
        if (!ok) {
            const std::size_t at = n_chars + 1;
            return "name character " + std::to_string(at) + " is " + describe_character(name, i) + "; a name is " +
                   spec::kNameRule;
        }
        ++i;
        ++n_chars;
    }
    if (name.size() > std::size_t(spec::kMaxNameLength))
        return "name is " + std::to_string(name.size()) + " characters long; a name is " + spec::kNameRule;
    if (shader_constant_key(name).empty())
        return "name has no letter or digit, so it gives no shader constant HBRDF_MATERIAL_<NAME>";
    return {};
}

// One material's record; `index` is its place in the list, as messages count it.
ModelMaterial read_material(const std::string& path, const json& m, std::size_t index) {
    ModelMaterial mat;
    if (!m.is_object() || !m.contains("name") || !m["name"].is_string() || m["name"].get<std::string>().empty())
        throw ModelFileError(path, "material " + std::to_string(index) + " has no name");
    mat.name = m["name"].get<std::string>();
    const std::string problem = name_problem(mat.name);
    if (!problem.empty()) throw ModelFileError(path, "material " + std::to_string(index) + ": " + problem);
    return mat;
}

// |W| b + |bias| for each output of a layer whose inputs are bounded by b_in.
std::vector<double> layer_bound(const std::map<std::string, Tensor>& tensors, const std::string& prefix,
                                const std::vector<double>& b_in) {
    const Tensor& w = tensors.at(prefix + ".weight");
    const Tensor& bias = tensors.at(prefix + ".bias");
    const std::size_t n_out = std::size_t(w.shape[0]), n_in = std::size_t(w.shape[1]);
    std::vector<double> b(n_out);
    for (std::size_t o = 0; o < n_out; ++o) {
        double sum = 0.0;
        for (std::size_t i = 0; i < n_in; ++i) sum += std::fabs(double(w.data[o * n_in + i])) * b_in[i];
        b[o] = sum + std::fabs(double(bias.data[o]));
    }
    return b;
}

// The overflow message for `tensor` when the largest bound in b passes the contract's limit.
std::string overflow_message(const std::string& tensor, const std::vector<double>& b) {
    const double top = b.empty() ? 0.0 : *std::max_element(b.begin(), b.end());
    if (!(top > spec::kMaxNetworkValue)) return {};
    char buf[160];
    std::snprintf(buf, sizeof buf, ": network values may reach %.3g, beyond %.3g (float32 evaluation could overflow)",
                  top, spec::kMaxNetworkValue);
    return "tensor " + tensor + buf;
}

}  // namespace

json read_document(const std::string& path, const std::map<std::string, std::string>& metadata) {
    const std::string key = spec::kMetadataKey;
    auto meta = metadata.find(key);
    if (meta == metadata.end())
        throw ModelFileError(path, "safetensors file without '" + key + "' metadata: not a hybridbrdf model");
    if (json_depth(meta->second) > spec::kMaxJsonDepth)
        throw ModelFileError(path, "'" + key + "' metadata: JSON nested deeper than " +
                                       std::to_string(spec::kMaxJsonDepth) + " levels");
    json doc;
    try {
        doc = json::parse(meta->second);
    } catch (const json::exception& e) {
        throw ModelFileError(path, "'" + key + "' metadata is not valid JSON (" + e.what() + ")");
    }
    if (!doc.is_object()) throw ModelFileError(path, "'" + key + "' metadata is not a JSON object");
    return doc;
}

void check_versions(const std::string& path, const json& doc) {
    struct Versions { const char* field; int oldest, newest; };
    for (const Versions& f : {Versions{"format_version", spec::kOldestFormatVersion, spec::kFormatVersion},
                              Versions{"conventions_version", spec::kConventionsVersion, spec::kConventionsVersion}}) {
        std::string reads = std::to_string(f.oldest);
        for (int n = f.oldest + 1; n <= f.newest; ++n) reads += " and " + std::to_string(n);
        const json* v = doc.contains(f.field) ? &doc[f.field] : nullptr;
        if (!v || !v->is_number_integer())
            throw ModelFileError(path, std::string(f.field) + " must be an integer, got " +
                                           (v ? json_type(*v) : "nothing") + " (this library reads " + reads + ")");
        // Compared as 64-bit integers of their own sign: 2^32 + 1 must not wrap onto 1.
        const bool ok = v->is_number_unsigned()
                            ? v->get<std::uint64_t>() >= std::uint64_t(f.oldest) && v->get<std::uint64_t>() <= std::uint64_t(f.newest)
                            : v->get<std::int64_t>() >= f.oldest && v->get<std::int64_t>() <= f.newest;
        if (!ok)
            throw ModelFileError(path, std::string(f.field) + " " + v->dump() + " is not supported (this library reads " +
                                           reads + ")");
    }
}

Arch read_arch(const std::string& path, const json& doc) {
    if (!doc.contains("arch") || !doc["arch"].is_object()) throw ModelFileError(path, "metadata has no 'arch' object");
    const json& arch = doc["arch"];
    std::map<std::string, double> field;
    for (const auto& f : spec::kArchFields) field[f.key] = read_arch_field(path, arch, f);
    Arch a;
    a.kind = static_cast<ModelKind>(int(field.at("kind")));
    a.activation = static_cast<Activation>(int(field.at("activation")));
    a.width = int(field.at("width"));
    a.depth = int(field.at("depth"));
    a.latent = int(field.at("latent"));
    a.n_in = int(field.at("n_in"));
    a.n_out = int(field.at("n_out"));
    a.pre_exp_max = float(field.at("pre_exp_max"));
    a.output_layer = static_cast<OutputLayer>(int(field.at("output_layer")));
    a.energy_bound = static_cast<EnergyBound>(int(field.at("energy_bound")));
    const spec::ArchSpec& as = a.row();
    // An older definition of the same inputs (spec/model.json, since_format): check_versions ran first.
    const int format_version = int(doc["format_version"].get<std::int64_t>());
    if (format_version < as.since_format)
        throw ModelFileError(path, std::string("arch.kind '") + as.name + "' in format_version " +
                                       std::to_string(format_version) + ": " + as.refused_before +
                                       "; refit with --arch " + as.name);
    const int expected_in = as.direction_count + a.latent + as.extra_count;
    if (a.n_in != expected_in || a.n_out != as.n_out)
        throw ModelFileError(path, "arch n_in/n_out " + std::to_string(a.n_in) + "/" + std::to_string(a.n_out) +
                                       " do not match kind " + as.name + " with latent " + std::to_string(a.latent) +
                                       " (expected " + std::to_string(expected_in) + "/" + std::to_string(as.n_out) + ")");
    return a;
}

std::vector<ModelMaterial> read_materials(const std::string& path, const json& doc) {
    if (!doc.contains("materials") || !doc["materials"].is_array() || doc["materials"].empty())
        throw ModelFileError(path, "metadata lists no materials");
    if (doc["materials"].size() > std::size_t(spec::kMaxMaterials))
        throw ModelFileError(path, "metadata lists " + std::to_string(doc["materials"].size()) +
                                       " materials, more than " + std::to_string(spec::kMaxMaterials));
    std::vector<ModelMaterial> materials;
    std::set<std::string> seen;
    for (const auto& m : doc["materials"]) {
        ModelMaterial mat = read_material(path, m, materials.size());
        if (!seen.insert(mat.name).second) throw ModelFileError(path, "duplicate material names: " + mat.name);
        if (m.contains("origin") && !m["origin"].is_string())
            throw ModelFileError(path, "material '" + mat.name + "': origin must be a string");
        if (m.contains("isotropic") && !m["isotropic"].is_boolean())
            throw ModelFileError(path, "material '" + mat.name + "': isotropic must be true or false");
        mat.origin = m.contains("origin") ? m["origin"].get<std::string>() : "";
        mat.isotropic = !m.contains("isotropic") || m["isotropic"].get<bool>();
        materials.push_back(std::move(mat));
    }
    // Valid, distinct names can still share a shader constant (gold-1, GOLD_1).
    std::map<std::string, std::string> constant_owner;
    for (const auto& mat : materials) {
        const auto [it, fresh] = constant_owner.emplace(shader_constant_key(mat.name), mat.name);
        if (!fresh)
            throw ModelFileError(path, "materials '" + it->second + "' and '" + mat.name +
                                           "' would share the shader constant HBRDF_MATERIAL_" + it->first);
    }
    return materials;
}

TensorShapes expected_tensors(const std::string& path, const Arch& a, std::int64_t n_mat) {
    const spec::ArchSpec& as = a.row();
    TensorShapes expected;
    std::int64_t n_in = a.n_in;
    for (int i = 0; i < a.depth; ++i) {
        const std::string prefix = "mlp.hidden." + std::to_string(i);
        expected[prefix + ".weight"] = {a.width, n_in};
        expected[prefix + ".bias"] = {a.width};
        n_in = a.width;
    }
    if (a.output_layer == OutputLayer::Shared) {
        expected["mlp.out.weight"] = {a.n_out, a.width};
        expected["mlp.out.bias"] = {a.n_out};
    } else {
        if (!as.analytic)
            throw ModelFileError(path, std::string("arch.output_layer 'material' is for architectures with an analytic "
                                                   "part, not ") + as.name);
        expected["materials.head_weight"] = {n_mat, a.n_out, a.width};
        expected["materials.head_bias"] = {n_mat, a.n_out};
    }
    if (as.directions == spec::DirectionInputs::Frames) {
        expected["frames.weight"] = {6 * spec::kNeuralFrames, a.latent};
        expected["frames.bias"] = {6 * spec::kNeuralFrames};
    }
    expected["materials.z"] = {n_mat, a.latent};
    if (a.energy_bound == EnergyBound::AlbedoTable) expected["materials.energy_bound"] = {n_mat, spec::kEnergyNodes};
    if (as.analytic)
        for (const auto& r : spec::kMaterialRanges) expected[std::string("materials.") + r.tensor] = {n_mat, r.components};
    return expected;
}

void check_tensors(const std::string& path, const std::map<std::string, Tensor>& tensors,
                   const TensorShapes& expected) {
    std::vector<std::string> missing, extra;
    for (const auto& e : expected)
        if (!tensors.count(e.first)) missing.push_back(e.first);
    for (const auto& t : tensors)
        if (!expected.count(t.first)) extra.push_back(t.first);
    if (!missing.empty()) throw ModelFileError(path, "missing tensors: " + join_names(missing));
    if (!extra.empty()) throw ModelFileError(path, "unexpected tensors: " + join_names(extra));
    for (const auto& [name, shape] : expected) {
        const Tensor& t = tensors.at(name);
        if (t.shape != shape)
            throw ModelFileError(path, "tensor " + name + " has shape " + shape_str(t.shape) + ", expected " +
                                           shape_str(shape));
        for (float v : t.data)
            if (!std::isfinite(v)) throw ModelFileError(path, "tensor " + name + " holds NaN or Inf");
    }
}

void read_analytic_params(const std::string& path, const std::map<std::string, Tensor>& tensors,
                          std::vector<ModelMaterial>& materials) {
    for (std::size_t i = 0; i < materials.size(); ++i) {
        ModelMaterial& mat = materials[i];
        for (const auto& r : spec::kMaterialRanges) {
            const float* row = tensors.at(std::string("materials.") + r.tensor).data.data() + i * r.components;
            for (int c = 0; c < r.components; ++c)
                if (!(row[c] >= float(r.min) && row[c] <= float(r.max)))  // in float32, as Python; NaN fails
                    throw ModelFileError(path, "material '" + mat.name + "': " + r.tensor + "[" + std::to_string(c) +
                                                   "] = " + num(row[c]) + " is outside [" + num(r.min) + ", " +
                                                   num(r.max) + "]");
        }
        const float* kd = tensors.at("materials.kd").data.data() + 3 * i;
        const float* eta = tensors.at("materials.eta").data.data() + 3 * i;
        const float* alpha = tensors.at("materials.alpha").data.data() + 2 * i;
        mat.params.kd = Vec3<float>(kd[0], kd[1], kd[2]);
        mat.params.eta = Vec3<float>(eta[0], eta[1], eta[2]);
        mat.params.alpha = Vec2<float>(alpha[0], alpha[1]);
        if (mat.isotropic && mat.params.alpha.x != mat.params.alpha.y)
            throw ModelFileError(path, "material '" + mat.name + "' is marked isotropic but alpha_x != alpha_y");
    }
}

void read_energy_bounds(const std::string& path, const Arch& arch, const std::map<std::string, Tensor>& tensors,
                        std::vector<ModelMaterial>& materials) {
    if (arch.energy_bound != EnergyBound::AlbedoTable) return;
    const Tensor& table = tensors.at("materials.energy_bound");
    const std::size_t K = spec::kEnergyNodes;
    for (std::size_t i = 0; i < materials.size(); ++i) {
        const float* row = table.data.data() + i * K;
        for (std::size_t j = 0; j < K; ++j)
            if (!(row[j] >= 0.f && row[j] <= 1.f))  // a factor above 1 would add light; NaN fails
                throw ModelFileError(path, "material '" + materials[i].name + "': energy_bound[" + std::to_string(j) +
                                               "] = " + num(row[j]) + " is outside [0, 1]");
        materials[i].energy_bound.assign(row, row + K);
    }
}

// Inputs bounded (directions by 1, the latent codes by their largest magnitude over the
// materials, log1p(f_a) by log1p(FLT_MAX)), |W| b + |bias| per layer, relu and hardGeLU never
// grow a magnitude. The first layer past the limit is the one named.
std::string network_overflow_problem(const std::map<std::string, Tensor>& tensors, const Arch& a) {
    const spec::ArchSpec& as = a.row();
    const Tensor& z = tensors.at("materials.z");
    std::vector<double> z_bound(a.latent, 0.0);
    for (std::size_t k = 0; k < z.data.size(); ++k)
        z_bound[k % a.latent] = std::max(z_bound[k % a.latent], std::fabs(double(z.data[k])));
    if (as.directions == spec::DirectionInputs::Frames) {
        const std::string problem = overflow_message("frames.weight", layer_bound(tensors, "frames", z_bound));
        if (!problem.empty()) return problem;
    }
    std::vector<double> b(as.direction_count, 1.0);
    b.insert(b.end(), z_bound.begin(), z_bound.end());
    b.insert(b.end(), as.extra_count, std::log1p(double(std::numeric_limits<float>::max())));
    for (int i = 0; i < a.depth; ++i) {
        const std::string prefix = "mlp.hidden." + std::to_string(i);
        b = layer_bound(tensors, prefix, b);
        const std::string problem = overflow_message(prefix + ".weight", b);
        if (!problem.empty()) return problem;
    }
    if (a.output_layer == OutputLayer::Material) {
        // Every material's head on the shared bound of the last hidden layer; the largest output counts.
        const Tensor& w = tensors.at("materials.head_weight");
        const Tensor& bias = tensors.at("materials.head_bias");
        const std::size_t rows = std::size_t(w.shape[0] * w.shape[1]), n_in = std::size_t(w.shape[2]);
        std::vector<double> out(rows);
        for (std::size_t r = 0; r < rows; ++r) {
            double sum = 0.0;
            for (std::size_t i = 0; i < n_in; ++i) sum += std::fabs(double(w.data[r * n_in + i])) * b[i];
            out[r] = sum + std::fabs(double(bias.data[r]));
        }
        return overflow_message("materials.head_weight", out);
    }
    return overflow_message("mlp.out.weight", layer_bound(tensors, "mlp.out", b));
}

}  // namespace hbrdf::model_file
