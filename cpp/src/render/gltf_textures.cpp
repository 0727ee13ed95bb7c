// hybridbrdf renderer — a glTF asset's textures for its materials (docs/GLTF.md, "Textures").
//
// A material's textureInfo names a texture; the texture its image (source) and sampler. Each
// image is checked before a decoder sees its pixels: exactly one of uri and bufferView, a
// mimeType image/png or image/jpeg (required with a bufferView; a data: URI's own type; a file's
// from its signature), the bytes' signature matching it, and its size read from the header
// (a PNG's IHDR, a JPEG's start-of-frame, read here without a decoder) at most kMaxGltfImageSide a side and
// kMaxGltfImageTexels in all. Then stb_image decodes it (8-bit RGBA); a decoder failure (a
// truncated file) is one line naming the image. Each image is decoded once per asset, and its mip
// chain (gltf_mip_chain, below) built once per asset and encoding when a sampler asks for one.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>

#include <stb/stb_image.h>

#include "hybridbrdf/text.hpp"
#include "scene_reader.hpp"

namespace hbrdf::render {

namespace {

// The weights of a box filter halving a side of n texels to m = max(1, n / 2): destination texel
// i covers source [i n / m, (i + 1) n / m); each source texel k weighs its overlap with it, over
// the footprint's width n / m. Even n: (1/2, 1/2) of texels 2i, 2i + 1; odd n: three texels.
struct Tap {
    int k;
    double w;
};
std::vector<std::vector<Tap>> box_taps(int n) {
    const int m = std::max(1, n / 2);
    const double width = double(n) / m;
    std::vector<std::vector<Tap>> taps(static_cast<std::size_t>(m));
    for (int i = 0; i < m; ++i) {
        const double lo = i * width, hi = (i + 1) * width;
        for (int k = int(std::floor(lo)); k < n && k < hi; ++k) {
            const double overlap = std::min(hi, k + 1.0) - std::max(lo, double(k));
            if (overlap > 0.0) taps[std::size_t(i)].push_back({k, overlap / width});
        }
    }
    return taps;
}

}  // namespace

std::vector<GltfImage> gltf_mip_chain(const GltfImage& level0, bool srgb) {
    int w = level0.width, h = level0.height;
    // Linear values in double: the previous level unrounded (no 8-bit loss compounding down the chain).
    std::vector<double> values(level0.rgba.size());
    for (std::size_t i = 0; i < values.size(); ++i) {
        const double x = level0.rgba[i] / 255.0;
        values[i] = srgb && i % 4 != 3 ? srgb_to_linear(x) : x;
    }
    std::vector<GltfImage> chain;
    while (w > 1 || h > 1) {
        const auto tx = box_taps(w), ty = box_taps(h);
        const int w2 = int(tx.size()), h2 = int(ty.size());
        std::vector<double> next(std::size_t(w2) * std::size_t(h2) * 4, 0.0);
        for (int y = 0; y < h2; ++y)
            for (int x = 0; x < w2; ++x) {
                double* out = &next[(std::size_t(y) * std::size_t(w2) + std::size_t(x)) * 4];
                for (const Tap& a : ty[std::size_t(y)])
                    for (const Tap& b : tx[std::size_t(x)]) {
                        const double* in = &values[(std::size_t(a.k) * std::size_t(w) + std::size_t(b.k)) * 4];
                        for (int c = 0; c < 4; ++c) out[c] += a.w * b.w * in[c];
                    }
            }
        GltfImage level;
        level.width = w2, level.height = h2;
        level.rgba.resize(next.size());
        for (std::size_t i = 0; i < next.size(); ++i) {
            const double x = std::clamp(srgb && i % 4 != 3 ? linear_to_srgb(next[i]) : next[i], 0.0, 1.0);
            level.rgba[i] = static_cast<unsigned char>(std::lround(x * 255.0));
        }
        chain.push_back(std::move(level));
        values = std::move(next);
        w = w2, h = h2;
    }
    return chain;
}

}  // namespace hbrdf::render

