// hybridbrdf._core — bindings of the reference path tracer (docs/RENDERING.md).
// The Python front end is python/hybridbrdf/render.py; these functions are its
// plumbing. Rendering releases the GIL; measured materials are Python callables
// that take it back once per batch.
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <variant>

namespace py = pybind11;

#ifdef HBRDF_HAVE_RENDERER

#include "hybridbrdf/render/render.hpp"

namespace {

namespace hr = hbrdf::render;
using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;

// A Python callable f(wi, wo) -> (n, 3) as a BatchEval. The callable is held
// through a shared_ptr whose deleter takes the GIL, so copies of the
// std::function may be made and dropped on any thread.
hbrdf::BatchEval wrap_callable(py::object fn, const std::string& source) {
    std::shared_ptr<py::object> held(new py::object(std::move(fn)), [](py::object* p) {
        py::gil_scoped_acquire gil;
        delete p;
    });
    return [held, source](std::size_t n, const float* wi, const float* wo, float* f) {
        py::gil_scoped_acquire gil;
        try {
            FloatArray a_wi({py::ssize_t(n), py::ssize_t(3)}), a_wo({py::ssize_t(n), py::ssize_t(3)});
            std::copy(wi, wi + 3 * n, a_wi.mutable_data());
            std::copy(wo, wo + 3 * n, a_wo.mutable_data());
            FloatArray out = FloatArray::ensure((*held)(a_wi, a_wo));
            if (!out || out.ndim() != 2 || out.shape(0) != py::ssize_t(n) || out.shape(1) != 3)
                throw std::runtime_error("measured material '" + source + "': eval(wi, wo) must return an (N, 3) array");
            std::copy(out.data(), out.data() + 3 * n, f);
        } catch (py::error_already_set& e) {
            // Converted while the GIL is held: the Python error object must not
            // outlive it on a worker thread.
            throw std::runtime_error("measured material '" + source + "': " + std::string(e.what()));
        }
    };
}

hr::ToneMap parse_tonemap(const std::string& s) {
    if (s == "clamp") return hr::ToneMap::Clamp;
    if (s == "aces") return hr::ToneMap::Aces;
    throw py::value_error("unknown tonemap '" + s + "'; expected clamp or aces");
}

// A Python value as a SettingValue, unconverted, so that set_setting sees what
// was given (True is a bool, not the integer 1; 3000000000 is not wrapped).
hr::SettingValue setting_value(const py::handle& v) {
    if (py::isinstance<py::bool_>(v)) return v.cast<bool>();
    if (py::isinstance<py::int_>(v)) {
        const py::int_ i = py::reinterpret_borrow<py::int_>(v);
        if (i >= py::int_(0) && i <= py::int_(std::numeric_limits<std::uint64_t>::max())) return i.cast<std::uint64_t>();
        if (i < py::int_(0) && i >= py::int_(std::numeric_limits<std::int64_t>::min())) return i.cast<std::int64_t>();
        return hr::OtherValue{"an integer beyond 64 bits"};
    }
    if (py::isinstance<py::float_>(v)) return v.cast<double>();
    if (py::isinstance<py::str>(v)) return v.cast<std::string>();
    return hr::OtherValue{std::string(py::str(py::type::handle_of(v).attr("__name__")))};
}

py::object setting_object(const hr::SettingValue& v) {
    switch (v.index()) {
        case 0: return py::bool_(std::get<bool>(v));
        case 1: return py::int_(std::get<std::int64_t>(v));
        case 2: return py::int_(std::get<std::uint64_t>(v));
        case 3: return py::float_(std::get<double>(v));
        case 4: return py::str(std::get<std::string>(v));
        default: return py::none();
    }
}

py::dict settings_dict(const hr::RenderSettings& s) {
    py::dict d;
    for (const hr::SettingInfo& info : hr::kRenderSettings) d[info.name] = setting_object(hr::get_setting(s, info));
    return d;
}

hr::Image image_from_array(const FloatArray& a) {
    if (a.ndim() != 3 || a.shape(2) != 3) throw py::value_error("image must have shape (H, W, 3)");
    hr::Image img(int(a.shape(1)), int(a.shape(0)));
    std::copy(a.data(), a.data() + img.rgb.size(), img.rgb.begin());
    return img;
}

FloatArray array_from_image(const hr::Image& img) {
    FloatArray a({py::ssize_t(img.height), py::ssize_t(img.width), py::ssize_t(3)});
    std::copy(img.rgb.begin(), img.rgb.end(), a.mutable_data());
    return a;
}

}  // namespace

