// hybridbrdf — model files (safetensors + JSON metadata) and their evaluation.
// The format is specified in docs/FITTING.md and its contract (architectures,
// fields, ranges) in spec/model.json; the Python writer and loader are
// python/hybridbrdf/model_file.py.
#include "hybridbrdf/model.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <set>
#include <tuple>
#include <sstream>

#include <nlohmann/json.hpp>
#include <sys/stat.h>

#include "hybridbrdf/version.hpp"
#include "model_math.hpp"

namespace hbrdf {
namespace {

using json = nlohmann::json;

using spec::kMaxHeaderBytes;
using detail::activate;

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

// The safetensors header text as the Python loader's parser (serde_json, in the safetensors
// package) reads it, where nlohmann-json is more lenient: it skips a UTF-8 byte-order mark and
// stops at a NUL. Raw control characters are invalid anywhere in JSON but for the whitespace
// \t \n \r between tokens, so refusing them all is exact. Empty when acceptable.
std::string header_text_problem(const std::string& text) {
    if (text.size() >= 3 && static_cast<unsigned char>(text[0]) == 0xEF &&
        static_cast<unsigned char>(text[1]) == 0xBB && static_cast<unsigned char>(text[2]) == 0xBF)
        return "the header starts with a UTF-8 byte-order mark";
    for (std::size_t i = 0; i < text.size(); ++i) {
        const unsigned char c = static_cast<unsigned char>(text[i]);
        if (c < 0x20 && c != '\t' && c != '\n' && c != '\r')
            return "control character " + std::to_string(int(c)) + " at header byte " + std::to_string(i);
    }
    return {};
}

// A JSON array of unsigned integers, as serde reads a `usize` list: 6.0, 6.9, -0 and true are
// not integers there (nlohmann-json would convert them). False when any element is not one.
bool read_usize_array(const json& v, std::vector<std::uint64_t>& out) {
    if (!v.is_array()) return false;
    for (const auto& d : v) {
        if (!d.is_number_unsigned()) return false;
        out.push_back(d.get<std::uint64_t>());
    }
    return true;
}

// Reads the safetensors container: metadata map and float32 tensors. The header is checked
// whole (entries, and the data section laid out exactly against the file's real size) before
// any tensor memory is allocated, and then only the bytes the header declares are read, so a
// file's length never sizes a buffer by itself.
void read_safetensors(const std::string& path, std::map<std::string, std::string>& metadata,
                      std::map<std::string, Tensor>& tensors) {
    // What the file is, before opening it (python/hybridbrdf/inputs.py, the same words): opening a
    // FIFO blocks until a writer comes, and a device such as /dev/zero never ends.
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0) {
        if (S_ISDIR(st.st_mode)) throw ModelFileError(path, "is a folder, not a model file");
        if (S_ISFIFO(st.st_mode)) throw ModelFileError(path, "is a FIFO, not a regular file");
        if (S_ISCHR(st.st_mode)) throw ModelFileError(path, "is a character device, not a regular file");
        if (S_ISBLK(st.st_mode)) throw ModelFileError(path, "is a block device, not a regular file");
        if (S_ISSOCK(st.st_mode)) throw ModelFileError(path, "is a socket, not a regular file");
        if (!S_ISREG(st.st_mode)) throw ModelFileError(path, "is not a regular file");
        // The contract bounds a model's size (spec::kMaxDataBytes); the Python loader refuses a
        // longer file with these words too (inputs.check_input_file).
        const std::uint64_t limit = 8 + kMaxHeaderBytes + spec::kMaxDataBytes;
        if (static_cast<std::uint64_t>(st.st_size) > limit)
            throw ModelFileError(path, "model file too long: " + std::to_string(st.st_size) +
                                           " bytes (a model file is at most " + std::to_string(limit) + " bytes)");
    }
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) throw ModelFileError(path, "no such file or not readable");
    const std::streamoff file_size = in.tellg();
    if (file_size < 0) throw ModelFileError(path, "not a regular file");
    const std::uint64_t size = static_cast<std::uint64_t>(file_size);
    if (size < 8)
        throw ModelFileError(path, "truncated: " + std::to_string(size) + " bytes, not even a safetensors header length");
    unsigned char head[8];
    in.seekg(0);
    in.read(reinterpret_cast<char*>(head), 8);
    std::uint64_t hlen = 0;
    for (int i = 7; i >= 0; --i) hlen = (hlen << 8) | head[i];
    // Checked before anything is allocated: a damaged length must not size a buffer.
    if (hlen > kMaxHeaderBytes || 8 + hlen > size)
        throw ModelFileError(path, "not a safetensors file or truncated (header length " + std::to_string(hlen) +
                                       ", file " + std::to_string(size) + " bytes)");
    std::string text(static_cast<std::size_t>(hlen), '\0');
    if (!in.read(text.data(), static_cast<std::streamsize>(hlen)))
        throw ModelFileError(path, "cannot read the " + std::to_string(hlen) + "-byte header (changed while reading?)");
    // serde refuses a repeated field of a struct: "__metadata__" at the top, and "dtype", "shape"
    // or "data_offsets" in a tensor's entry (repeated tensor names and metadata keys are a map's,
    // the last one wins, in both parsers). Noted during the parse, reported after it.
    std::string repeated;
    std::set<std::string> entry_fields;
    bool top_metadata = false, in_entry = false;
    const json::parser_callback_t note = [&](int depth, json::parse_event_t event, json& parsed) {
        if (event == json::parse_event_t::object_start && depth == 1) entry_fields.clear();
        if (event == json::parse_event_t::key && parsed.is_string()) {
            const std::string& k = parsed.get_ref<const std::string&>();
            if (depth == 1) {
                in_entry = k != "__metadata__";
                if (!in_entry && top_metadata && repeated.empty()) repeated = "__metadata__";
                top_metadata = top_metadata || !in_entry;
            } else if (depth == 2 && in_entry && (k == "dtype" || k == "shape" || k == "data_offsets") &&
                       !entry_fields.insert(k).second && repeated.empty()) {
                repeated = k;
            }
        }
        return true;
    };
    json header;
    try {
        header = json::parse(text, note);
    } catch (const json::exception& e) {
        throw ModelFileError(path, std::string("safetensors header is not valid JSON (") + e.what() + ")");
    }
    // After the parse, so that text nlohmann-json refuses keeps its message (which byte, where).
    if (const std::string problem = header_text_problem(text); !problem.empty())
        throw ModelFileError(path, "not a valid safetensors file (" + problem + ")");
    if (!repeated.empty())
        throw ModelFileError(path, "not a valid safetensors file (the header repeats the field '" + repeated + "')");
    if (!header.is_object()) throw ModelFileError(path, "safetensors header is not a JSON object");
    const std::uint64_t data_len = size - 8 - hlen;
    struct Entry {
        std::string name;
        std::vector<std::int64_t> shape;
        std::uint64_t start, end;
    };
    std::vector<Entry> entries;
    for (auto it = header.begin(); it != header.end(); ++it) {
        if (it.key() == "__metadata__") {
            if (it->is_null()) continue;  // an absent map to serde, as to the Python loader
            if (!it->is_object()) throw ModelFileError(path, "__metadata__ is not an object");
            for (auto m = it->begin(); m != it->end(); ++m) {
                if (!m->is_string())
                    throw ModelFileError(path, "not a valid safetensors file (__metadata__ entry '" + m.key() + "' is " +
                                                   (m->is_number_integer() ? std::string("an integer")
                                                    : m->is_number()       ? std::string("a number")
                                                    : m->is_boolean()      ? std::string("a boolean")
                                                    : m->is_null()         ? std::string("null")
                                                    : m->is_array()        ? std::string("an array")
                                                                           : std::string("an object")) +
                                                   ", not a string)");
                metadata[m.key()] = m->get<std::string>();
            }
            continue;
        }
        const json& info = *it;
        Entry e{it.key(), {}, 0, 0};
        std::vector<std::uint64_t> dims, offsets;
        try {
            if (info.at("dtype").get<std::string>() != "F32")
                throw ModelFileError(path, "tensor '" + it.key() + "': dtype " + info.at("dtype").get<std::string>() +
                                               ", expected F32");
            if (!read_usize_array(info.at("shape"), dims))
                throw ModelFileError(path, "not a valid safetensors file (tensor '" + it.key() +
                                               "': shape is not a list of non-negative integers)");
            if (!read_usize_array(info.at("data_offsets"), offsets) || offsets.size() != 2)
                throw ModelFileError(path, "not a valid safetensors file (tensor '" + it.key() +
                                               "': data_offsets is not a list of two non-negative integers)");
        } catch (const json::exception&) {
            throw ModelFileError(path, "tensor '" + it.key() + "': malformed entry in the header");
        }
        e.start = offsets[0];
        e.end = offsets[1];
        std::uint64_t count = 1;
        for (auto d : dims) {
            // Element counts past the data section cannot fit it; stopping here also keeps the
            // product from wrapping around 2^64 and passing the range check below.
            if (d != 0 && count > data_len / 4 / d) {
                count = std::numeric_limits<std::uint64_t>::max() / 8;
                break;
            }
            count *= d;
        }
        for (auto d : dims) e.shape.push_back(static_cast<std::int64_t>(std::min<std::uint64_t>(d, INT64_MAX)));
        if (!(e.start <= e.end && e.end <= data_len) || e.end - e.start != 4 * count)
            throw ModelFileError(path, "tensor '" + it.key() + "': data range [" + std::to_string(e.start) + ", " +
                                           std::to_string(e.end) + ") does not fit shape " + shape_str(e.shape) +
                                           " in " + std::to_string(data_len) + " data bytes (truncated?)");
        entries.push_back(std::move(e));
    }
    // The safetensors format indexes its data section exactly: no overlap, no hole, nothing after
    // the last tensor (bytes nothing reads are damage, or something hidden in the file). Checked
    // against the file's real size before a byte of tensor data is read or allocated.
    std::sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
        return std::tie(a.start, a.end) < std::tie(b.start, b.end);
    });
    std::uint64_t covered = 0;
    for (const auto& e : entries) {
        if (e.start != covered)
            throw ModelFileError(path, "safetensors data section is not laid out tensor after tensor (bytes " +
                                           std::to_string(std::min(e.start, covered)) + " on)");
        covered = e.end;
    }
    if (covered != data_len)
        throw ModelFileError(path, "safetensors data section has " + std::to_string(data_len - covered) +
                                       " bytes after the last tensor");
    // Only now the data: tensor by tensor, in file order, exactly the bytes declared. A failed
    // allocation is the file's size speaking, reported as such rather than as std::bad_alloc.
    try {
        for (auto& e : entries) {
            Tensor t;
            t.shape = std::move(e.shape);
            t.data.resize(static_cast<std::size_t>((e.end - e.start) / 4));
            in.seekg(static_cast<std::streamoff>(8 + hlen + e.start));
            if (e.end > e.start &&  // little-endian hosts only
                !in.read(reinterpret_cast<char*>(t.data.data()), static_cast<std::streamsize>(e.end - e.start)))
                throw ModelFileError(path, "cannot read tensor '" + e.name + "' (the file changed while reading?)");
            tensors[e.name] = std::move(t);
        }
    } catch (const std::bad_alloc&) {
        throw ModelFileError(path, "needs " + std::to_string(data_len) +
                                       " bytes of tensor data, more than this process could allocate");
    }
}

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

