// hybridbrdf renderer — image files: EXR in and out (tinyexr), HDR in and PNG
// out (stb_image, stb_image_write), written atomically.
#include "hybridbrdf/render/image.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <vector>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <utility>

#include <stb/stb_image.h>
#include <stb/stb_image_write.h>
#include <tinyexr.h>

#include "hybridbrdf/render/limits.hpp"

namespace hbrdf::render {

namespace {

std::string lower_extension(const std::string& path) {
    const auto dot = path.find_last_of('.');
    if (dot == std::string::npos) return "";
    std::string ext = path.substr(dot);
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return ext;
}

std::string temp_name(const std::string& path) { return path + ".tmp" + std::to_string(::getpid()); }

// Writes `bytes` to the staged temporary of `file`, checking every write, the fsync and the close:
// a full disk must be an error naming the file, never a truncated file renamed into place (stdio's
// fclose() reports the last buffered bytes' ENOSPC, and tinyexr and stb_image_write never looked).
// A stale temporary of this name (a killed run with our pid) is removed first and the new one is
// created exclusively, without following a symlink planted at its name. The temporary takes the
// mode of the file it will replace (a 0640 output stays 0640); a new file gets 0666 minus the umask,
// as fopen() gave it. On failure the caller's StagedFile removes the temporary.
void write_staged(const StagedFile& file, const unsigned char* bytes, std::size_t size) {
    const std::string& path = file.path();
    const std::string& tmp = file.temp_path();
    auto fail = [&](const char* step, int err) {
        throw FileError(path, std::string("cannot ") + step + " the file: " + std::strerror(err));
    };
    if (::unlink(tmp.c_str()) != 0 && errno != ENOENT) fail("replace a stale temporary of", errno);
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
    if (fd < 0) fail("create", errno);
    auto fail_open = [&](const char* step) {
        const int err = errno;
        ::close(fd);
        fail(step, err);
    };
    struct stat old {};
    if (::stat(path.c_str(), &old) == 0 && S_ISREG(old.st_mode) && ::fchmod(fd, old.st_mode & 07777) != 0)
        fail_open("keep the permissions of");
    const unsigned char* p = bytes;
    std::size_t left = size;
    while (left > 0) {
        const ssize_t n = ::write(fd, p, left);
        if (n < 0) {
            if (errno == EINTR) continue;
            fail_open("write");
        }
        if (n == 0) {  // no progress and no errno: treat as a full device
            errno = ENOSPC;
            fail_open("write");
        }
        p += n;
        left -= std::size_t(n);
    }
    if (::fsync(fd) != 0) fail_open("flush (fsync)");
    if (::close(fd) != 0) fail("close", errno);
}

// Stages `bytes` (an encoded image) as the next version of `path`.
StagedFile stage_bytes(const std::string& path, const unsigned char* bytes, std::size_t size) {
    StagedFile file(path);
    write_staged(file, bytes, size);
    return file;
}

// Float RGB as tinyexr's SaveEXR lays it out (B, G, R float32 channels; ZIP from 16 x 16 up),
// encoded in memory so that the bytes are written, and checked, by write_staged. The buffer is
// tinyexr's own (malloc'ed), not copied: at the film limit it is ~1.6 GB.
std::unique_ptr<unsigned char, decltype(&std::free)> encode_exr(const Image& image, const std::string& path,
                                                                std::size_t* size) {
    const std::size_t n = std::size_t(image.width) * std::size_t(image.height);
    std::vector<float> planes[3];
    for (int c = 0; c < 3; ++c) {
        planes[c].resize(n);
        for (std::size_t i = 0; i < n; ++i) planes[c][i] = image.rgb[3 * i + std::size_t(c)];
    }
    float* channels[3] = {planes[2].data(), planes[1].data(), planes[0].data()};  // B, G, R: viewers expect it
    EXRImage exr;
    InitEXRImage(&exr);
    exr.num_channels = 3;
    exr.images = reinterpret_cast<unsigned char**>(channels);
    exr.width = image.width;
    exr.height = image.height;
    EXRHeader header;
    InitEXRHeader(&header);
    header.compression_type =
        (image.width < 16 && image.height < 16) ? TINYEXR_COMPRESSIONTYPE_NONE : TINYEXR_COMPRESSIONTYPE_ZIP;
    EXRChannelInfo info[3] = {};
    const char* names[3] = {"B", "G", "R"};
    int pixel_types[3], requested[3];
    for (int c = 0; c < 3; ++c) {
        std::strncpy(info[c].name, names[c], sizeof info[c].name - 1);
        pixel_types[c] = requested[c] = TINYEXR_PIXELTYPE_FLOAT;  // float32 in and out: what a reference needs
    }
    header.num_channels = 3;
    header.channels = info;
    header.pixel_types = pixel_types;
    header.requested_pixel_types = requested;
    unsigned char* memory = nullptr;
    const char* err = nullptr;
    *size = SaveEXRImageToMemory(&exr, &header, &memory, &err);
    if (*size == 0 || !memory) {
        std::string problem = err ? err : "cannot encode the OpenEXR file";
        if (err) FreeEXRErrorMessage(err);
        std::free(memory);
        throw FileError(path, problem);
    }
    return {memory, &std::free};
}

// The pixel count an image file's header declares, or {0, 0} when the header
// cannot be read (the full read then reports why).
std::pair<std::int64_t, std::int64_t> declared_size(const std::string& path, const std::string& ext) {
    if (ext == ".exr") {
        EXRVersion version;
        if (ParseEXRVersionFromFile(&version, path.c_str()) != TINYEXR_SUCCESS || version.multipart) return {0, 0};
        EXRHeader header;
        InitEXRHeader(&header);
        const char* err = nullptr;
        std::pair<std::int64_t, std::int64_t> size{0, 0};
        if (ParseEXRHeaderFromFile(&header, &version, path.c_str(), &err) == TINYEXR_SUCCESS) {
            const EXRBox2i& w = header.data_window;
            size = {std::int64_t(w.max_x) - w.min_x + 1, std::int64_t(w.max_y) - w.min_y + 1};
            FreeEXRHeader(&header);
        }
        if (err) FreeEXRErrorMessage(err);
        return size;
    }
    int w = 0, h = 0, comp = 0;
    if (!stbi_info(path.c_str(), &w, &h, &comp)) return {0, 0};
    return {w, h};
}

// A header may claim any size; refuse before decoding allocates it.
void check_declared_size(const std::string& path, const std::string& ext) {
    const auto [w, h] = declared_size(path, ext);
    const std::string problem = check_image_size(w, h, kMaxEnvironmentTexels, kEnvironmentBytesPerTexel, "of memory");
    if (!problem.empty()) throw FileError(path, "the image is " + problem);
}

// A byte source over a file with a 64 KB buffer, for the walk below; get() is -1 at the end.
class ByteReader {
public:
    explicit ByteReader(std::FILE* f) : f_(f), buf_(1 << 16) {}
    int get() {
        if (pos_ == len_) {
            len_ = std::fread(buf_.data(), 1, buf_.size(), f_);
            pos_ = 0;
            if (len_ == 0) return -1;
        }
        return buf_[pos_++];
    }
    // Skips n bytes; false when the file ends first.
    bool skip(std::uint64_t n) {
        while (n > 0) {
            if (pos_ == len_) {
                len_ = std::fread(buf_.data(), 1, buf_.size(), f_);
                pos_ = 0;
                if (len_ == 0) return false;
            }
            const std::uint64_t take = std::min<std::uint64_t>(n, len_ - pos_);
            pos_ += std::size_t(take);
            n -= take;
        }
        return true;
    }

private:
    std::FILE* f_;
    std::vector<unsigned char> buf_;
    std::size_t pos_ = 0, len_ = 0;
};

// Walks a Radiance RGBE file's pixel data as stb_image decodes it, without decoding, and says
// where it ends too soon: stb_image reads past the end as zeros (a truncated map renders with
// black texels, a 41-byte header declaring 4096 x 32768 was a black sky), and a run-length
// scanline cut short makes its decoder loop forever on those zeros. Empty when the data are
// all there; other damage is left to the decoder's own messages. The walk follows stb's
// layout rules exactly: widths below 8 or from 32768 are flat (4 bytes a pixel); otherwise each
// scanline starts 2 2 hi lo, then four channels of runs (count > 128: a repeated byte) and
// dumps (count <= 128: that many bytes); a scanline that does not start 2 2 switches the rest
// of the image to flat pixels, from pixel 1 of the first scanline on (stb's `goto`).
std::string hdr_truncation(const std::string& path) {
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) return "";  // the decoder reports why it cannot open it
    ByteReader in(f);
    // Lines are bounded: a file of zeros (a sparse file) has no '\n', and an unbounded line
    // grew until std::bad_alloc (1 TiB file) or walked the whole file.
    constexpr std::size_t kMaxHeaderLine = 1 << 16;
    bool overlong = false;
    auto line = [&](std::string& s) {  // stb's header token: up to '\n'; false at the end
        s.clear();
        for (int c; (c = in.get()) >= 0;) {
            if (c == '\n') return true;
            if (s.size() == kMaxHeaderLine) {
                overlong = true;
                return false;
            }
            s.push_back(char(c));
        }
        return !s.empty();
    };
    std::string s;
    bool ok = line(s) && (s == "#?RADIANCE" || s == "#?RGBE");
    while (ok && line(s) && !s.empty()) {
    }
    if (ok && overlong) {
        std::fclose(f);
        return "header line longer than " + std::to_string(kMaxHeaderLine) + " bytes";
    }
    long long w = 0, h = 0;
    if (!(ok && line(s) && std::sscanf(s.c_str(), "-Y %lld +X %lld", &h, &w) == 2 && w > 0 && h > 0)) {
        std::fclose(f);
        return "";  // not a header the decoder accepts: it says so
    }
    const std::int64_t width = w, height = h;
    std::string problem;
    auto flat_from = [&](std::int64_t pixel) {  // 4 bytes per pixel from `pixel` on
        for (std::int64_t row = pixel / width; row < height && problem.empty(); ++row) {
            const std::int64_t first = std::max(pixel, row * width);
            if (!in.skip(std::uint64_t(4) * std::uint64_t((row + 1) * width - first)))
                problem = "truncated: scanline " + std::to_string(row + 1) + " of " + std::to_string(height);
        }
    };
    if (width < 8 || width >= 32768) {
        flat_from(0);
    } else {
        for (std::int64_t row = 0; row < height && problem.empty(); ++row) {
            const std::string cut = "truncated: scanline " + std::to_string(row + 1) + " of " + std::to_string(height);
            int head[4];
            for (int& b : head) b = in.get();
            if (head[3] < 0) {
                problem = cut;
                break;
            }
            if (head[0] != 2 || head[1] != 2 || (head[2] & 0x80)) {
                flat_from(1);  // this scanline's 4 bytes were pixel 0
                break;
            }
            if (((head[2] << 8) | head[3]) != width) break;  // the decoder's "invalid decoded scanline length"
            for (int k = 0; k < 4 && problem.empty(); ++k) {
                for (std::int64_t i = 0; i < width;) {
                    const int count = in.get();
                    if (count < 0) {
                        problem = cut;
                        break;
                    }
                    if (count > 128) {
                        if (in.get() < 0) problem = cut;
                        i += count - 128;
                    } else {
                        if (!in.skip(std::uint64_t(count))) problem = cut;
                        i += count;
                    }
                    if (!problem.empty()) break;
                    if (i > width) {  // the decoder's "bad RLE data": its message, not a walk gone astray
                        std::fclose(f);
                        return "";
                    }
                }
            }
        }
    }
    std::fclose(f);
    return problem;
}

void check_image(const Image& image, const std::string& path) {
    if (image.width <= 0 || image.height <= 0 ||
        image.rgb.size() != std::size_t(image.width) * std::size_t(image.height) * 3)
        throw FileError(path, "image has no pixels or an inconsistent size");
}

float srgb_oetf(float x) {
    return x <= 0.0031308f ? 12.92f * x : 1.055f * std::pow(x, 1.0f / 2.4f) - 0.055f;
}

}  // namespace

