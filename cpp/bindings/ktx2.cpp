// hybridbrdf._core — the BC block decoders and BC4/BC5 encoder (hybridbrdf/bc.hpp) and the KTX2 reader
// (render/ktx2.hpp): hybridbrdf.svbrdf.ktx2 decodes its levels with the first, and the tests
// compare its reading of a file with the second's (tests/python/test_ktx2.py).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstring>
#include <string>

#include "hybridbrdf/bc.hpp"
#ifdef HBRDF_HAVE_RENDERER
#include "hybridbrdf/render/ktx2.hpp"
#endif

namespace py = pybind11;

namespace {

hbrdf::bc::BlockFormat block_format(const std::string& name) {
    if (name == "bc1") return hbrdf::bc::BlockFormat::BC1;
    if (name == "bc4") return hbrdf::bc::BlockFormat::BC4;
    if (name == "bc5") return hbrdf::bc::BlockFormat::BC5;
    if (name == "bc7") return hbrdf::bc::BlockFormat::BC7;
    throw py::value_error("unknown block format '" + name + "'; expected bc1, bc4, bc5 or bc7");
}

}  // namespace

void bind_ktx2(py::module_& m) {
    m.def(
        "bc_decode_level",
        [](const std::string& format, const py::bytes& blocks, std::uint32_t width, std::uint32_t height) {
            const hbrdf::bc::BlockFormat f = block_format(format);
            if (width < 1 || height < 1 || width > 65536 || height > 65536)
                throw py::value_error("width and height must be in 1..65536");
            const std::string data = blocks;
            const std::size_t need = hbrdf::bc::level_bytes(f, width, height);
            if (data.size() != need)
                throw py::value_error(format + ": " + std::to_string(data.size()) + " bytes of blocks, a " +
                                      std::to_string(width) + " x " + std::to_string(height) + " level has " +
                                      std::to_string(need));
            const int c = hbrdf::bc::block_channels(f);
            py::array_t<std::uint8_t> out({py::ssize_t(height), py::ssize_t(width), py::ssize_t(c)});
            {
                py::gil_scoped_release release;
                hbrdf::bc::decode_level(f, reinterpret_cast<const std::uint8_t*>(data.data()), width, height,
                                        out.mutable_data());
            }
            return out;
        },
        py::arg("format"), py::arg("blocks"), py::arg("width"), py::arg("height"),
        "Decodes a width x height level of BC blocks ('bc1', 'bc4', 'bc5', 'bc7'; rows of blocks from the "
        "top) into uint8 (height, width, C), C = 3, 1, 2, 4.");
    m.def(
        "bc_encode_level",
        [](const std::string& format, py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast> texels) {
            const hbrdf::bc::BlockFormat f = block_format(format);
            if (f != hbrdf::bc::BlockFormat::BC4 && f != hbrdf::bc::BlockFormat::BC5)
                throw py::value_error("bc_encode_level encodes bc4 and bc5, not " + format);
            const int need = hbrdf::bc::block_channels(f);
            if (texels.ndim() != 3 || texels.shape(2) < need || texels.shape(0) < 1 || texels.shape(1) < 1 ||
                texels.shape(0) > 65536 || texels.shape(1) > 65536)
                throw py::value_error(format + ": texels must be uint8 (H, W, C) with H, W in 1..65536 and C >= " +
                                      std::to_string(need));
            const auto h = std::uint32_t(texels.shape(0)), w = std::uint32_t(texels.shape(1));
            std::string out(hbrdf::bc::level_bytes(f, w, h), '\0');
            {
                py::gil_scoped_release release;
                hbrdf::bc::encode_level(f, texels.data(), w, h, int(texels.shape(2)),
                                        reinterpret_cast<std::uint8_t*>(out.data()));
            }
            return py::bytes(out);
        },
        py::arg("format"), py::arg("texels"),
        "A level's BC4 (channel 0) or BC5 (channels 0, 1) blocks from uint8 (H, W, C) texels: this library's "
        "encoder (squared error of the decode, 0 and 255 kept exact; docs/TEXTURES.md).");
#ifdef HBRDF_HAVE_RENDERER
    m.def(
        "render_read_ktx2",
        [](const std::string& path) {
            const hbrdf::render::Ktx2Texture t = hbrdf::render::read_ktx2(path);
            py::list levels;
            for (const hbrdf::render::Ktx2Level& l : t.levels) {
                const std::vector<py::ssize_t> shape = {py::ssize_t(l.height), py::ssize_t(l.width), py::ssize_t(t.channels)};
                if (t.is_float) {
                    py::array_t<float> a(shape);
                    std::memcpy(a.mutable_data(), l.floats.data(), l.floats.size() * sizeof(float));
                    levels.append(a);
                } else {
                    py::array_t<std::uint8_t> a(shape);
                    std::memcpy(a.mutable_data(), l.bytes.data(), l.bytes.size());
                    levels.append(a);
                }
            }
            py::dict out;
            out["vk_format"] = t.vk_format;
            out["name"] = t.format_name;
            out["width"] = t.width;
            out["height"] = t.height;
            out["channels"] = t.channels;
            out["srgb"] = t.srgb;
            out["levels"] = levels;
            return out;
        },
        py::arg("path"),
        "libhybridbrdf's KTX2 reader: {vk_format, name, width, height, channels, srgb, levels: [uint8 or "
        "float32 (H, W, channels)]}. Raises RenderFileError '<path>: <problem>'.");
#endif
}
