// hybridbrdf renderer — RGB float images and the files they come from or go to.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

namespace hbrdf::render {

/// A file that cannot be read or written, or a malformed scene. what() is
/// "<path>: <problem>", one line, like hbrdf::ModelFileError.
class FileError : public std::runtime_error {
public:
    FileError(const std::string& path, const std::string& problem)
        : std::runtime_error(path + ": " + problem), path_(path), problem_(problem) {}
    const std::string& path() const { return path_; }
    const std::string& problem() const { return problem_; }

private:
    std::string path_, problem_;
};

/// Linear RGB, float32, row-major from the top-left pixel, 3 floats per pixel.
struct Image {
    int width = 0, height = 0;
    std::vector<float> rgb;

    Image() = default;
    Image(int w, int h) : width(w), height(h), rgb(std::size_t(w) * std::size_t(h) * 3, 0.0f) {}
    float* at(int x, int y) { return rgb.data() + (std::size_t(y) * std::size_t(width) + std::size_t(x)) * 3; }
    const float* at(int x, int y) const {
        return rgb.data() + (std::size_t(y) * std::size_t(width) + std::size_t(x)) * 3;
    }
};

/// Tone mapping of the 8-bit PNG output (EXR output is always linear).
enum class ToneMap { Clamp, Aces };

struct PngOptions {
    float exposure = 0.0f;           ///< stops: the image is multiplied by 2^exposure
    ToneMap tonemap = ToneMap::Clamp; ///< Clamp: clip to [0, 1]; Aces: Narkowicz's ACES fit
};

/// Reads an equirectangular environment map: OpenEXR (.exr, via tinyexr) or
/// Radiance RGBE (.hdr, via stb_image). Throws FileError naming the file.
Image read_image(const std::string& path);

/// Writes linear float32 RGB OpenEXR. Atomic: the data go to "<path>.tmp<pid>"
/// first and are renamed over `path`, so a failed write never leaves a
/// half-written file. Throws FileError.
void write_exr(const Image& image, const std::string& path);

/// Writes an 8-bit sRGB PNG: exposure, tone map, then the sRGB OETF
/// (IEC 61966-2-1), rounded to nearest. Atomic like write_exr.
void write_png(const Image& image, const std::string& path, const PngOptions& options = {});

/// The display value in [0, 1] of one linear channel value, as write_png computes it.
float display_value(float linear, const PngOptions& options);

}  // namespace hbrdf::render
