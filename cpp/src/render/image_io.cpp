// hybridbrdf renderer — image files: EXR in and out (tinyexr), HDR in and PNG
// out (stb_image, stb_image_write), written atomically.
#include "hybridbrdf/render/image.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
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

// Writes through `write_to(tmp)` into a StagedFile, which removes tmp on failure.
template <typename F> StagedFile stage(const std::string& path, F&& write_to) {
    StagedFile file(path);
    write_to(file.temp_path());
    return file;
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

void check_image(const Image& image, const std::string& path) {
    if (image.width <= 0 || image.height <= 0 ||
        image.rgb.size() != std::size_t(image.width) * std::size_t(image.height) * 3)
        throw FileError(path, "image has no pixels or an inconsistent size");
}

float srgb_oetf(float x) {
    return x <= 0.0031308f ? 12.92f * x : 1.055f * std::pow(x, 1.0f / 2.4f) - 0.055f;
}

}  // namespace

Image read_image(const std::string& path) {
    const std::string ext = lower_extension(path);
    if (ext == ".exr" || ext == ".hdr") check_declared_size(path, ext);
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
    return stage(path, [&](const std::string& tmp) {
        // tinyexr's SaveEXR takes interleaved float RGB and writes float32
        // channels (save_as_fp16 = 0), which is what a reference needs.
        const char* err = nullptr;
        if (SaveEXR(image.rgb.data(), image.width, image.height, 3, 0, tmp.c_str(), &err) != TINYEXR_SUCCESS) {
            std::string problem = err ? err : "cannot write the OpenEXR file";
            if (err) FreeEXRErrorMessage(err);
            throw FileError(path, problem);
        }
    });
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
    return stage(path, [&](const std::string& tmp) {
        if (!stbi_write_png(tmp.c_str(), image.width, image.height, 3, bytes.data(), image.width * 3))
            throw FileError(path, "cannot write the PNG file (directory missing or not writable?)");
    });
}

void write_png(const Image& image, const std::string& path, const PngOptions& options) {
    stage_png(image, path, options).commit();
}

}  // namespace hbrdf::render
