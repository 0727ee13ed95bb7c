// hybridbrdf._core — bindings of the reference path tracer (docs/RENDERING.md).
// The Python front end is python/hybridbrdf/render/tracer.py; these functions are its
// plumbing. Loading and rendering run on a thread of their own, GIL released,
// while the calling thread watches for Ctrl-C; measured materials are Python
// callables that take the GIL back once per batch.
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <variant>

namespace py = pybind11;

#ifdef HBRDF_HAVE_RENDERER

#include "hybridbrdf/render/render.hpp"
#include "hybridbrdf/render/svbrdf_io.hpp"

namespace {

namespace hr = hbrdf::render;
using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;

// A Python exception as one line for a scene error: its message, prefixed by
// its type unless it is a ValueError or OSError (whose messages name the file
// and the problem already: "gold.bsdf: truncated file"). Tracebacks stay out:
// the error is about the scene, not about where the reader noticed it.
// Called with the GIL held.
std::string one_line(const py::error_already_set& e) {
    std::string msg = py::str(e.value());
    for (char& c : msg)
        if (c == '\n' || c == '\r') c = ' ';
    const bool names_itself = PyErr_GivenExceptionMatches(e.type().ptr(), PyExc_ValueError) ||
                              PyErr_GivenExceptionMatches(e.type().ptr(), PyExc_OSError);
    if (names_itself && !msg.empty()) return msg;
    const std::string type = py::str(e.type().attr("__name__"));
    return msg.empty() ? type : type + ": " + msg;
}

// A BaseException that is not an Exception (KeyboardInterrupt, SystemExit)
// stops the render as Ctrl-C does, instead of becoming a scene error.
[[noreturn]] void rethrow_python_error(const py::error_already_set& e, const std::string& prefix) {
    if (!e.matches(PyExc_Exception)) throw hr::Cancelled();
    throw std::runtime_error(prefix + one_line(e));
}

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
            rethrow_python_error(e, "measured material '" + source + "': eval(wi, wo) raised ");
        }
    };
}

// The loader's MeasuredFactory over a Python `measured(source)`; called on the
// loading thread, so it takes the GIL. `measured` outlives the load.
hr::MeasuredFactory measured_factory(const py::object& measured) {
    return [&measured](const std::string& source) {
        py::gil_scoped_acquire gil;
        try {
            return wrap_callable(measured(source), source);
        } catch (py::error_already_set& e) {
            rethrow_python_error(e, "");
        }
    };
}

// Runs `work` on a thread of its own while this thread, GIL released, waits
// for it and every 50 ms takes the GIL to run Python's signal handlers: the
// only way Ctrl-C reaches Python while C++ works (handlers run on the main
// thread only, between bytecodes). A handler that raises (SIGINT's
// KeyboardInterrupt) sets `cancel`, which the loader and the renderer check
// between tiles and waves; once `work` has returned, the handler's exception
// is raised here. Otherwise `work`'s own exception, if any, is rethrown.
void run_interruptibly(const std::function<void()>& work, std::atomic<bool>& cancel) {
    std::exception_ptr error;
    std::mutex mutex;
    std::condition_variable cv;
    bool done = false;
    bool interrupted = false;
    {
        py::gil_scoped_release release;
        std::thread worker([&] {
            try {
                work();
            } catch (...) {
                error = std::current_exception();
            }
            std::lock_guard<std::mutex> lock(mutex);
            done = true;
            cv.notify_all();
        });
        std::unique_lock<std::mutex> lock(mutex);
        while (!cv.wait_for(lock, std::chrono::milliseconds(50), [&] { return done; })) {
            if (interrupted) continue;
            lock.unlock();
            {
                py::gil_scoped_acquire gil;
                // A raising handler leaves its exception set on this thread; it is raised below.
                interrupted = PyErr_CheckSignals() != 0;
            }
            if (interrupted) cancel = true;
            lock.lock();
        }
        lock.unlock();
        worker.join();
    }
    if (interrupted) throw py::error_already_set();
    if (error) std::rethrow_exception(error);
}

