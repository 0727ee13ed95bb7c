// hybridbrdf renderer — the KTX 2.0 reader (render/ktx2.hpp). The order of the checks and their
// words follow python/hybridbrdf/svbrdf/ktx2.py's read_ktx2, so both refuse a file the same way.
#include "hybridbrdf/render/ktx2.hpp"

#include <sys/stat.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <utility>

#include "hybridbrdf/bc.hpp"
#include "hybridbrdf/render/image.hpp"

namespace hbrdf::render {

namespace {

constexpr unsigned char kIdentifier[12] = {0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A};
constexpr std::uint64_t kHeaderBytes = 80, kLevelEntryBytes = 24;
constexpr std::uint32_t kUint32Max = 0xFFFFFFFFu, kFloatMinusOne = 0xBF800000u, kFloatOne = 0x3F800000u;
constexpr std::uint32_t kQualifierLinear = 0x10, kQualifierSigned = 0x40, kQualifierFloat = 0x80, kChannelAlpha = 15;

enum class Kind { Unorm8, Float16, Float32, Block };

// A DFD sample: bitOffset, bitLength - 1, channelType (id and qualifiers), sampleLower, sampleUpper.
struct Sample {
    std::uint32_t offset, length, channel, lower, upper;
};

struct Format {
    std::uint32_t vk;
    const char* name;
    Kind kind;
    bc::BlockFormat block_format;  // Block formats only
    bool srgb;
    std::uint32_t block, block_bytes, type_size;
    int channels;
    std::uint32_t color_model;
    std::vector<Sample> samples;