void check_input_file(const std::string& path, const std::string& what) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) {  // follows symlinks: a link to /dev/zero is a device
        if (errno == ENOENT) throw FileError(path, "no such file");
        throw FileError(path, "cannot read the " + what + ": " + std::strerror(errno));
    }
    if (S_ISDIR(st.st_mode)) throw FileError(path, "is a folder, not a " + what);
    if (S_ISFIFO(st.st_mode)) throw FileError(path, "is a FIFO, not a regular file");
    if (S_ISCHR(st.st_mode)) throw FileError(path, "is a character device, not a regular file");
    if (S_ISBLK(st.st_mode)) throw FileError(path, "is a block device, not a regular file");
    if (S_ISSOCK(st.st_mode)) throw FileError(path, "is a socket, not a regular file");
    if (!S_ISREG(st.st_mode)) throw FileError(path, "is not a regular file");
}

Image read_image(const std::string& path) {
    const std::string ext = lower_extension(path);
    check_input_file(path, "image file");  // before anything opens it, whatever its name
    if (ext == ".exr" || ext == ".hdr") check_declared_size(path, ext);
    if (ext == ".hdr") {
        const std::string truncated = hdr_truncation(path);
        if (!truncated.empty()) throw FileError(path, truncated);
    }
    if (ext == ".exr") {
        float* rgba = nullptr;
        int w = 0, h = 0;
        const char* err = nullptr;
        if (LoadEXR(&rgba, &w, &h, path.c_str(), &err) != TINYEXR_SUCCESS) {
            std::string problem = err ? err : "cannot read the OpenEXR file";
            if (err) FreeEXRErrorMessage(err);
            throw FileError(path, problem);
        }
        Image img(w, h);
        for (std::size_t i = 0; i < std::size_t(w) * std::size_t(h); ++i)
            for (int c = 0; c < 3; ++c) img.rgb[i * 3 + c] = rgba[i * 4 + c];
        std::free(rgba);
        return img;
    }
    if (ext == ".hdr") {
        int w = 0, h = 0, comp = 0;
        float* data = stbi_loadf(path.c_str(), &w, &h, &comp, 3);
        if (!data) {
            const char* reason = stbi_failure_reason();
            throw FileError(path, std::string("cannot read the Radiance HDR file: ") + (reason ? reason : "unknown"));
        }
        Image img(w, h);
        std::copy(data, data + std::size_t(w) * std::size_t(h) * 3, img.rgb.begin());
        stbi_image_free(data);
        return img;
    }
    throw FileError(path, "unsupported image format '" + ext + "'; expected .exr or .hdr");
}