void bind_render(py::module_& m) {
    py::register_exception<hr::FileError>(m, "RenderFileError", PyExc_ValueError);

    m.def(
        "render_scene",
        [](const std::string& json_text, const std::string& base_dir, const std::string& origin, py::object measured,
           bool quiet, const std::string& exr, const std::string& png, float exposure, const std::string& tonemap) {
            hr::SceneLoadOptions load;
            if (!measured.is_none())
                load.measured = [measured](const std::string& source) { return wrap_callable(measured(source), source); };
            const hr::PngOptions png_options{exposure, parse_tonemap(tonemap)};
            hr::Scene scene = hr::load_scene_json(json_text, base_dir, origin, load);
            hr::RenderOptions options = hr::RenderOptions::from_scene(scene.settings);
            options.quiet = quiet;
            hr::RenderStats stats;
            hr::Image image;
            {
                py::gil_scoped_release release;
                try {
                    image = hr::render(scene, options, &stats);
                } catch (const std::invalid_argument& e) {
                    throw hr::FileError(origin, e.what());
                }
                if (!exr.empty()) hr::write_exr(image, exr);
                if (!png.empty()) hr::write_png(image, png, png_options);
            }
            py::dict st;
            st["seconds"] = stats.seconds;
            st["samples_per_second"] = stats.samples_per_second;
            st["rays"] = stats.rays;
            st["shadow_rays"] = stats.shadow_rays;
            st["brdf_evals"] = stats.brdf_evals;
            st["network_evals"] = stats.network_evals;
            st["threads"] = stats.threads;
            st["tiles"] = stats.tiles;
            st["spp"] = options.spp;
            st["sampler"] = hr::sampler_name(scene.settings.sampler);
            py::list mem;
            for (const auto& mat : scene.materials) mem.append(py::make_tuple(mat->name(), mat->sampler_memory_bytes()));
            st["sampler_memory_bytes"] = mem;
            return py::make_tuple(array_from_image(image), st);
        },
        py::arg("json_text"), py::arg("base_dir"), py::arg("origin"), py::arg("measured") = py::none(),
        py::arg("quiet") = true, py::arg("exr") = "", py::arg("png") = "", py::arg("exposure") = 0.0f,
        py::arg("tonemap") = "clamp",
        "Load a scene from JSON text and render it; returns ((H, W, 3) float32, stats). `measured(source)` "
        "returns a callable f(wi, wo) -> (N, 3) for each measured material.");

    m.def(
        "render_settings",
        []() {
            const hr::RenderSettings defaults;
            py::list out;
            for (const hr::SettingInfo& info : hr::kRenderSettings) {
                const std::string type = hr::setting_type(info);
                const bool numeric = type == "int" || type == "float";
                auto bound = [&](double b) -> py::object {
                    if (!numeric || std::isinf(b)) return py::none();
                    return type == "int" ? py::object(py::int_(static_cast<long long>(b))) : py::object(py::float_(b));
                };
                py::dict d;
                d["name"] = info.name;
                d["type"] = type;
                d["default"] = setting_object(hr::get_setting(defaults, info));
                d["min"] = bound(info.min);
                d["max"] = bound(info.max);
                py::object choices = py::none();
                if (std::holds_alternative<hr::SamplerKind hr::RenderSettings::*>(info.field)) {
                    py::list names;
                    for (hr::SamplerKind k : hr::kSamplerKinds) names.append(hr::sampler_name(k));
                    choices = py::tuple(names);
                }
                d["choices"] = choices;
                d["doc"] = info.doc;
                out.append(d);
            }
            return out;
        },
        "The scene settings (cpp/include/hybridbrdf/render/settings.hpp), one dict each: name, type "
        "('int', 'float', 'bool', 'str'), default, min and max (inclusive, None = unbounded), choices (or None), doc.");
    m.def(
        "check_render_setting",
        [](const std::string& name, py::handle value) {
            const hr::SettingInfo* info = hr::find_setting(name);
            if (!info) throw py::value_error("unknown render setting '" + name + "'");
            hr::RenderSettings s;
            const std::string problem = hr::set_setting(s, *info, setting_value(value));
            if (!problem.empty()) throw py::value_error(name + ": " + problem);
            return setting_object(hr::get_setting(s, *info));
        },
        py::arg("name"), py::arg("value"),
        "Check a setting's value as the scene loader does; returns it as stored, or raises ValueError "
        "'<name>: <problem>'.");
    m.def(
        "read_scene_decl",
        [](const std::string& json_text, const std::string& base_dir, const std::string& origin) {
            const hr::SceneDecl decl = hr::read_scene_decl(json_text, base_dir, origin);
            py::list models, others;
            for (const auto& d : decl.model_materials) {
                py::dict e;
                e["where"] = d.where;
                e["name"] = d.name;
                e["file"] = d.file;
                e["material"] = d.material;
                e["evaluate"] = d.analytic_only ? "analytic" : "full";
                models.append(e);
            }
            for (const auto& d : decl.other_materials) {
                py::dict e;
                e["where"] = d.where;
                e["name"] = d.name;
                e["type"] = d.type;
                others.append(e);
            }
            py::dict out;
            out["settings"] = settings_dict(decl.settings);
            out["model_materials"] = models;
            out["other_materials"] = others;
            return out;
        },
        py::arg("json_text"), py::arg("base_dir"), py::arg("origin"),
        "A scene's settings and materials, read and checked as the loader does without opening the files they "
        "name: {'settings': {name: value}, 'model_materials': [{where, name, file, material, evaluate}], "
        "'other_materials': [{where, name, type}]}. Raises RenderFileError '<origin>: <where>: <problem>'.");

    m.def("render_write_exr", [](const FloatArray& a, const std::string& path) { hr::write_exr(image_from_array(a), path); },
          py::arg("image"), py::arg("path"), "Write (H, W, 3) linear float32 OpenEXR, atomically.");
    m.def(
        "render_write_png",
        [](const FloatArray& a, const std::string& path, float exposure, const std::string& tonemap) {
            hr::write_png(image_from_array(a), path, hr::PngOptions{exposure, parse_tonemap(tonemap)});
        },
        py::arg("image"), py::arg("path"), py::arg("exposure") = 0.0f, py::arg("tonemap") = "clamp",
        "Write an 8-bit sRGB PNG (exposure in stops, then clamp or ACES, then the sRGB OETF), atomically.");
    m.def("render_read_image", [](const std::string& path) { return array_from_image(hr::read_image(path)); },
          py::arg("path"), "Read an .exr or .hdr image as (H, W, 3) float32.");
    m.attr("HAVE_RENDERER") = true;
}

#else

void bind_render(py::module_& m) { m.attr("HAVE_RENDERER") = false; }

#endif