    std::uint64_t alignment() const {  // lcm(texel block size, 4)
        std::uint64_t a = block_bytes, b = 4;
        while (b) a = std::exchange(b, a % b);
        return std::uint64_t(block_bytes) * 4 / a;
    }
    std::uint64_t level_bytes(std::uint32_t w, std::uint32_t h) const {
        return std::uint64_t((w + block - 1) / block) * ((h + block - 1) / block) * block_bytes;
    }
};

std::vector<Sample> rgba_samples(std::uint32_t bits, std::uint32_t qualifiers, std::uint32_t lower,
                                 std::uint32_t upper, bool srgb) {
    std::vector<Sample> s;
    for (std::uint32_t i = 0; i < 4; ++i) {
        const std::uint32_t channel = i < 3 ? (i | qualifiers) : (kChannelAlpha | qualifiers | (srgb ? kQualifierLinear : 0));
        s.push_back({i * bits, bits - 1, channel, lower, upper});
    }
    return s;
}

// The formats read: the same table as hybridbrdf.svbrdf.ktx2.FORMATS.
const std::vector<Format>& formats() {
    using bc::BlockFormat;
    static const std::vector<Format> table = {
        {37, "R8G8B8A8_UNORM", Kind::Unorm8, BlockFormat::BC1, false, 1, 4, 1, 4, 1, rgba_samples(8, 0, 0, 255, false)},
        {43, "R8G8B8A8_SRGB", Kind::Unorm8, BlockFormat::BC1, true, 1, 4, 1, 4, 1, rgba_samples(8, 0, 0, 255, true)},
        {97, "R16G16B16A16_SFLOAT", Kind::Float16, BlockFormat::BC1, false, 1, 8, 2, 4, 1,
         rgba_samples(16, kQualifierFloat | kQualifierSigned, kFloatMinusOne, kFloatOne, false)},
        {109, "R32G32B32A32_SFLOAT", Kind::Float32, BlockFormat::BC1, false, 1, 16, 4, 4, 1,
         rgba_samples(32, kQualifierFloat | kQualifierSigned, kFloatMinusOne, kFloatOne, false)},
        {131, "BC1_RGB_UNORM_BLOCK", Kind::Block, BlockFormat::BC1, false, 4, 8, 1, 3, 128, {{0, 63, 0, 0, kUint32Max}}},
        {132, "BC1_RGB_SRGB_BLOCK", Kind::Block, BlockFormat::BC1, true, 4, 8, 1, 3, 128, {{0, 63, 0, 0, kUint32Max}}},
        {139, "BC4_UNORM_BLOCK", Kind::Block, BlockFormat::BC4, false, 4, 8, 1, 1, 131, {{0, 63, 0, 0, kUint32Max}}},
        {141, "BC5_UNORM_BLOCK", Kind::Block, BlockFormat::BC5, false, 4, 16, 1, 2, 132,
         {{0, 63, 0, 0, kUint32Max}, {64, 63, 1, 0, kUint32Max}}},
        {145, "BC7_UNORM_BLOCK", Kind::Block, BlockFormat::BC7, false, 4, 16, 1, 4, 134, {{0, 127, 0, 0, kUint32Max}}},
        {146, "BC7_SRGB_BLOCK", Kind::Block, BlockFormat::BC7, true, 4, 16, 1, 4, 134, {{0, 127, 0, 0, kUint32Max}}},
    };
    return table;
}

std::uint32_t u32(const unsigned char* p) {
    return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}
std::uint64_t u64(const unsigned char* p) { return std::uint64_t(u32(p)) | std::uint64_t(u32(p + 4)) << 32; }

std::uint32_t max_levels(std::uint32_t w, std::uint32_t h) {
    std::uint32_t m = std::max(w, h), n = 0;
    while (m) ++n, m >>= 1;
    return n;
}

// The basic descriptor block this reader expects for `f`, as 32-bit words (dfdTotalSize not included).
std::vector<std::uint32_t> dfd_words(const Format& f) {
    const std::uint32_t block_size = 24 + 16 * std::uint32_t(f.samples.size());
    const std::uint32_t dim = f.block - 1;
    std::vector<std::uint32_t> w = {0, 2u | block_size << 16, f.color_model | 1u << 8 | (f.srgb ? 2u : 1u) << 16,
                                    dim | dim << 8, f.block_bytes, 0};
    for (const Sample& s : f.samples) {
        w.insert(w.end(), {s.offset | s.length << 16 | s.channel << 24, 0, s.lower, s.upper});
    }
    return w;
}

// The fields compared, named as the specification names them (hybridbrdf.svbrdf.ktx2.dfd_fields).
std::vector<std::pair<std::string, std::uint32_t>> dfd_fields(const std::vector<std::uint32_t>& w) {
    std::vector<std::pair<std::string, std::uint32_t>> f = {
        {"vendorId", w[0] & 0x1FFFF}, {"descriptorType", w[0] >> 17}, {"versionNumber", w[1] & 0xFFFF},
        {"descriptorBlockSize", w[1] >> 16}, {"colorModel", w[2] & 0xFF}, {"transferFunction", (w[2] >> 16) & 0xFF},
        {"texelBlockDimension", w[3]}, {"bytesPlane0..3", w[4]}, {"bytesPlane4..7", w[5]}};
    for (std::size_t k = 0; 6 + 4 * k + 3 < w.size(); ++k) {
        const std::uint32_t* s = &w[6 + 4 * k];
        const std::string p = "sample " + std::to_string(k) + " ";
        f.insert(f.end(), {{p + "bitOffset", s[0] & 0xFFFF}, {p + "bitLength", (s[0] >> 16) & 0xFF},
                           {p + "channelType", s[0] >> 24}, {p + "samplePosition", s[1]},
                           {p + "sampleLower", s[2]}, {p + "sampleUpper", s[3]}});
    }
    return f;
}

float half_to_float(std::uint16_t h) {
    const int exponent = (h >> 10) & 31, mantissa = h & 1023;
    float value;
    if (exponent == 0) value = std::ldexp(float(mantissa), -24);
    else if (exponent == 31) value = mantissa ? NAN : INFINITY;
    else value = std::ldexp(float(mantissa | 1024), exponent - 25);
    return (h & 0x8000) ? -value : value;
}

// Reads the file's ranges, each checked against its length first (a short read is "truncated").
class Reader {
public:
    explicit Reader(const std::string& path) : path_(path), file_(std::fopen(path.c_str(), "rb"), &std::fclose) {
        if (!file_) fail("cannot read the KTX2 file: " + std::string(std::strerror(errno)));
        struct stat st {};
        if (::fstat(::fileno(file_.get()), &st) != 0) fail("cannot read the KTX2 file: " + std::string(std::strerror(errno)));
        size_ = std::uint64_t(st.st_size);
    }
    [[noreturn]] void fail(const std::string& problem) const { throw FileError(path_, problem); }
    std::uint64_t size() const { return size_; }
    std::vector<unsigned char> read(std::uint64_t offset, std::uint64_t length, const std::string& truncated) {
        std::vector<unsigned char> bytes(length);
        if (std::fseek(file_.get(), long(offset), SEEK_SET) != 0 ||
            std::fread(bytes.data(), 1, length, file_.get()) != length)
            fail(truncated);
        return bytes;
    }

private:
    std::string path_;
    std::unique_ptr<std::FILE, decltype(&std::fclose)> file_;
    std::uint64_t size_ = 0;
};

}  // namespace

namespace {

const Format& check_header(const Reader& r, const unsigned char* head, std::uint32_t* count) {
    const std::uint32_t vk = u32(head + 12), type_size = u32(head + 16), w = u32(head + 20), h = u32(head + 24);
    const std::uint32_t depth = u32(head + 28), layers = u32(head + 32), faces = u32(head + 36);
    const std::uint32_t levels = u32(head + 40), scheme = u32(head + 44);
    const Format* f = nullptr;
    for (const Format& candidate : formats())
        if (candidate.vk == vk) f = &candidate;
    if (!f) r.fail("vkFormat " + std::to_string(vk) + " is not supported (docs/TEXTURES.md lists the formats read)");
    if (type_size != f->type_size)
        r.fail("typeSize " + std::to_string(type_size) + " does not match " + f->name + " (needs " +
               std::to_string(f->type_size) + ")");
    if (w < 1 || w > kMaxKtx2Side || h < 1 || h > kMaxKtx2Side)
        r.fail("pixelWidth x pixelHeight " + std::to_string(w) + " x " + std::to_string(h) + " outside 1.." +
               std::to_string(kMaxKtx2Side));
    if (depth != 0 || layers != 0 || faces != 1)
        r.fail("pixelDepth " + std::to_string(depth) + ", layerCount " + std::to_string(layers) + ", faceCount " +
               std::to_string(faces) + ": only a single 2D texture (0, 0, 1) is read");
    if (scheme != 0) r.fail("supercompressionScheme " + std::to_string(scheme) + " is not supported (only 0, none)");
    if (levels == 0 && f->block > 1)
        r.fail(std::string("levelCount 0 (levels left to the loader) is not allowed for ") + f->name);
    if (levels > max_levels(w, h))
        r.fail("levelCount " + std::to_string(levels) + " exceeds the " + std::to_string(max_levels(w, h)) +
               " levels of a " + std::to_string(w) + " x " + std::to_string(h) + " texture");
    *count = std::max<std::uint32_t>(levels, 1);
    return *f;
}

void check_dfd(const Reader& r, const std::vector<unsigned char>& data, const Format& f) {
    const std::uint32_t total = u32(data.data());
    if (total != data.size())
        r.fail("data format descriptor: dfdTotalSize " + std::to_string(total) + " differs from dfdByteLength " +
               std::to_string(data.size()));
    const std::vector<std::uint32_t> want = dfd_words(f);
    if (data.size() < 4 + 4 * want.size())
        r.fail("data format descriptor: " + std::to_string(data.size()) + " bytes, " + f.name + " needs " +
               std::to_string(4 + 4 * want.size()));
    std::vector<std::uint32_t> got(want.size());
    for (std::size_t i = 0; i < got.size(); ++i) got[i] = u32(data.data() + 4 + 4 * i);
    const auto g = dfd_fields(got), e = dfd_fields(want);
    for (std::size_t i = 0; i < g.size(); ++i) {
        if (g[i].second == e[i].second) continue;
        std::string problem = "data format descriptor: " + g[i].first + " " + std::to_string(g[i].second) + ", " +
                              f.name + " needs " + std::to_string(e[i].second);
        if (g[i].first == "transferFunction") problem += f.srgb ? " (sRGB)" : " (linear)";
        r.fail(problem);
    }
}

// Checks the DFD, the key/value data and the global data; returns where they end.
std::uint64_t check_metadata(Reader& r, const unsigned char* head, std::uint64_t start, const Format& f) {
    const std::uint64_t size = r.size();
    const std::uint64_t dfd_offset = u32(head + 48), dfd_length = u32(head + 52);
    const std::uint64_t kvd_offset = u32(head + 56), kvd_length = u32(head + 60), sgd_length = u64(head + 72);
    if (dfd_offset < start || dfd_length < 4 || dfd_offset + dfd_length > size)
        r.fail("data format descriptor at " + std::to_string(dfd_offset) + ", " + std::to_string(dfd_length) +
               " bytes, lies outside the file's " + std::to_string(size) + " bytes past the level index");
    if (dfd_length > 4 + 4 * (6 + 4 * 16))
        r.fail("data format descriptor: dfdByteLength " + std::to_string(dfd_length) +
               " is larger than any format read needs");
    check_dfd(r, r.read(dfd_offset, dfd_length, "truncated while reading the data format descriptor"), f);
    std::uint64_t end = dfd_offset + dfd_length;
    if (kvd_length) {
        if (kvd_offset < start || kvd_offset + kvd_length > size)
            r.fail("key/value data at " + std::to_string(kvd_offset) + ", " + std::to_string(kvd_length) +
                   " bytes, lies outside the file's " + std::to_string(size) + " bytes past the level index");
        if (kvd_length > (1u << 20))
            r.fail("key/value data of " + std::to_string(kvd_length) + " bytes (at most 1 MiB is read)");
        const std::vector<unsigned char> kvd = r.read(kvd_offset, kvd_length, "truncated while reading the key/value data");
        std::uint64_t position = 0;
        while (position < kvd_length) {
            const std::uint64_t entry = position + 4 <= kvd_length ? u32(kvd.data() + position) : kvd_length;
            if (position + 4 + entry > kvd_length)
                r.fail("key/value data: the entry at " + std::to_string(kvd_offset + position) +
                       " runs past the key/value data's end");
            position += 4 + entry + ((4 - entry % 4) % 4);
        }
        end = std::max(end, kvd_offset + kvd_length);
    }
    if (sgd_length) r.fail("sgdByteLength " + std::to_string(sgd_length) + ": no supercompression takes global data");
    return end;
}

struct LevelEntry {
    std::uint64_t offset, length, uncompressed;
    std::uint32_t width, height;
};

void check_levels(const Reader& r, const std::vector<LevelEntry>& levels, std::uint64_t metadata_end, const Format& f) {
    const std::uint64_t size = r.size();
    for (std::size_t p = 0; p < levels.size(); ++p) {
        const LevelEntry& l = levels[p];
        const std::string level = "level " + std::to_string(p) + ": ";
        const std::uint64_t expected = f.level_bytes(l.width, l.height);
        if (l.length != expected)
            r.fail(level + "byteLength " + std::to_string(l.length) + ", a " + std::to_string(l.width) + " x " +
                   std::to_string(l.height) + " " + f.name + " level is " + std::to_string(expected) + " bytes");
        if (l.uncompressed != l.length)
            r.fail(level + "uncompressedByteLength " + std::to_string(l.uncompressed) + " differs from byteLength " +
                   std::to_string(l.length));
        if (l.offset > size || l.length > size - l.offset)
            r.fail(level + "byteOffset " + std::to_string(l.offset) + " + byteLength " + std::to_string(l.length) +
                   " lies outside the file's " + std::to_string(size) + " bytes");
        if (l.offset % f.alignment())
            r.fail(level + "byteOffset " + std::to_string(l.offset) + " is not a multiple of " + std::to_string(f.alignment()));
        if (l.offset < metadata_end)
            r.fail(level + "byteOffset " + std::to_string(l.offset) + " lies inside the header and metadata (which end at " +
                   std::to_string(metadata_end) + ")");
        if (p > 0 && l.offset + l.length > levels[p - 1].offset)
            r.fail(level + "stored after level " + std::to_string(p - 1) + " (KTX2 stores the smallest level first)");
    }
}

Ktx2Level decode_level(const std::vector<unsigned char>& data, const Format& f, std::uint32_t w, std::uint32_t h) {
    Ktx2Level level;
    level.width = w;
    level.height = h;
    const std::size_t texels = std::size_t(w) * h;
    level.stored.assign(data.begin(), data.end());
    if (f.kind == Kind::Block) {
        level.bytes.resize(texels * std::size_t(f.channels));
        bc::decode_level(f.block_format, data.data(), w, h, level.bytes.data());
    } else if (f.kind == Kind::Unorm8) {
        level.bytes.assign(data.begin(), data.end());
    } else if (f.kind == Kind::Float16) {
        level.floats.resize(4 * texels);
        for (std::size_t i = 0; i < 4 * texels; ++i)
            level.floats[i] = half_to_float(std::uint16_t(data[2 * i] | data[2 * i + 1] << 8));
    } else {
        level.floats.resize(4 * texels);
        for (std::size_t i = 0; i < 4 * texels; ++i) {
            const std::uint32_t bits = u32(data.data() + 4 * i);
            std::memcpy(&level.floats[i], &bits, 4);
        }
    }
    return level;
}

}  // namespace

Ktx2Texture read_ktx2(const std::string& path) {
    check_input_file(path, "KTX2 file");
    Reader r(path);
    if (r.size() < kHeaderBytes)
        r.fail("truncated: " + std::to_string(r.size()) + " bytes, a KTX2 header needs " + std::to_string(kHeaderBytes));
    const std::vector<unsigned char> head = r.read(0, kHeaderBytes, "truncated while reading the header");
    if (std::memcmp(head.data(), kIdentifier, 12) != 0)
        r.fail("not a KTX 2.0 file (its first 12 bytes are not the KTX 2.0 identifier)");
    std::uint32_t count = 0;
    const Format& f = check_header(r, head.data(), &count);
    const std::uint32_t w = u32(head.data() + 20), h = u32(head.data() + 24);
    const std::uint64_t index_end = kHeaderBytes + kLevelEntryBytes * count;
    if (index_end > r.size())
        r.fail("truncated: " + std::to_string(r.size()) + " bytes, the level index ends at " + std::to_string(index_end));
    const std::vector<unsigned char> index = r.read(kHeaderBytes, index_end - kHeaderBytes, "truncated");
    std::vector<LevelEntry> levels(count);
    for (std::uint32_t p = 0; p < count; ++p) {
        const unsigned char* e = index.data() + kLevelEntryBytes * p;
        levels[p] = {u64(e), u64(e + 8), u64(e + 16), std::max(1u, w >> p), std::max(1u, h >> p)};
    }
    const std::uint64_t metadata_end = check_metadata(r, head.data(), index_end, f);
    check_levels(r, levels, metadata_end, f);
    Ktx2Texture texture;
    texture.vk_format = f.vk;
    texture.format_name = f.name;
    texture.width = w;
    texture.height = h;
    texture.channels = f.channels;
    texture.srgb = f.srgb;
    texture.is_float = f.kind == Kind::Float16 || f.kind == Kind::Float32;
    for (std::uint32_t p = 0; p < count; ++p) {
        const std::vector<unsigned char> data =
            r.read(levels[p].offset, levels[p].length, "truncated while reading level " + std::to_string(p));
        texture.levels.push_back(decode_level(data, f, levels[p].width, levels[p].height));
    }
    return texture;
}

}  // namespace hbrdf::render