StagedFile::StagedFile(std::string path) : path_(std::move(path)), temp_(temp_name(path_)) {}

StagedFile::StagedFile(StagedFile&& other) noexcept
    : path_(std::move(other.path_)), temp_(std::move(other.temp_)), pending_(other.pending_) {
    other.pending_ = false;
}

StagedFile::~StagedFile() {
    if (pending_) std::remove(temp_.c_str());
}

void StagedFile::commit() {
    if (!pending_) return;
    if (std::rename(temp_.c_str(), path_.c_str()) != 0)
        throw FileError(path_, std::string("cannot rename the temporary file into place: ") + std::strerror(errno));
    pending_ = false;
    // The rename itself reaches the disk with its folder's fsync; a file system that cannot fsync a
    // folder (EINVAL) has nothing more to flush, and the file's bytes were fsynced already.
    const auto slash = path_.find_last_of('/');
    const std::string folder = slash == std::string::npos ? "." : slash == 0 ? "/" : path_.substr(0, slash);
    const int dir = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dir >= 0) {
        ::fsync(dir);
        ::close(dir);
    }
}

void check_output_path(const std::string& path) {
    if (path.empty()) throw FileError(path, "empty output file name");
    struct stat st;
    if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) throw FileError(path, "is a folder, expected a file name");
    const std::string tmp = temp_name(path);
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) {
        const auto slash = path.find_last_of('/');
        const std::string folder = slash == std::string::npos ? "." : slash == 0 ? "/" : path.substr(0, slash);
        throw FileError(path, "cannot create files in " + folder + " (" + std::strerror(errno) + ")");
    }
    ::close(fd);
    std::remove(tmp.c_str());
}