// What render_scene computes on its worker thread.
struct RenderJob {
    std::unique_ptr<hr::Scene> scene;
    hr::RenderOptions options;
    hr::RenderStats stats;
    hr::Image image;
};

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
    py::register_exception<hr::MaterialError>(m, "RenderMaterialError", PyExc_RuntimeError);
    // A cancellation with no Python exception behind it (a measured callable
    // raised KeyboardInterrupt or SystemExit) reads as Ctrl-C.
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const hr::Cancelled&) {
            PyErr_SetNone(PyExc_KeyboardInterrupt);
        }
    });

    m.def(
        "render_scene",
        [](const std::string& json_text, const std::string& base_dir, const std::string& origin, py::object measured,
           bool quiet, const std::string& exr, const std::string& png, float exposure, const std::string& tonemap) {
            const hr::PngOptions png_options{exposure, parse_tonemap(tonemap)};
            // Before the render, not after it: a bad output path costs no render time.
            if (!exr.empty()) hr::check_output_path(exr);
            if (!png.empty()) hr::check_output_path(png);
            std::atomic<bool> cancel{false};
            hr::SceneLoadOptions load;
            load.cancel = &cancel;
            if (!measured.is_none()) load.measured = measured_factory(measured);
            RenderJob job;
            run_interruptibly([&] {
                job.scene = std::make_unique<hr::Scene>(hr::load_scene_json(json_text, base_dir, origin, load));
                job.options = hr::RenderOptions::from_scene(job.scene->settings);
                job.options.quiet = quiet;
                job.options.cancel = &cancel;
                try {
                    job.image = hr::render(*job.scene, job.options, &job.stats);
                } catch (const std::invalid_argument& e) {
                    throw hr::FileError(origin, e.what());
                }
                // Both files are written under temporary names, then renamed
                // together: a cancelled render replaces neither.
                std::optional<hr::StagedFile> staged_exr, staged_png;
                if (!exr.empty()) staged_exr.emplace(hr::stage_exr(job.image, exr));
                if (!png.empty()) staged_png.emplace(hr::stage_png(job.image, png, png_options));
                hr::throw_if_cancelled(&cancel);
                if (staged_exr) staged_exr->commit();
                if (staged_png) staged_png->commit();
            }, cancel);
            const hr::Scene& scene = *job.scene;
            const hr::RenderOptions& options = job.options;
            const hr::RenderStats& stats = job.stats;
            const hr::Image& image = job.image;
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
            py::list folders;
            for (const auto& folder : decl.textured_folders) folders.append(folder);
            out["textured_folders"] = folders;
            return out;
        },
        py::arg("json_text"), py::arg("base_dir"), py::arg("origin"),
        "A scene's settings and materials, read and checked as the loader does without opening the files they "
        "name: {'settings': {name: value}, 'model_materials': [{where, name, file, material, evaluate}], "
        "'other_materials': [{where, name, type}]}. Raises RenderFileError '<origin>: <where>: <problem>'.");

    m.def(
        "render_environment",
        [](const std::string& json_text, const std::string& base_dir, const std::string& origin) {
            // A sky of the viewer's sizes bakes in milliseconds: no cancellation needed.
            return array_from_image(hr::load_environment_json(json_text, base_dir, origin).image());
        },
        py::arg("json_text"), py::arg("base_dir"), py::arg("origin"),
        "The radiance image (H, W, 3) float32 of a scene's \"environment\" object given as JSON text, as the "
        "tracer lights with it: read, baked (sky) and scaled by the scene loader (a map holding a negative or "
        "non-finite texel is refused), before its rotation_deg (which turns lookups, not the image). Errors as load_scene_json's.");
    m.def("render_write_exr", [](const FloatArray& a, const std::string& path) { hr::write_exr(image_from_array(a), path); },
          py::arg("image"), py::arg("path"), "Write (H, W, 3) linear float32 OpenEXR, atomically.");
    m.def(
        "render_write_png",
        [](const FloatArray& a, const std::string& path, float exposure, const std::string& tonemap) {
            hr::write_png(image_from_array(a), path, hr::PngOptions{exposure, parse_tonemap(tonemap)});
        },
        py::arg("image"), py::arg("path"), py::arg("exposure") = 0.0f, py::arg("tonemap") = "clamp",
        "Write an 8-bit sRGB PNG (exposure in stops, then clamp or ACES, then the sRGB OETF), atomically.");
    using SvbrdfPtr = std::shared_ptr<hbrdf::Svbrdf>;  // pybind11 holders are not const; the object is never changed
    const auto filter_of = [](const std::string& filter) {
        if (filter != "bilinear" && filter != "nearest") throw std::invalid_argument("filter must be bilinear or nearest");
        return filter == "nearest" ? hbrdf::TexelFilter::Nearest : hbrdf::TexelFilter::Bilinear;
    };
    const auto strategy_of = [](const std::string& s) {
        if (s != "cosine" && s != "ggx" && s != "mis") throw std::invalid_argument("strategy must be cosine, ggx or mis");
        return s == "cosine" ? hbrdf::Strategy::Cosine : s == "ggx" ? hbrdf::Strategy::Ggx : hbrdf::Strategy::Mis;
    };
    const auto rows = [](const FloatArray& a, py::ssize_t n, py::ssize_t c, const char* what) {
        if (a.ndim() != 2 || a.shape(0) != n || a.shape(1) != c)
            throw std::invalid_argument(std::string(what) + " must have shape (N, " + std::to_string(c) + ")");
    };
    // An optional (N, 3) float32 array argument (None: absent).
    const auto optional_rows = [](const py::object& a) -> std::optional<FloatArray> {
        if (a.is_none()) return std::nullopt;
        FloatArray arr = FloatArray::ensure(a);
        if (!arr) throw std::invalid_argument("weights must be an (N, 3) float array or None");
        return arr;
    };
    // Pair i's texel: weights from the map, or row i of the caller's (N, 3) weights.
    const auto texel_of = [](const hbrdf::Svbrdf& sv, const FloatArray& uv, const std::optional<FloatArray>& weights,
                             py::ssize_t i, hbrdf::TexelFilter flt, hbrdf::Texel* tx) {
        const hbrdf::Vec2<float> t(uv.data()[2 * i], uv.data()[2 * i + 1]);
        if (weights) sv.texel(t, flt, weights->data() + 3 * i, tx);
        else sv.texel(t, flt, tx);
    };
    py::class_<hbrdf::Svbrdf, SvbrdfPtr>(m, "Svbrdf",
                                         "A textured material's folder read by libhybridbrdf's loader (render::load_svbrdf, "
                                         "the tracer's; docs/SVBRDF.md).")
        .def(py::init([](const std::string& folder) { return std::const_pointer_cast<hbrdf::Svbrdf>(hr::load_svbrdf(folder)); }),
             py::arg("folder"))
        .def_property_readonly("size", [](const hbrdf::Svbrdf& sv) { return py::make_tuple(sv.width(), sv.height()); })
        .def_property_readonly("layer_count", &hbrdf::Svbrdf::layer_count)
        .def_property_readonly("levels", &hbrdf::Svbrdf::level_count)
        .def(
            "eval",
            [=](const hbrdf::Svbrdf& sv, const FloatArray& uv, const FloatArray& wi, const FloatArray& wo,
                const std::string& filter, bool analytic, bool batched, const py::object& weights_in, const py::object& lod_in) {
                const std::optional<FloatArray> weights = optional_rows(weights_in);
                const py::ssize_t n = uv.ndim() == 2 ? uv.shape(0) : -1;
                rows(uv, n, 2, "uv"), rows(wi, n, 3, "wi"), rows(wo, n, 3, "wo");
                if (weights) rows(*weights, n, 3, "weights");
                std::optional<FloatArray> lod;
                if (!lod_in.is_none()) {
                    lod = FloatArray::ensure(lod_in);
                    if (!*lod || lod->ndim() != 1 || lod->shape(0) != n) throw std::invalid_argument("lod must have shape (N,)");
                    if (weights || analytic) throw std::invalid_argument("lod reads the weights map: not with weights or analytic");
                }
                const hbrdf::TexelFilter flt = filter_of(filter);
                FloatArray f({n, py::ssize_t(3)});
                py::gil_scoped_release release;
                float* o = f.mutable_data();
                if (batched && !analytic && !weights) {
                    sv.eval_batch(std::size_t(n), uv.data(), wi.data(), wo.data(), flt, o, lod ? lod->data() : nullptr);
                    return f;
                }
                hbrdf::Texel tx;
                for (py::ssize_t i = 0; i < n; ++i) {
                    const hbrdf::Vec2<float> t(uv.data()[2 * i], uv.data()[2 * i + 1]);
                    const hbrdf::Vec3<float> a(wi.data()[3 * i], wi.data()[3 * i + 1], wi.data()[3 * i + 2]);
                    const hbrdf::Vec3<float> b(wo.data()[3 * i], wo.data()[3 * i + 1], wo.data()[3 * i + 2]);
                    hbrdf::Vec3<float> v;
                    if (weights) {
                        texel_of(sv, uv, weights, i, flt, &tx);
                        v = analytic ? hbrdf::Svbrdf::eval_analytic(tx, a, b) : sv.eval_texel(tx, a, b);
                    } else if (lod) {
                        v = sv.eval(t, flt, lod->data()[i], a, b);
                    } else {
                        v = analytic ? sv.eval_analytic(t, flt, a, b) : sv.eval(t, flt, a, b);
                    }
                    o[3 * i] = v.x, o[3 * i + 1] = v.y, o[3 * i + 2] = v.z;
                }
                return f;
            },
            py::arg("uv"), py::arg("wi"), py::arg("wo"), py::arg("filter") = "bilinear", py::arg("analytic") = false,
            py::arg("batched") = false, py::arg("weights") = py::none(), py::arg("lod") = py::none(),
            "f at (N, 2) uv through the scalar path (Svbrdf::eval) or, with batched, Svbrdf::eval_batch; with analytic "
            "the f_a mixture; with weights (N, 3), w_1..w_3 per pair instead of the weights map's (the scalar path); "
            "with lod (N,), read trilinearly from the mip chain at that level of detail; (N, 3).")
        .def(
            "sample",
            [=](const hbrdf::Svbrdf& sv, const FloatArray& uv, const FloatArray& wo, const FloatArray& u,
                const std::string& strategy, const std::string& filter, const py::object& weights_in) {
                const std::optional<FloatArray> weights = optional_rows(weights_in);
                const py::ssize_t n = uv.ndim() == 2 ? uv.shape(0) : -1;
                rows(uv, n, 2, "uv"), rows(wo, n, 3, "wo"), rows(u, n, 2, "u");
                if (weights) rows(*weights, n, 3, "weights");
                const hbrdf::Strategy s = strategy_of(strategy);
                const hbrdf::TexelFilter flt = filter_of(filter);
                FloatArray wi({n, py::ssize_t(3)}), pdf({n}), again({n});
                hbrdf::Texel tx;
                for (py::ssize_t i = 0; i < n; ++i) {
                    const hbrdf::Vec3<float> o(wo.data()[3 * i], wo.data()[3 * i + 1], wo.data()[3 * i + 2]);
                    texel_of(sv, uv, weights, i, flt, &tx);
                    const auto b = hbrdf::Svbrdf::sample(tx, s, o, hbrdf::Vec2<float>(u.data()[2 * i], u.data()[2 * i + 1]));
                    for (int c = 0; c < 3; ++c) wi.mutable_data()[3 * i + c] = b.wi[c];
                    pdf.mutable_data()[i] = b.pdf;
                    again.mutable_data()[i] = b.pdf > 0.f ? hbrdf::Svbrdf::pdf(tx, s, b.wi, o) : 0.f;
                }
                return py::make_tuple(wi, pdf, again);
            },
            py::arg("uv"), py::arg("wo"), py::arg("u"), py::arg("strategy") = "mis", py::arg("filter") = "bilinear",
            py::arg("weights") = py::none(),
            "Samples of the texels' layer mixture (weights (N, 3): w_1..w_3 per pair instead of the map's): "
            "(wi (N, 3), pdf (N,), pdf(wi, wo) recomputed (N,)).")
        .def(
            "pdf",
            [=](const hbrdf::Svbrdf& sv, const FloatArray& uv, const FloatArray& wi, const FloatArray& wo,
                const std::string& strategy, const std::string& filter, const py::object& weights_in) {
                const std::optional<FloatArray> weights = optional_rows(weights_in);
                const py::ssize_t n = uv.ndim() == 2 ? uv.shape(0) : -1;
                rows(uv, n, 2, "uv"), rows(wi, n, 3, "wi"), rows(wo, n, 3, "wo");
                if (weights) rows(*weights, n, 3, "weights");
                const hbrdf::Strategy s = strategy_of(strategy);
                const hbrdf::TexelFilter flt = filter_of(filter);
                FloatArray pdf({n});
                hbrdf::Texel tx;
                for (py::ssize_t i = 0; i < n; ++i) {
                    texel_of(sv, uv, weights, i, flt, &tx);
                    pdf.mutable_data()[i] = hbrdf::Svbrdf::pdf(tx, s, hbrdf::Vec3<float>(wi.data()[3 * i], wi.data()[3 * i + 1], wi.data()[3 * i + 2]),
                                                               hbrdf::Vec3<float>(wo.data()[3 * i], wo.data()[3 * i + 1], wo.data()[3 * i + 2]));
                }
                return pdf;
            },
            py::arg("uv"), py::arg("wi"), py::arg("wo"), py::arg("strategy") = "mis", py::arg("filter") = "bilinear",
            py::arg("weights") = py::none(),
            "The sampling density pdf(wi | wo) at (N, 2) uv (weights (N, 3): w_1..w_3 per pair instead of the map's), (N,).");
    m.def("render_read_image", [](const std::string& path) { return array_from_image(hr::read_image(path)); },
          py::arg("path"), "Read an .exr or .hdr image as (H, W, 3) float32.");
    m.attr("HAVE_RENDERER") = true;
}

#else

void bind_render(py::module_& m) { m.attr("HAVE_RENDERER") = false; }

#endif