namespace hbrdf::render::detail {

namespace {

const char* signature_type(const std::string& bytes) {
    static const unsigned char png[8] = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
    if (bytes.size() >= 8 && std::memcmp(bytes.data(), png, 8) == 0) return "image/png";
    if (bytes.size() >= 3 && (unsigned char)bytes[0] == 0xFF && (unsigned char)bytes[1] == 0xD8 && (unsigned char)bytes[2] == 0xFF)
        return "image/jpeg";
    return nullptr;
}

// The width and height an image's header declares, read without a decoder: a PNG's IHDR, a
// JPEG's first start-of-frame segment (the markers walked by their lengths). False when absent.
bool header_size(const std::string& b, const std::string& type, std::uint64_t& width, std::uint64_t& height) {
    auto byte = [&](std::size_t i) { return std::uint64_t(static_cast<unsigned char>(b[i])); };
    auto be16 = [&](std::size_t i) { return byte(i) << 8 | byte(i + 1); };
    auto be32 = [&](std::size_t i) { return be16(i) << 16 | be16(i + 2); };
    if (type == "image/png") {
        if (b.size() < 24 || b.compare(12, 4, "IHDR") != 0) return false;
        width = be32(16), height = be32(20);
        return true;
    }
    std::size_t at = 2;  // past SOI
    while (at + 4 <= b.size()) {
        if (byte(at) != 0xFF) return false;
        const std::uint64_t marker = byte(at + 1);
        if (marker == 0xFF) {  // fill byte
            ++at;
            continue;
        }
        if (marker == 0xD8 || marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) {  // no length
            at += 2;
            continue;
        }
        const std::uint64_t length = be16(at + 2);
        const bool sof = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
        if (sof) {
            if (at + 9 > b.size()) return false;
            height = be16(at + 5), width = be16(at + 7);
            return true;
        }
        if (length < 2) return false;
        at += 2 + length;
    }
    return false;
}

std::uint64_t count(const SceneReader& r, const json& obj, const std::string& w, const char* key, std::uint64_t def) {
    if (!obj.contains(key)) return def;
    const json& v = obj.at(key);
    if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<std::int64_t>() >= 0))
        r.fail(w + "." + key, "expected an integer >= 0, got " + v.dump());
    return v.get<std::uint64_t>();
}

const json& element(const SceneReader& r, const json& doc, const char* array, std::uint64_t i, const std::string& w) {
    const std::size_t size = doc.contains(array) && doc.at(array).is_array() ? doc.at(array).size() : 0;
    if (i >= size) r.fail(w, std::to_string(i) + " is out of range (the asset has " + std::to_string(size) + " " + array + ")");
    const json& e = doc.at(array).at(i);
    if (!e.is_object()) r.fail(std::string(array) + "[" + std::to_string(i) + "]", "expected an object");
    return e;
}

}  // namespace

GltfImages::GltfImages(const SceneReader& r, const json& doc, const std::vector<std::string>& buffers, std::string folder)
    : r_(r), doc_(doc), buffers_(buffers), folder_(std::move(folder)) {}