// Deepest nesting of arrays and objects in JSON `text`, brackets inside strings not counted
// (python/hybridbrdf/inputs.py json_depth, the same rule): the contract bounds it
// (spec::kMaxJsonDepth) so that both loaders refuse the same files, and before parsing, as
// Python's parser recurses once per level. On malformed text it is a bound the parser then
// rejects for another reason.
int json_depth(const std::string& text) {
    int depth = 0, deepest = 0;
    bool in_string = false, escaped = false;
    for (char c : text) {
        if (in_string) {
            if (escaped) escaped = false;
            else if (c == '\\') escaped = true;
            else if (c == '"') in_string = false;
        } else if (c == '"') {
            in_string = true;
        } else if (c == '[' || c == '{') {
            deepest = std::max(deepest, ++depth);
        } else if (c == ']' || c == '}') {
            --depth;
        }
    }
    return deepest;
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

// Interval bound of every network value (spec::kMaxNetworkValue; the Python loader's
// network_overflow_problem computes the same): inputs bounded, |W| b + |bias| per layer,
// relu and hardGeLU never grow a magnitude. Empty when the network cannot overflow float32.
std::string network_overflow_problem(const std::map<std::string, Tensor>& tensors, const spec::ArchSpec& as,
                                     int depth, int latent, OutputLayer output_layer) {
    const Tensor& z = tensors.at("materials.z");
    std::vector<double> z_bound(latent, 0.0);
    for (std::size_t k = 0; k < z.data.size(); ++k)
        z_bound[k % latent] = std::max(z_bound[k % latent], std::fabs(double(z.data[k])));
    auto layer = [&](const std::string& prefix, const std::vector<double>& b_in) {
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
    };
    auto message = [](const std::string& tensor, const std::vector<double>& b) -> std::string {
        const double top = b.empty() ? 0.0 : *std::max_element(b.begin(), b.end());
        if (!(top > spec::kMaxNetworkValue)) return {};
        char buf[160];
        std::snprintf(buf, sizeof buf, ": network values may reach %.3g, beyond %.3g (float32 evaluation could overflow)",
                      top, spec::kMaxNetworkValue);
        return "tensor " + tensor + buf;
    };
    if (as.directions == spec::DirectionInputs::Frames) {
        const std::string problem = message("frames.weight", layer("frames", z_bound));
        if (!problem.empty()) return problem;
    }
    std::vector<double> b(as.direction_count, 1.0);
    b.insert(b.end(), z_bound.begin(), z_bound.end());
    b.insert(b.end(), as.extra_count, std::log1p(double(std::numeric_limits<float>::max())));
    for (int i = 0; i < depth; ++i) {
        const std::string prefix = "mlp.hidden." + std::to_string(i);
        b = layer(prefix, b);
        const std::string problem = message(prefix + ".weight", b);
        if (!problem.empty()) return problem;
    }
    if (output_layer == OutputLayer::Material) {
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
        return message("materials.head_weight", out);
    }
    return message("mlp.out.weight", layer("mlp.out", b));
}

std::string join_names(const std::vector<std::string>& names) {
    std::string s;
    for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
    return s;
}

}  // namespace

