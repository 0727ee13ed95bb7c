// hybridbrdf renderer — image files: EXR in and out (tinyexr), HDR in and PNG
// out (stb_image, stb_image_write), written atomically.
#include "hybridbrdf/render/image.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include <stb/stb_image.h>
#include <stb/stb_image_write.h>
#include <tinyexr.h>

namespace hbrdf::render {

namespace {

std::string lower_extension(const std::string& path) {
    const auto dot = path.find_last_of('.');
    if (dot == std::string::npos) return "";
    std::string ext = path.substr(dot);
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return ext;
}

// Writes through `write_to(tmp)` and renames tmp over path; removes tmp on failure.
template <typename F> void write_atomically(const std::string& path, F&& write_to) {
    const std::string tmp = path + ".tmp" + std::to_string(::getpid());
    std::string problem;
    try {
        write_to(tmp);
    } catch (...) {
        std::remove(tmp.c_str());
        throw;
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        problem = std::string("cannot rename the temporary file into place: ") + std::strerror(errno);
        std::remove(tmp.c_str());
        throw FileError(path, problem);
    }
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

void write_exr(const Image& image, const std::string& path) {
    check_image(image, path);
    write_atomically(path, [&](const std::string& tmp) {
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

float display_value(float linear, const PngOptions& options) {
    float x = linear * std::exp2(options.exposure);
    if (!(x > 0.0f)) return 0.0f;  // negatives and NaN
    if (options.tonemap == ToneMap::Aces) {
        // Narkowicz 2015 fit of the ACES reference rendering transform (per channel).
        x = (x * (2.51f * x + 0.03f)) / (x * (2.43f * x + 0.59f) + 0.14f);
    }
    return srgb_oetf(std::min(x, 1.0f));
}

void write_png(const Image& image, const std::string& path, const PngOptions& options) {
    check_image(image, path);
    std::vector<unsigned char> bytes(image.rgb.size());
    for (std::size_t i = 0; i < bytes.size(); ++i)
        bytes[i] = (unsigned char)(std::lround(display_value(image.rgb[i], options) * 255.0f));
    write_atomically(path, [&](const std::string& tmp) {
        if (!stbi_write_png(tmp.c_str(), image.width, image.height, 3, bytes.data(), image.width * 3))
            throw FileError(path, "cannot write the PNG file (directory missing or not writable?)");
    });
}

}  // namespace hbrdf::render