StagedFile stage_exr(const Image& image, const std::string& path) {
    check_image(image, path);
    std::size_t size = 0;
    const auto bytes = encode_exr(image, path, &size);
    return stage_bytes(path, bytes.get(), size);
}

void write_exr(const Image& image, const std::string& path) { stage_exr(image, path).commit(); }

float display_value(float linear, const PngOptions& options) {
    float x = linear * std::exp2(options.exposure);
    if (!(x > 0.0f)) return 0.0f;  // negatives and NaN
    if (options.tonemap == ToneMap::Aces) {
        // Narkowicz 2015 fit of the ACES reference rendering transform (per channel).
        x = (x * (2.51f * x + 0.03f)) / (x * (2.43f * x + 0.59f) + 0.14f);
    }
    return srgb_oetf(std::min(x, 1.0f));
}

StagedFile stage_png(const Image& image, const std::string& path, const PngOptions& options) {
    check_image(image, path);
    std::vector<unsigned char> bytes(image.rgb.size());
    for (std::size_t i = 0; i < bytes.size(); ++i)
        bytes[i] = (unsigned char)(std::lround(display_value(image.rgb[i], options) * 255.0f));
    std::vector<unsigned char> png;
    const auto append = [](void* context, void* data, int size) {
        auto* out = static_cast<std::vector<unsigned char>*>(context);
        out->insert(out->end(), static_cast<unsigned char*>(data), static_cast<unsigned char*>(data) + size);
    };
    if (!stbi_write_png_to_func(append, &png, image.width, image.height, 3, bytes.data(), image.width * 3))
        throw FileError(path, "cannot encode the PNG file");
    return stage_bytes(path, png.data(), png.size());
}

void write_png(const Image& image, const std::string& path, const PngOptions& options) {
    stage_png(image, path, options).commit();
}

}  // namespace hbrdf::render