// The checks and their order follow the model contract (spec/model.json) and are
// the same in the Python loader (model_file.py); tests/data/malformed_models.json
// holds the shared table of broken files both must reject alike.
HybridModel HybridModel::load(const std::string& path) try {
    std::map<std::string, std::string> metadata;
    std::map<std::string, Tensor> tensors;
    read_safetensors(path, metadata, tensors);
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

    HybridModel model;
    for (const auto& [field, expected] : {std::pair<const char*, int>{"format_version", spec::kFormatVersion},
                                          {"conventions_version", spec::kConventionsVersion}}) {
        const json* v = doc.contains(field) ? &doc[field] : nullptr;
        if (!v || !v->is_number_integer())
            throw ModelFileError(path, std::string(field) + " must be an integer, got " + (v ? json_type(*v) : "nothing") +
                                           " (this library reads " + std::to_string(expected) + ")");
        const bool ok = v->is_number_unsigned() ? v->get<std::uint64_t>() == std::uint64_t(expected)
                                                : v->get<std::int64_t>() == expected;
        if (!ok)
            throw ModelFileError(path, std::string(field) + " " + v->dump() + " is not supported (this library reads " +
                                           std::to_string(expected) + ")");
    }
    model.conventions_version_ = spec::kConventionsVersion;
    if (!doc.contains("arch") || !doc["arch"].is_object()) throw ModelFileError(path, "metadata has no 'arch' object");
    const json& arch = doc["arch"];
    // Every field in the table's order (so the first problem reported is the Python loader's too).
    std::map<std::string, double> field;
    for (const auto& f : spec::kArchFields) field[f.key] = read_arch_field(path, arch, f);
    model.kind_ = static_cast<ModelKind>(int(field.at("kind")));
    model.activation_ = static_cast<Activation>(int(field.at("activation")));
    model.width_ = int(field.at("width"));
    model.depth_ = int(field.at("depth"));
    model.latent_ = int(field.at("latent"));
    model.n_in_ = int(field.at("n_in"));
    model.n_out_ = int(field.at("n_out"));
    model.pre_exp_max_ = float(field.at("pre_exp_max"));
    model.output_layer_ = static_cast<OutputLayer>(int(field.at("output_layer")));
    const spec::ArchSpec& as = model.arch();
    const int expected_in = as.direction_count + model.latent_ + as.extra_count;
    if (model.n_in_ != expected_in || model.n_out_ != as.n_out)
        throw ModelFileError(path, "arch n_in/n_out " + std::to_string(model.n_in_) + "/" + std::to_string(model.n_out_) +
                                       " do not match kind " + as.name + " with latent " + std::to_string(model.latent_) +
                                       " (expected " + std::to_string(expected_in) + "/" + std::to_string(as.n_out) + ")");

    if (!doc.contains("materials") || !doc["materials"].is_array() || doc["materials"].empty())
        throw ModelFileError(path, "metadata lists no materials");
    if (doc["materials"].size() > std::size_t(spec::kMaxMaterials))
        throw ModelFileError(path, "metadata lists " + std::to_string(doc["materials"].size()) +
                                       " materials, more than " + std::to_string(spec::kMaxMaterials));
    std::set<std::string> seen;
    for (const auto& m : doc["materials"]) {
        ModelMaterial mat;
        if (!m.is_object() || !m.contains("name") || !m["name"].is_string() || m["name"].get<std::string>().empty())
            throw ModelFileError(path, "material " + std::to_string(model.materials_.size()) + " has no name");
        mat.name = m["name"].get<std::string>();
        const std::string problem = name_problem(mat.name);
        if (!problem.empty())
            throw ModelFileError(path, "material " + std::to_string(model.materials_.size()) + ": " + problem);
        if (!seen.insert(mat.name).second) throw ModelFileError(path, "duplicate material names: " + mat.name);
        if (m.contains("origin") && !m["origin"].is_string())
            throw ModelFileError(path, "material '" + mat.name + "': origin must be a string");
        if (m.contains("isotropic") && !m["isotropic"].is_boolean())
            throw ModelFileError(path, "material '" + mat.name + "': isotropic must be true or false");
        mat.origin = m.contains("origin") ? m["origin"].get<std::string>() : "";
        mat.isotropic = !m.contains("isotropic") || m["isotropic"].get<bool>();
        model.materials_.push_back(std::move(mat));
    }

    // Valid, distinct names can still share a shader constant (gold-1, GOLD_1).
    std::map<std::string, std::string> constant_owner;
    for (const auto& mat : model.materials_) {
        const auto [it, fresh] = constant_owner.emplace(shader_constant_key(mat.name), mat.name);
        if (!fresh)
            throw ModelFileError(path, "materials '" + it->second + "' and '" + mat.name +
                                           "' would share the shader constant HBRDF_MATERIAL_" + it->first);
    }

    // The tensors the architecture needs, then their shapes in name order (as Python).
    const std::int64_t n_mat = static_cast<std::int64_t>(model.materials_.size());
    std::map<std::string, std::vector<std::int64_t>> expected;
    std::int64_t n_in = model.n_in_;
    for (int i = 0; i < model.depth_; ++i) {
        const std::string prefix = "mlp.hidden." + std::to_string(i);
        expected[prefix + ".weight"] = {model.width_, n_in};
        expected[prefix + ".bias"] = {model.width_};
        n_in = model.width_;
    }
    if (model.output_layer_ == OutputLayer::Shared) {
        expected["mlp.out.weight"] = {model.n_out_, model.width_};
        expected["mlp.out.bias"] = {model.n_out_};
    } else {
        if (!as.analytic)
            throw ModelFileError(path, std::string("arch.output_layer 'material' is for architectures with an analytic "
                                                   "part, not ") + as.name);
        expected["materials.head_weight"] = {n_mat, model.n_out_, model.width_};
        expected["materials.head_bias"] = {n_mat, model.n_out_};
    }
    if (as.directions == spec::DirectionInputs::Frames) {
        expected["frames.weight"] = {6 * spec::kNeuralFrames, model.latent_};
        expected["frames.bias"] = {6 * spec::kNeuralFrames};
    }
    expected["materials.z"] = {n_mat, model.latent_};
    if (as.analytic)
        for (const auto& r : spec::kMaterialRanges) expected[std::string("materials.") + r.tensor] = {n_mat, r.components};
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

    // Shared network.
    const std::string overflow = network_overflow_problem(tensors, as, model.depth_, model.latent_, model.output_layer_);
    auto layer = [&](const std::string& prefix) {
        DenseLayer l;
        const Tensor& w = tensors.at(prefix + ".weight");
        l.n_out = int(w.shape[0]);
        l.n_in = int(w.shape[1]);
        l.weight = w.data;
        l.bias = tensors.at(prefix + ".bias").data;
        return l;
    };
    for (int i = 0; i < model.depth_; ++i) model.layers_.push_back(layer("mlp.hidden." + std::to_string(i)));
    if (model.output_layer_ == OutputLayer::Shared) model.layers_.push_back(layer("mlp.out"));
    if (as.directions == spec::DirectionInputs::Frames) model.frames_ = layer("frames");

    // Per-material values.
    const Tensor& z = tensors.at("materials.z");
    for (std::int64_t i = 0; i < n_mat; ++i)
        model.materials_[i].latent.assign(z.data.begin() + i * model.latent_, z.data.begin() + (i + 1) * model.latent_);
    if (model.output_layer_ == OutputLayer::Material) {
        const Tensor& hw = tensors.at("materials.head_weight");
        const Tensor& hb = tensors.at("materials.head_bias");
        const std::size_t nw = std::size_t(model.n_out_) * model.width_;
        for (std::int64_t i = 0; i < n_mat; ++i) {
            DenseLayer& h = model.materials_[i].head;
            h.n_in = model.width_;
            h.n_out = model.n_out_;
            h.weight.assign(hw.data.begin() + i * nw, hw.data.begin() + (i + 1) * nw);
            h.bias.assign(hb.data.begin() + i * model.n_out_, hb.data.begin() + (i + 1) * model.n_out_);
        }
    }
    if (as.analytic) {
        for (std::int64_t i = 0; i < n_mat; ++i) {
            ModelMaterial& mat = model.materials_[i];
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
            model.analytic_.emplace_back(mat.params);
        }
    }
    if (!overflow.empty()) throw ModelFileError(path, overflow);  // checked last, as in Python
    model.prepare_batch();
    return model;
} catch (const std::bad_alloc&) {
    // Whatever the allocation, a model's memory is proportional to its file, which the contract
    // bounds (spec::kMaxDataBytes); what fails below that is this machine's limit, said so.
    throw ModelFileError(path, "needs more memory than this process could allocate");
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

void HybridModel::run_mlp(int m, const float* x, float* out) const {
    float a[kMaxLayerWidth], b[kMaxLayerWidth];
    std::copy(x, x + n_in_, a);
    for (int l = 0; l <= depth_; ++l) {
        const bool last = l == depth_;
        const DenseLayer& L = last ? output_layer(m) : layers_[l];
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
    const spec::ArchSpec& as = arch();
    // Network input (spec/model.json): direction inputs, the latent code, extra inputs.
    float x[kMaxLayerWidth];
    float o[6];
    if (as.directions == spec::DirectionInputs::Frames) {
        // wi, then wo, in the material's shading frames (t, b, n each), prepared at load.
        const float* fr = frame_cache_[m].data();
        for (int side = 0; side < 2; ++side)
            for (int k = 0; k < 3 * spec::kNeuralFrames; ++k)
                x[9 * side + k] = dot(Vec3<float>(fr[3 * k], fr[3 * k + 1], fr[3 * k + 2]), side ? wo : wi);
    } else {
        x[0] = wi.x, x[1] = wi.y, x[2] = wi.z, x[3] = wo.x, x[4] = wo.y, x[5] = wo.z;
        if (as.directions == spec::DirectionInputs::LocalHalf) {
            const Vec3<float> h = half_vector(wi, wo);
            x[6] = h.z, x[7] = cos_theta_d(wi, wo, h);
        }
    }
    std::copy(mat.latent.begin(), mat.latent.end(), x + as.direction_count);
    const Vec3<float> fa = as.analytic ? analytic_[m].eval(wi, wo) : Vec3<float>(0.f);
    if (as.extra == spec::ExtraInputs::Log1pFa)
        for (int c = 0; c < 3; ++c) x[as.direction_count + latent_ + c] = std::log1p(fa[c]);
    run_mlp(m, x, o);
    Vec3<float> f;
    for (int c = 0; c < 3; ++c)
        f[c] = detail::combine(as.combine, o[c], as.n_out == 6 ? o[3 + c] : 0.f, fa[c], pre_exp_max_);
    return f;
}

void HybridModel::prepare_batch() {
    // Inputs that vary per pair: the direction inputs and the extra inputs. The latent
    // inputs are constant per material, so W0[:, z] z is added to the first bias once,
    // here, in double.
    const int z_start = arch().direction_count;
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
        if (arch().directions == spec::DirectionInputs::Frames) {
            std::vector<float> fr(9 * spec::kNeuralFrames);
            detail::neural_frames(frames_, mat.latent.data(), fr.data());
            frame_cache_.push_back(std::move(fr));
        }
    }
}

double HybridModel::flops_per_eval() const {
    double fl = 2.0 * width_ * n_dir_inputs_;
    for (int l = 1; l < depth_; ++l) fl += 2.0 * layers_[l].n_in * layers_[l].n_out;
    const DenseLayer& out = output_layer(0);  // every material's has the same shape
    return fl + 2.0 * out.n_in * out.n_out;
}

}  // namespace hbrdf
