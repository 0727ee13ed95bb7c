// hybridbrdf renderer — a textured material's folder into a Svbrdf (svbrdf_io.hpp).
#include "hybridbrdf/render/svbrdf_io.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

#include <nlohmann/json.hpp>
#include <stb/stb_image.h>

#include "hybridbrdf/render/image.hpp"
#include "hybridbrdf/render/ktx2.hpp"
#include "hybridbrdf/spec.hpp"
#include "hybridbrdf/text.hpp"

namespace hbrdf::render {

namespace {

using json = nlohmann::json;

constexpr const char* kIndexFile = "svbrdf.json";
constexpr std::uint64_t kMaxIndexBytes = 1 << 20;
constexpr int kChannels = spec::kSvbrdfMapChannels;

struct Quantity {
    const char* name;
    int components;  // -1: the latent dimension
    bool per_layer;
    double min, max;
};
// spec/model.json, svbrdf.quantities (the order of the spec).
const Quantity kQuantities[] = {
    {"weights", 3, false, 0.0, 1.0},
    {"kd", 3, true, spec::kKdMin, spec::kKdMax},
    {"eta", 3, true, spec::kEtaMin, spec::kEtaMax},
    {"alpha", 2, true, spec::kAlphaMin, spec::kAlphaMax},
    {"latent", -1, true, -1e6, 1e6},
    {"normal", 2, false, -1.0, 1.0},
};

const Quantity* find_quantity(const std::string& name) {
    for (const Quantity& q : kQuantities)
        if (name == q.name) return &q;
    return nullptr;
}

double transfer(const std::string& name, double v) {
    if (name == "srgb") return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
    if (name == "square") return v * v;
    return v;  // linear (checked before)
}

bool is_int(const json& v) { return v.is_number_integer(); }

std::string read_index(const std::string& path) {
    check_input_file(path, "textured-material index");
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0 && std::uint64_t(st.st_size) > kMaxIndexBytes)
        throw FileError(path, "textured-material index too long: " + std::to_string(st.st_size) + " bytes (a textured-material index is at most " +
                                  std::to_string(kMaxIndexBytes) + " bytes)");
    std::ifstream in(path, std::ios::binary);
    if (!in) throw FileError(path, "cannot read the textured-material index");
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

void plain_name(const std::string& index_path, const json& name, const std::string& what) {
    if (!name.is_string()) throw FileError(index_path, what + " must be a plain file name inside the folder");
    const std::string n = name.get<std::string>();
    if (n.empty() || n == "." || n == ".." || n[0] == '.' || n.find('/') != std::string::npos ||
        n.find('\\') != std::string::npos || n.find('\0') != std::string::npos)
        throw FileError(index_path, what + " must be a plain file name inside the folder, got '" + n + "'");
}

// Stored values (H, W, 3) of a map, as doubles (PNG bytes / 255, EXR floats), size checked.
std::vector<double> read_map(const std::string& path, int width, int height, bool* eight_bit) {
    const auto dot = path.find_last_of('.');
    std::string ext = dot == std::string::npos ? "" : path.substr(dot);
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    if (ext != ".png" && ext != ".exr")
        throw FileError(path, "texel maps are .png (8-bit) or .exr (float32), not '" + (ext.empty() ? std::string("no extension") : ext) + "'");
    check_input_file(path, "texel map");
    std::vector<double> out;
    int w = 0, h = 0;
    if (ext == ".png") {
        int comp = 0;
        if (!stbi_info(path.c_str(), &w, &h, &comp)) {
            const char* why = stbi_failure_reason();
            throw FileError(path, std::string("cannot read the PNG map: ") + (why ? why : "unknown"));
        }
        if (w < 1 || h < 1 || w > spec::kSvbrdfMaxSide || h > spec::kSvbrdfMaxSide)
            throw FileError(path, "map is " + std::to_string(w) + "x" + std::to_string(h) + "; each side must be 1 to " +
                                      std::to_string(spec::kSvbrdfMaxSide) + " texels");
        if (comp != 3 || stbi_is_16_bit(path.c_str()))
            throw FileError(path, "texel maps are 8-bit RGB PNG; this one has " + std::to_string(comp) + " channel(s)" +
                                      (stbi_is_16_bit(path.c_str()) ? " of 16 bits" : ""));
        int c = 0;
        unsigned char* data = stbi_load(path.c_str(), &w, &h, &c, 3);
        if (!data) {
            const char* why = stbi_failure_reason();
            throw FileError(path, std::string("cannot read the PNG map: ") + (why ? why : "unknown"));
        }
        out.assign(std::size_t(w) * std::size_t(h) * 3, 0.0);
        for (std::size_t i = 0; i < out.size(); ++i) out[i] = data[i] / 255.0;
        stbi_image_free(data);
        *eight_bit = true;
    } else {
        const Image img = read_image(path);
        w = img.width, h = img.height;
        if (w > spec::kSvbrdfMaxSide || h > spec::kSvbrdfMaxSide)
            throw FileError(path, "map is " + std::to_string(w) + "x" + std::to_string(h) + "; each side must be 1 to " +
                                      std::to_string(spec::kSvbrdfMaxSide) + " texels");
        out.assign(img.rgb.begin(), img.rgb.end());
        for (std::size_t i = 0; i < out.size(); ++i)
            if (!std::isfinite(out[i])) {
                const std::size_t t = i / 3;
                throw FileError(path, "texel (" + std::to_string(t % std::size_t(w)) + ", " + std::to_string(t / std::size_t(w)) +
                                          ") channel " + "RGB"[i % 3] + " is not finite (maps must be finite)");
            }
        *eight_bit = false;
    }
    if (w != width || h != height)
        throw FileError(path, "map is " + std::to_string(w) + "x" + std::to_string(h) + "; the index says " +
                                  std::to_string(width) + "x" + std::to_string(height));
    return out;
}

std::string fmt(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
}

// Why a width x height material cannot have `levels` mip levels ("" if it can): the words of
// hybridbrdf.svbrdf.mips.chain_problem.
std::string chain_problem(int width, int height, int levels) {
    if (levels == 1) return "";
    const auto pow2 = [](int n) { return n > 0 && (n & (n - 1)) == 0; };
    const std::string size = std::to_string(width) + "x" + std::to_string(height);
    if (!pow2(width) || !pow2(height)) return "a mip chain needs power-of-two sides, the size is " + size;
    int complete = 0;
    for (int side = std::max(width, height); side > 0; side >>= 1) ++complete;
    if (levels != complete)
        return "a " + size + " material's mip chain has 1 or " + std::to_string(complete) + " levels (down to 1x1), got " +
               std::to_string(levels);
    return "";
}

// One map file's decoded values (texels x used channels), each checked against the quantity's range.
std::vector<double> decode_stored(const std::string& path, const std::vector<double>& stored, int width, int height,
                                  const json& decodes, int used, const Quantity& q) {
    const std::size_t texels = std::size_t(width) * std::size_t(height);
    std::vector<double> values(texels * std::size_t(used));
    for (int ch = 0; ch < used; ++ch) {
        const json& d = decodes[std::size_t(ch)];
        const std::string tr = d["transfer"].get<std::string>();
        const double scale = d["scale"].get<double>(), offset = d["offset"].get<double>();
        for (std::size_t t = 0; t < texels; ++t) {
            const double v = offset + scale * transfer(tr, stored[3 * t + std::size_t(ch)]);
            if (!(v >= q.min && v <= q.max))
                throw FileError(path, "texel (" + std::to_string(t % std::size_t(width)) + ", " + std::to_string(t / std::size_t(width)) +
                                          ") channel " + "RGB"[ch] + " decodes to " + fmt(float(v)) + ", outside " + q.name + "'s range [" +
                                          fmt(q.min) + ", " + fmt(q.max) + "]");
            values[t * std::size_t(used) + std::size_t(ch)] = v;
        }
    }
    return values;
}

// A map file's decoded values (read_map, then decode_stored).
std::vector<double> decode_map(const std::string& path, int width, int height, const json& decodes, int used, const Quantity& q) {
    bool eight_bit = false;
    return decode_stored(path, read_map(path, width, height, &eight_bit), width, height, decodes, used, q);
}

// Level L of a KTX2 map decoded: its format holds the channels the map uses (a weights map those
// of its layers; a channel it lacks reads 0, as a sampler returns it), and an sRGB format only
// channels of the srgb transfer (a sampler decodes them before filtering). The words of
// hybridbrdf.svbrdf.entries._ktx2_levels.
std::vector<double> ktx2_values(const Ktx2Texture& tex, int L, const std::string& path, const std::string& index_path,
                                const std::string& qn, const json& decodes, int used, int n_layers, const Quantity& q) {
    const int needed = qn == "weights" ? n_layers - 1 : used;
    if (tex.channels < needed)
        throw FileError(path, tex.format_name + " holds " + std::to_string(tex.channels) + " channel(s); this " + qn + " map needs " +
                                  std::to_string(needed));
    const std::string file = path.substr(path.find_last_of('/') + 1);
    if (tex.srgb)
        for (int ch = 0; ch < std::min(used, tex.channels); ++ch) {
            const json& d = decodes[std::size_t(ch)];
            if (!d.is_null() && d["transfer"] != "srgb")
                throw FileError(index_path, file + " channel " + "RGB"[ch] + ": " + tex.format_name + " is sRGB-encoded (a sampler decodes it), "
                                            "so its transfer must be srgb, not " + d["transfer"].get<std::string>());
        }
    const Ktx2Level& level = tex.levels[std::size_t(L)];
    const std::size_t texels = std::size_t(level.width) * std::size_t(level.height);
    const int k = std::min(tex.channels, kChannels);
    std::vector<double> stored(texels * kChannels, 0.0);
    for (std::size_t t = 0; t < texels; ++t)
        for (int ch = 0; ch < k; ++ch) {
            const std::size_t i = t * std::size_t(tex.channels) + std::size_t(ch);
            stored[t * kChannels + std::size_t(ch)] = tex.is_float ? double(level.floats[i]) : level.bytes[i] / 255.0;
        }
    return decode_stored(path, stored, int(level.width), int(level.height), decodes, used, q);
}

}  // namespace

std::shared_ptr<const Svbrdf> load_svbrdf(const std::string& folder_in) {
    std::string folder = folder_in;
    while (folder.size() > 1 && folder.back() == '/') folder.pop_back();
    struct stat st {};
    if (::stat(folder.c_str(), &st) != 0) throw FileError(folder, "no such folder");
    if (!S_ISDIR(st.st_mode)) throw FileError(folder, "is not a folder");
    const std::string index_path = folder + "/" + kIndexFile;
    json index;
    const std::string text = read_index(index_path);
    if (json_depth(text) > spec::kMaxJsonDepth)
        throw FileError(index_path, "textured-material index: JSON nested deeper than " + std::to_string(spec::kMaxJsonDepth) + " levels");
    try {
        index = json::parse(text);
    } catch (const json::parse_error& e) {
        throw FileError(index_path, std::string("textured-material index is not valid JSON (") + e.what() + ")");
    }
    if (!index.is_object()) throw FileError(index_path, "the index must be a JSON object");
    // Version 1 has no mip chain; version 2 adds the index's "levels" and each map's "mips".
    const json version = index.contains("format_version") ? index["format_version"] : json();
    if (!is_int(version) || (version.get<long long>() != 1 && version.get<long long>() != spec::kSvbrdfFormatVersion))
        throw FileError(index_path, "format_version " + (version.is_null() ? std::string("None") : version.dump()) +
                                        " is not supported (this library reads 1 and " + std::to_string(spec::kSvbrdfFormatVersion) + ")");
    std::set<std::string> keys = {"format_version", "model", "size", "addressing", "layers", "maps"};
    if (version.get<long long>() >= 2) keys.insert("levels");
    for (const auto& item : index.items())
        if (!keys.count(item.key())) throw FileError(index_path, "unknown keys ['" + item.key() + "']");
    for (const std::string& k : keys)
        if (!index.contains(k)) throw FileError(index_path, "missing keys ['" + k + "']");
    plain_name(index_path, index["model"], "model");
    const std::string model_path = folder + "/" + index["model"].get<std::string>();
    std::shared_ptr<const HybridModel> model;
    try {
        model = std::make_shared<const HybridModel>(HybridModel::load(model_path));
    } catch (const ModelFileError& e) {
        throw FileError(e.path(), e.problem());
    }
    if (!model->arch().analytic)
        throw FileError(model_path, "a textured material needs a hybrid model; this one is the neural baseline");
    const json& size = index["size"];
    if (!size.is_array() || size.size() != 2 || !is_int(size[0]) || !is_int(size[1]) || size[0].get<long long>() < 1 ||
        size[1].get<long long>() < 1 || size[0].get<long long>() > spec::kSvbrdfMaxSide || size[1].get<long long>() > spec::kSvbrdfMaxSide)
        throw FileError(index_path, "size must be [W, H], integers 1 to " + std::to_string(spec::kSvbrdfMaxSide) + ", got " + size.dump());
    const int width = size[0].get<int>(), height = size[1].get<int>();
    int max_levels = 0;
    for (int side = spec::kSvbrdfMaxSide; side > 0; side >>= 1) ++max_levels;
    const json levels_j = index.contains("levels") ? index["levels"] : json(1);
    if (!is_int(levels_j) || levels_j.get<long long>() < 1 || levels_j.get<long long>() > max_levels)
        throw FileError(index_path, "levels must be an integer 1 to " + std::to_string(max_levels) + ", got " + levels_j.dump());
    const int levels = levels_j.get<int>();
    if (const std::string problem = chain_problem(width, height, levels); !problem.empty()) throw FileError(index_path, problem);
    const json& addressing = index["addressing"];
    if (!addressing.is_string() || (addressing != "repeat" && addressing != "clamp"))
        throw FileError(index_path, "addressing must be one of repeat, clamp, got " + addressing.dump());
    const json& layers_j = index["layers"];
    if (!layers_j.is_array() || layers_j.empty() || int(layers_j.size()) > spec::kSvbrdfMaxLayers)
        throw FileError(index_path, "layers must be a list of 1 to " + std::to_string(spec::kSvbrdfMaxLayers) + " layers");
    std::vector<SvbrdfLayer> layers(layers_j.size());
    for (std::size_t k = 0; k < layers_j.size(); ++k) {
        const json& l = layers_j[k];
        if (!l.is_object() || l.size() != 1 || !l.contains("material") || !l["material"].is_string())
            throw FileError(index_path, "layer " + std::to_string(k) + " must be {\"material\": NAME}");
        const int m = model->find(l["material"].get<std::string>());
        if (m < 0)
            throw FileError(index_path, "layer " + std::to_string(k) + ": material '" + l["material"].get<std::string>() +
                                            "' is not in " + index["model"].get<std::string>());
        layers[k].material = m;
    }
    const int n_layers = int(layers.size()), latent = model->latent_dim();
    std::vector<std::vector<float>> weights, normal;  // per level
    std::set<std::tuple<std::string, int, int>> seen;
    // (layer, quantity) -> first -> values per level
    std::map<std::pair<int, std::string>, std::map<int, std::vector<std::vector<double>>>> parts;
    if (!index["maps"].is_array()) throw FileError(index_path, "maps must be a list");
    for (const json& e : index["maps"]) {
        static const std::set<std::string> map_keys = {"file", "quantity", "layer", "first", "mips", "decode"};
        bool ok = e.is_object() && e.contains("file") && e.contains("quantity") && e.contains("first") && e.contains("decode");
        if (ok)
            for (const auto& item : e.items()) ok = ok && map_keys.count(item.key());
        if (!ok) throw FileError(index_path, "each map must be {\"file\", \"quantity\", [\"layer\"], \"first\", [\"mips\"], \"decode\"}");
        const Quantity* q = e["quantity"].is_string() ? find_quantity(e["quantity"].get<std::string>()) : nullptr;
        if (!q) throw FileError(index_path, "unknown map quantity " + e["quantity"].dump() + " (expected one of weights, kd, eta, alpha, latent, normal)");
        const std::string qn = q->name;
        if (q->per_layer != e.contains("layer"))
            throw FileError(index_path, "a " + qn + " map " + (q->per_layer ? "needs" : "has no") + " \"layer\"");
        int layer = -1;
        if (q->per_layer) {
            if (!is_int(e["layer"]) || e["layer"].get<long long>() < 0 || e["layer"].get<long long>() >= n_layers)
                throw FileError(index_path, qn + " map: layer must be 0 to " + std::to_string(n_layers - 1) + ", got " + e["layer"].dump());
            layer = e["layer"].get<int>();
        }
        const int c = q->components < 0 ? latent : q->components;
        if (!is_int(e["first"]) || e["first"].get<long long>() < 0 || e["first"].get<long long>() >= c ||
            e["first"].get<long long>() % kChannels != 0)
            throw FileError(index_path, qn + " map: first must be a multiple of " + std::to_string(kChannels) + " below " +
                                            std::to_string(c) + ", got " + e["first"].dump());
        const int first = e["first"].get<int>();
        plain_name(index_path, e["file"], "a map's file");
        const std::string file = e["file"].get<std::string>();
        const std::string path = folder + "/" + file;
        const auto dot = file.find_last_of('.');
        std::string ext = dot == std::string::npos ? "" : file.substr(dot);
        std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char ch) { return char(std::tolower(ch)); });
        const bool ktx2 = ext == ".ktx2";  // one file holding the whole chain (svbrdf_io.hpp)
        const bool has_mips = e.contains("mips");
        if (ktx2 && has_mips)
            throw FileError(index_path, file + ": a KTX2 map holds its own mip levels; \"mips\" lists PNG and EXR levels");
        if (!ktx2 && (has_mips != (levels > 1) || (has_mips && (!e["mips"].is_array() || int(e["mips"].size()) != levels - 1))))
            throw FileError(index_path, levels > 1 ? file + ": a material of " + std::to_string(levels) + " levels lists " +
                                                         std::to_string(levels - 1) + " mip files per map (\"mips\")"
                                                   : file + ": \"mips\" needs \"levels\" above 1 in the index");
        Ktx2Texture texture;
        if (ktx2) {
            check_input_file(path, "texel map");
            texture = read_ktx2(path);  // bounded: every size checked against the file before any allocation
            if (int(texture.width) != width || int(texture.height) != height)
                throw FileError(path, "map is " + std::to_string(texture.width) + "x" + std::to_string(texture.height) + "; the index says " +
                                          std::to_string(width) + "x" + std::to_string(height));
            if (int(texture.levels.size()) != levels)
                throw FileError(path, "holds " + std::to_string(texture.levels.size()) + " mip level(s); the index says " + std::to_string(levels));
        }
        const json& decodes = e["decode"];
        const int used = std::min(kChannels, c - first);
        if (!decodes.is_array() || int(decodes.size()) != kChannels)
            throw FileError(index_path, file + ": decode must list " + std::to_string(kChannels) + " channels");
        if (ext != ".png" && ext != ".exr" && ext != ".ktx2")
            throw FileError(path, "texel maps are .png (8-bit), .exr (float32) or .ktx2, not '" + (ext.empty() ? std::string("no extension") : ext) + "'");
        const bool png = ktx2 ? !texture.is_float : ext == ".png";  // stored values in [0, 1]: the 8-bit decode's rules
        for (int ch = 0; ch < kChannels; ++ch) {
            const json& d = decodes[std::size_t(ch)];
            const std::string where = file + " channel " + "RGB"[ch] + ": ";
            if (ch >= used) {
                if (!d.is_null() && qn != "weights")
                    throw FileError(index_path, file + ": channel " + "RGB"[ch] + " holds no " + qn + " component; its decode must be null");
                continue;
            }
            if (!d.is_object() || d.size() != 3 || !d.contains("transfer") || !d.contains("scale") || !d.contains("offset"))
                throw FileError(index_path, where + "a channel's decode must be {\"transfer\", \"scale\", \"offset\"}");
            if (!d["transfer"].is_string() || (d["transfer"] != "linear" && d["transfer"] != "srgb" && d["transfer"] != "square"))
                throw FileError(index_path, where + "unknown transfer '" + (d["transfer"].is_string() ? d["transfer"].get<std::string>() : d["transfer"].dump()) +
                                                "' (expected one of linear, srgb, square)");
            for (const char* key : {"scale", "offset"})
                if (!d[key].is_number() || !std::isfinite(d[key].get<double>()))
                    throw FileError(index_path, where + "decode " + key + " must be a finite number, got " + d[key].dump());
            if (png) {
                const std::string tr = d["transfer"].get<std::string>();
                const double a = d["offset"].get<double>() + d["scale"].get<double>() * transfer(tr, 0.0);
                const double b = d["offset"].get<double>() + d["scale"].get<double>() * transfer(tr, 1.0);
                const double lo = std::min(a, b), hi = std::max(a, b);
                const double slack = 1e-6 * std::max({1.0, std::fabs(q->min), std::fabs(q->max)});
                if (lo < q->min - slack || hi > q->max + slack)
                    throw FileError(index_path, where + "decodes to [" + fmt(lo) + ", " + fmt(hi) + "], outside " + qn + "'s range [" +
                                                    fmt(q->min) + ", " + fmt(q->max) + "]");
            }
        }
        if (!seen.insert({qn, layer, first}).second)
            throw FileError(index_path, "two maps give " + qn + " " + std::to_string(first) + ".." + std::to_string(first + 2) +
                                            (layer < 0 ? "" : " of layer " + std::to_string(layer)));
        std::vector<std::string> paths = {path};
        for (int L = 1; L < levels && !ktx2; ++L) {
            const json& name = e["mips"][std::size_t(L - 1)];
            plain_name(index_path, name, "a mip file");
            const std::string mip = name.get<std::string>();
            const auto mdot = mip.find_last_of('.');
            std::string mext = mdot == std::string::npos ? "" : mip.substr(mdot);
            std::transform(mext.begin(), mext.end(), mext.begin(), [](unsigned char ch) { return char(std::tolower(ch)); });
            if (mext != ext) throw FileError(index_path, mip + ": a mip level is stored as level 0 is (" + ext + ")");
            paths.push_back(folder + "/" + mip);
        }
        std::vector<std::vector<double>> chain;
        for (int L = 0; L < levels; ++L) {
            const int lw = std::max(1, width >> L), lh = std::max(1, height >> L);
            std::vector<double> values = ktx2 ? ktx2_values(texture, L, path, index_path, qn, decodes, used, n_layers, *q)
                                              : decode_map(paths[std::size_t(L)], lw, lh, decodes, used, *q);
            if (qn == "weights")
                for (std::size_t t = 0; t < std::size_t(lw) * std::size_t(lh); ++t)
                    for (int ch = n_layers - 1; ch < 3; ++ch)
                        if (values[t * 3 + std::size_t(ch)] != 0.0)
                            throw FileError(paths[std::size_t(ktx2 ? 0 : L)], "weights of layers beyond the last (" + std::to_string(n_layers - 1) + ") must be 0");
            chain.push_back(std::move(values));
        }
        if (qn == "weights") {
            for (const auto& v : chain) weights.emplace_back(v.begin(), v.end());
        } else if (qn == "normal") {  // x, y per texel (used = 2 channels)
            for (const auto& v : chain) normal.emplace_back(v.begin(), v.end());
        } else {
            parts[{layer, qn}][first] = std::move(chain);
        }
    }
    std::vector<std::vector<SvbrdfLayer>> level_layers(std::size_t(levels), layers);
    for (auto& [key, pieces] : parts) {
        const auto& [layer, qn] = key;
        const Quantity* q = find_quantity(qn);
        const int c = q->components < 0 ? latent : q->components;
        int expect = 0;
        for (const auto& piece : pieces) {
            if (piece.first != expect) break;
            expect += kChannels;
        }
        if (expect < c || int(pieces.size()) * kChannels < c) {
            std::string starts;
            for (const auto& piece : pieces) starts += (starts.empty() ? "" : ", ") + std::to_string(piece.first);
            throw FileError(index_path, "layer " + std::to_string(layer) + ": " + qn + " maps must cover components 0.." +
                                            std::to_string(c - 1) + " (maps start at [" + starts + "])");
        }
        for (int lv = 0; lv < levels; ++lv) {
            const std::size_t n = std::size_t(std::max(1, width >> lv)) * std::size_t(std::max(1, height >> lv));
            std::vector<float> joined(n * std::size_t(c));
            for (const auto& [first, vals] : pieces) {
                const int used = std::min(kChannels, c - first);
                for (std::size_t t = 0; t < n; ++t)
                    for (int ch = 0; ch < used; ++ch)
                        joined[t * std::size_t(c) + std::size_t(first + ch)] = float(vals[std::size_t(lv)][t * std::size_t(used) + std::size_t(ch)]);
            }
            SvbrdfLayer& L = level_layers[std::size_t(lv)][std::size_t(layer)];
            (qn == "kd" ? L.kd : qn == "eta" ? L.eta : qn == "alpha" ? L.alpha : L.latent) = std::move(joined);
        }
    }
    if (n_layers > 1 && weights.empty())
        throw FileError(index_path, std::to_string(n_layers) + " layers need a weights map");
    const TexelAddressing addr = addressing == "repeat" ? TexelAddressing::Repeat : TexelAddressing::Clamp;
    std::vector<std::shared_ptr<const Svbrdf>> mips;
    for (int lv = 1; lv < levels; ++lv) {
        auto level = std::make_shared<Svbrdf>(model, std::max(1, width >> lv), std::max(1, height >> lv), addr,
                                              std::move(level_layers[std::size_t(lv)]),
                                              weights.empty() ? std::vector<float>() : std::move(weights[std::size_t(lv)]));
        if (!normal.empty()) level->set_normal_map(std::move(normal[std::size_t(lv)]));
        mips.push_back(std::move(level));
    }
    auto sv = std::make_shared<Svbrdf>(model, width, height, addr, std::move(level_layers[0]),
                                       weights.empty() ? std::vector<float>() : std::move(weights[0]));
    if (!normal.empty()) sv->set_normal_map(std::move(normal[0]));
    sv->set_mips(std::move(mips));
    return sv;
}

}  // namespace hbrdf::render