// The image's encoded bytes and its declared (or, for a file, signature's) type.
std::string GltfImages::encoded(const json& im, const std::string& w, std::string& type) const {
    const bool has_uri = im.contains("uri"), has_view = im.contains("bufferView");
    if (has_uri == has_view) r_.fail(w, "an image has exactly one of 'uri' and 'bufferView'");
    if (im.contains("mimeType")) type = r_.string(im.at("mimeType"), w + ".mimeType");
    if (has_view) {
        if (type.empty()) r_.fail(w + ".mimeType", "an image in a bufferView needs a mimeType");
        const std::uint64_t v = count(r_, im, w, "bufferView", 0);
        const json& view = element(r_, doc_, "bufferViews", v, w + ".bufferView");
        // check_views_and_accessors bounded every view inside its buffer
        const std::size_t b = view.at("buffer").get<std::size_t>();
        const std::uint64_t offset = count(r_, view, "bufferViews", "byteOffset", 0), length = view.at("byteLength").get<std::uint64_t>();
        return buffers_.at(b).substr(offset, length);
    }
    const std::string uri = r_.string(im.at("uri"), w + ".uri");
    if (ascii_lower(uri.substr(0, 5)) == "data:") {
        const std::size_t comma = uri.find(',');
        if (comma == std::string::npos || uri.rfind(";base64", comma) == std::string::npos)
            r_.fail(w + ".uri", "a data: URI must be base64");
        if (uri.size() > kMaxGltfDataUri)
            r_.fail(w + ".uri", "a data: URI of " + std::to_string(uri.size()) + " characters, above the limit of " +
                                    std::to_string(kMaxGltfDataUri));
        const std::string media = uri.substr(5, uri.find(';') - 5);
        if (type.empty()) type = media;
        return base64_decode(uri.substr(comma + 1));
    }
    if (uri.find(':') != std::string::npos || uri.empty() || uri[0] == '/' || uri.find('\\') != std::string::npos ||
        ("/" + uri + "/").find("/../") != std::string::npos || uri.find('%') != std::string::npos)
        r_.fail(w + ".uri", "'" + uri + "': an image must lie in the asset's folder (no scheme, absolute path, '..' or escapes)");
    const std::string file = folder_ + "/" + uri;
    try {
        check_input_file(file, "glTF image");
    } catch (const FileError& e) {
        r_.fail(w + ".uri", e.what());
    }
    std::ifstream in(file, std::ios::binary);
    std::string bytes;
    in.seekg(0, std::ios::end);
    const std::streamoff size = in.tellg();
    if (size < 0 || std::uint64_t(size) > kMaxGltfBytes)
        r_.fail(w + ".uri", file + ": not readable, or above the limit of " + std::to_string(kMaxGltfBytes) + " bytes");
    bytes.resize(std::size_t(size));
    in.seekg(0);
    if (!in.read(bytes.data(), size)) r_.fail(w + ".uri", file + ": cannot read " + std::to_string(size) + " bytes");
    if (type.empty() && signature_type(bytes)) type = signature_type(bytes);
    return bytes;
}

std::shared_ptr<const GltfImage> GltfImages::image(std::uint64_t index, const std::string& w_source) {
    if (const auto it = cache_.find(index); it != cache_.end()) return it->second;
    const json& im = element(r_, doc_, "images", index, w_source);
    const std::string w = "images[" + std::to_string(index) + "]";
    std::string type;
    const std::string bytes = encoded(im, w, type);
    if (type != "image/png" && type != "image/jpeg")
        r_.fail(w + ".mimeType", "'" + type + "': images are image/png or image/jpeg (glTF 2.0)");
    const char* found = signature_type(bytes);
    if (!found || type != found)
        r_.fail(w, std::string("declared ") + type + ", but its bytes are " + (found ? found : "neither PNG nor JPEG"));
    if (bytes.size() > std::size_t(std::numeric_limits<int>::max())) r_.fail(w, "more than 2^31 bytes");
    std::uint64_t width = 0, height = 0;
    if (!header_size(bytes, type, width, height)) r_.fail(w, "cannot read the " + type + " image's size from its header");
    if (width < 1 || height < 1 || width > std::uint64_t(kMaxGltfImageSide) || height > std::uint64_t(kMaxGltfImageSide) ||
        width * height > kMaxGltfImageTexels)
        r_.fail(w, "its header declares " + std::to_string(width) + " x " + std::to_string(height) + " texels; at most " +
                       std::to_string(kMaxGltfImageSide) + " a side and " + std::to_string(kMaxGltfImageTexels) + " in all");
    const auto* data = reinterpret_cast<const stbi_uc*>(bytes.data());
    int w2 = 0, h2 = 0, c2 = 0;
    stbi_uc* pixels = stbi_load_from_memory(data, int(bytes.size()), &w2, &h2, &c2, 4);
    if (!pixels || std::uint64_t(w2) != width || std::uint64_t(h2) != height) {
        if (pixels) stbi_image_free(pixels);
        const char* why = stbi_failure_reason();
        r_.fail(w, std::string("cannot decode the ") + type + " image: " + (why ? why : "unknown") + " (truncated or damaged?)");
    }
    auto out = std::make_shared<GltfImage>();
    out->width = w2, out->height = h2;
    out->rgba.assign(pixels, pixels + std::size_t(width) * std::size_t(height) * 4);
    stbi_image_free(pixels);
    return cache_[index] = out;
}

