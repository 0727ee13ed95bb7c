// hybridbrdf renderer — RGB float images and the files they come from or go to.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "hybridbrdf/text.hpp"

namespace hbrdf::render {

/// A file that cannot be read or written, or a malformed scene. what() is
/// "<path>: <problem>", one line, like hbrdf::ModelFileError.
class FileError : public std::runtime_error {
public:
    FileError(const std::string& path, const std::string& problem)
        : std::runtime_error(path + ": " + one_line_text(problem)), path_(path), problem_(one_line_text(problem)) {}
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

/// Refuses, before anything opens it, a path that is not a regular file (FileError with
/// python/hybridbrdf/inputs.py's words: "no such file", "is a folder, not a <what>", "is a FIFO,
/// not a regular file", ...): opening a FIFO blocks until a writer comes, and a device such as
/// /dev/zero never ends. `what` names the format ("mesh file").
void check_input_file(const std::string& path, const std::string& what);

/// Reads an equirectangular environment map: OpenEXR (.exr, via tinyexr) or
/// Radiance RGBE (.hdr, via stb_image). Throws FileError naming the file,
/// also when its header declares more than kMaxEnvironmentTexels pixels
/// (checked before any pixel is decoded: a forged header cannot make it
/// allocate what it says), when it is not a regular file, and (.hdr) when its
/// pixel data end before the last scanline ("truncated: scanline K of H").
Image read_image(const std::string& path);

/// An output file written under a temporary name next to its destination,
/// "<path>.tmp<pid>", and moved into place by commit(); the destructor
/// removes the temporary if it was not committed. A render with two outputs
/// stages both, then commits both, so that a failed or cancelled render
/// leaves the previous files untouched.
class StagedFile {
public:
    explicit StagedFile(std::string path);
    StagedFile(StagedFile&& other) noexcept;
    StagedFile(const StagedFile&) = delete;
    StagedFile& operator=(const StagedFile&) = delete;
    StagedFile& operator=(StagedFile&&) = delete;
    ~StagedFile();

    const std::string& path() const { return path_; }
    const std::string& temp_path() const { return temp_; }
    /// Renames the temporary over path(). Throws FileError.
    void commit();

private:
    std::string path_, temp_;
    bool pending_ = true;
};

/// Writes linear float32 RGB OpenEXR to a StagedFile (commit it to finish).
StagedFile stage_exr(const Image& image, const std::string& path);
/// Writes an 8-bit sRGB PNG to a StagedFile: exposure, tone map, then the
/// sRGB OETF (IEC 61966-2-1), rounded to nearest.
StagedFile stage_png(const Image& image, const std::string& path, const PngOptions& options = {});

/// Writes linear float32 RGB OpenEXR. Atomic: stage_exr, then commit, so a
/// failed write never leaves a half-written file. Throws FileError.
void write_exr(const Image& image, const std::string& path);

/// Writes an 8-bit sRGB PNG (stage_png, then commit). Atomic like write_exr.
void write_png(const Image& image, const std::string& path, const PngOptions& options = {});

/// Checks, before a long render, that `path` can be written later: it is not
/// a folder, its folder exists and accepts new files (by creating and removing
/// the temporary a StagedFile would use: the only test that also holds for
/// root, read-only mounts and network file systems). Throws FileError naming
/// the path.
void check_output_path(const std::string& path);

/// The display value in [0, 1] of one linear channel value, as write_png computes it.
float display_value(float linear, const PngOptions& options);

}  // namespace hbrdf::render