std::optional<GltfTexture> GltfImages::texture(const json& owner, const char* key, const std::string& w_owner, bool srgb) {
    if (!owner.is_object() || !owner.contains(key)) return std::nullopt;
    const std::string w = w_owner + "." + key;
    const json& info = owner.at(key);
    if (!info.is_object()) r_.fail(w, "expected an object");
    if (!info.contains("index")) r_.fail(w, "missing key 'index'");
    if (count(r_, info, w, "texCoord", 0) != 0)
        r_.fail(w + ".texCoord", "only TEXCOORD_0 is read (texCoord 0), got " + info.at("texCoord").dump());
    if (info.contains("extensions") && info.at("extensions").is_object() && info.at("extensions").contains("KHR_texture_transform"))
        r_.fail(w + ".extensions.KHR_texture_transform", "texture transforms are not read");
    const std::uint64_t t = count(r_, info, w, "index", 0);
    const json& tex = element(r_, doc_, "textures", t, w + ".index");
    const std::string wt = "textures[" + std::to_string(t) + "]";
    if (!tex.contains("source")) r_.fail(wt, "missing key 'source' (image extensions such as KTX2 are not read)");
    GltfTexture out;
    out.srgb = srgb;
    out.image = image(count(r_, tex, wt, "source", 0), wt + ".source");
    if (tex.contains("sampler")) {
        const std::uint64_t s = count(r_, tex, wt, "sampler", 0);
        const json& sampler = element(r_, doc_, "samplers", s, wt + ".sampler");
        const std::string ws = "samplers[" + std::to_string(s) + "]";
        auto wrap = [&](const char* k) {
            const std::uint64_t v = count(r_, sampler, ws, k, 10497);
            if (v != 10497 && v != 33071 && v != 33648) r_.fail(ws + "." + k, "expected 10497, 33071 or 33648, got " + std::to_string(v));
            return GltfWrap(v);
        };
        out.wrap_s = wrap("wrapS"), out.wrap_t = wrap("wrapT");
        const std::uint64_t mag = count(r_, sampler, ws, "magFilter", 9729), min = count(r_, sampler, ws, "minFilter", 9987);
        if (mag != 9728 && mag != 9729) r_.fail(ws + ".magFilter", "expected 9728 or 9729, got " + std::to_string(mag));
        if (min != 9728 && min != 9729 && (min < 9984 || min > 9987))
            r_.fail(ws + ".minFilter", "expected 9728, 9729 or 9984-9987, got " + std::to_string(min));
        out.nearest = mag == 9728;
        out.min_filter = int(min);
    }
    if (gltf_mipmapped(out.min_filter)) {  // no sampler: 9987, as the raster frame's default
        auto& chain = chains_[{count(r_, tex, wt, "source", 0), srgb}];
        if (!chain) chain = std::make_shared<const std::vector<GltfImage>>(gltf_mip_chain(*out.image, srgb));
        out.mips = chain;
    }
    return out;
}

}  // namespace hbrdf::render::detail
