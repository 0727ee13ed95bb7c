// hybridbrdf._core — Python bindings over libhybridbrdf, for verification and
// for the Python front end. Array in, array out: float32, C-contiguous; other
// dtypes and layouts are converted. The GIL is released while kernels run.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <string>

#include "checks.hpp"
#include "hybridbrdf/hybridbrdf.hpp"
#include "../src/model_contract.hpp"  // the test hook _contract_math (internal to the library)
#if (defined(__x86_64__) || defined(__i386__)) && defined(__GNUC__)
#include "../tools/fma_peak.hpp"
#define HBRDF_HAVE_FMA_PEAK 1
#endif

namespace py = pybind11;
using hbrdf_bindings::check_material;
using hbrdf_bindings::check_pairs;
using hbrdf_bindings::check_rows;
using hbrdf_bindings::FloatArray;
using hbrdf_bindings::row3;

namespace {

// hbrdf::parse_strategy, with its std::invalid_argument as a ValueError.
hbrdf::Strategy parse_strategy(const std::string& name) {
    try {
        return hbrdf::parse_strategy(name);
    } catch (const std::invalid_argument& e) {
        throw py::value_error(e.what());
    }
}

// (wi (N,3), pdf (N,), weight (N,3)) for wo (N,3) and u (N,2), both checked first; `fill(n, wo, u,
// wi, pdf, weight)` writes them without the GIL (the batched kernel or the scalar sampler).
template <typename Fill>
py::tuple sample_rows(const FloatArray& wo, const FloatArray& u, Fill fill) {
    const py::ssize_t n = check_rows(wo, "wo", 3, -1);
    check_rows(u, "u", 2, n);
    FloatArray wi({n, py::ssize_t(3)}), pdf({n}), weight({n, py::ssize_t(3)});
    {
        py::gil_scoped_release release;
        fill(std::size_t(n), wo.data(), u.data(), wi.mutable_data(), pdf.mutable_data(), weight.mutable_data());
    }
    return py::make_tuple(wi, pdf, weight);
}

hbrdf::AnalyticParams make_params(const std::array<float, 3>& kd, const std::array<float, 3>& eta,
                                  const std::array<float, 2>& alpha) {
    hbrdf::AnalyticParams p;
    p.kd = hbrdf::Vec3<float>(kd[0], kd[1], kd[2]);
    p.eta = hbrdf::Vec3<float>(eta[0], eta[1], eta[2]);
    p.alpha = hbrdf::Vec2<float>(alpha[0], alpha[1]);
    return p;
}

FloatArray hbrdf_eval_analytic_rows(const hbrdf::AnalyticParams& p, const FloatArray& wi, const FloatArray& wo,
                                    py::ssize_t n) {
    FloatArray f({n, py::ssize_t(3)});
    {
        py::gil_scoped_release release;
        hbrdf::eval_analytic_aos(p, std::size_t(n), wi.data(), wo.data(), f.mutable_data());
    }
    return f;
}

}  // namespace

// Defined in tabulated.cpp: hybridbrdf._core.TabulatedSampler.
void bind_tabulated(pybind11::module_& m);
void bind_baselines(pybind11::module_& m);

void bind_render(py::module_& m);  // cpp/bindings/render.cpp
void bind_ktx2(py::module_& m);    // cpp/bindings/ktx2.cpp

PYBIND11_MODULE(_core, m) {
    m.doc() = "libhybridbrdf bindings: analytic BRDF evaluation and importance sampling (float32).";
    m.attr("__version__") = hbrdf::kVersion;
    m.attr("CONVENTIONS_VERSION") = hbrdf::kConventionsVersion;
    m.attr("ALPHA_MIN") = hbrdf::kAlphaMin;
    m.attr("ALPHA_MAX") = hbrdf::kAlphaMax;
    m.attr("ETA_MIN") = hbrdf::kEtaMin;
    m.attr("ETA_MAX") = hbrdf::kEtaMax;
    m.attr("MIS_MIN_LOBE_PROBABILITY") = hbrdf::kMisMinLobeProbability;
    {
        py::list names;
        for (hbrdf::Strategy s : hbrdf::kStrategies) names.append(hbrdf::strategy_name(s));
        m.attr("STRATEGIES") = py::tuple(names);  // the names sample() and pdf() accept
    }

    py::class_<hbrdf::AnalyticParams>(m, "AnalyticParams",
                                      "Parameters of f_a as the C++ library stores them (float32, unchecked; "
                                      "evaluation clamps them into range).")
        .def(py::init(&make_params), py::arg("kd"), py::arg("eta"), py::arg("alpha"))
        .def_property_readonly("kd", [](const hbrdf::AnalyticParams& p) { return std::array<float, 3>{p.kd.x, p.kd.y, p.kd.z}; })
        .def_property_readonly("eta", [](const hbrdf::AnalyticParams& p) { return std::array<float, 3>{p.eta.x, p.eta.y, p.eta.z}; })
        .def_property_readonly("alpha", [](const hbrdf::AnalyticParams& p) { return std::array<float, 2>{p.alpha.x, p.alpha.y}; })
        .def("validate", [](const hbrdf::AnalyticParams& p) {
            try {
                hbrdf::validate(p);
            } catch (const std::invalid_argument& e) {
                throw py::value_error(e.what());
            }
        }, "Raise ValueError naming the first parameter outside its range.");

    m.def("eval_analytic", [](const FloatArray& wi, const FloatArray& wo, const hbrdf::AnalyticParams& p) {
        return hbrdf_eval_analytic_rows(p, wi, wo, check_pairs(wi, wo));
    }, py::arg("wi"), py::arg("wo"), py::arg("params"),
       "f_a for (N,3) wi and wo (local frame, wi toward the light); returns (N,3) RGB without the cosine.");

    m.def("eval_analytic_soa", [](const FloatArray& wi, const FloatArray& wo, const hbrdf::AnalyticParams& p) {
        if (wi.ndim() != 2 || wi.shape(0) != 3) throw py::value_error("wi must have shape (3, N)");
        if (wo.ndim() != 2 || wo.shape(0) != 3 || wo.shape(1) != wi.shape(1))
            throw py::value_error("wo must have shape (3, N) like wi");
        const py::ssize_t n = wi.shape(1);
        FloatArray f({py::ssize_t(3), n});
        {
            py::gil_scoped_release release;
            const float* a = wi.data();
            const float* b = wo.data();
            float* o = f.mutable_data();
            hbrdf::eval_analytic_soa(p, std::size_t(n), {a, a + n, a + 2 * n}, {b, b + n, b + 2 * n},
                                     {o, o + n, o + 2 * n});
        }
        return f;
    }, py::arg("wi"), py::arg("wo"), py::arg("params"),
       "f_a in structure-of-arrays layout: wi, wo of shape (3,N); returns (3,N). The fast path.");

    m.def("sample", [](const FloatArray& wo, const FloatArray& u, const hbrdf::AnalyticParams& p,
                       const std::string& strategy) {
        const hbrdf::Strategy s = parse_strategy(strategy);
        return sample_rows(wo, u, [&](std::size_t n, const float* o, const float* uu, float* wi, float* pdf, float* w) {
            hbrdf::sample_aos(s, p, n, o, uu, wi, pdf, w);
        });
    }, py::arg("wo"), py::arg("u"), py::arg("params"), py::arg("strategy") = "mis",
       "Sample wi for each wo from u in [0,1)^2: returns (wi (N,3), pdf (N,), weight (N,3)).");

    m.def("sample_scalar", [](const FloatArray& wo, const FloatArray& u, const hbrdf::AnalyticParams& p,
                              const std::string& strategy) {
        const hbrdf::Strategy s = parse_strategy(strategy);
        return sample_rows(wo, u, [&](std::size_t n, const float* o, const float* uu, float* wi, float* pdf, float* w) {
            const hbrdf::AnalyticBrdf brdf(p);
            for (std::size_t i = 0; i < n; ++i) {
                const hbrdf::BrdfSample r = hbrdf::sample(s, brdf, hbrdf::Vec3<float>(o[3 * i], o[3 * i + 1], o[3 * i + 2]),
                                                          hbrdf::Vec2<float>(uu[2 * i], uu[2 * i + 1]));
                wi[3 * i] = r.wi.x;
                wi[3 * i + 1] = r.wi.y;
                wi[3 * i + 2] = r.wi.z;
                pdf[i] = r.pdf;
                w[3 * i] = r.weight.x;
                w[3 * i + 1] = r.weight.y;
                w[3 * i + 2] = r.weight.z;
            }
        });
    }, py::arg("wo"), py::arg("u"), py::arg("params"), py::arg("strategy") = "mis",
       "As sample, through the scalar sampler (hbrdf::sample, sampling.hpp: libm sin/cos, one lane at a time): "
       "the reference the batched kernel and the generated C++ header are compared with.");

    m.def("pdf", [](const FloatArray& wi, const FloatArray& wo, const hbrdf::AnalyticParams& p,
                    const std::string& strategy) {
        const hbrdf::Strategy s = parse_strategy(strategy);
        const py::ssize_t n = check_pairs(wi, wo);
        FloatArray out({n});
        {
            py::gil_scoped_release release;
            hbrdf::pdf_aos(s, p, std::size_t(n), wi.data(), wo.data(), out.mutable_data());
        }
        return out;
    }, py::arg("wi"), py::arg("wo"), py::arg("params"), py::arg("strategy") = "mis",
       "Solid-angle density with which `strategy` samples wi given wo (over the whole sphere).");

    // libhybridbrdf's model-file errors surface as hybridbrdf.ModelFileError itself (path,
    // problem, one-line message), the type the Python loader raises: one except clause for both.
    m.attr("ModelFileError") = py::module_::import("hybridbrdf.errors").attr("ModelFileError");
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const hbrdf::ModelFileError& e) {
            const py::gil_scoped_acquire gil;
            // A path Python handed in round-trips; undecodable bytes stay visible as surrogates.
            py::object path = py::reinterpret_steal<py::object>(
                PyUnicode_DecodeUTF8(e.path().data(), py::ssize_t(e.path().size()), "surrogateescape"));
            py::object err = py::module_::import("hybridbrdf.errors").attr("ModelFileError")(path, e.problem());
            PyErr_SetObject(reinterpret_cast<PyObject*>(Py_TYPE(err.ptr())), err.ptr());
        }
    });
    py::class_<hbrdf::HybridModel>(m, "Model", "A model file evaluated by libhybridbrdf (float32).")
        // Any str or os.PathLike, encoded as the OS does (os.fsencode): paths with undecodable bytes work.
        .def(py::init([](const py::object& path) {
                 const std::string bytes = py::module_::import("os").attr("fsencode")(path).cast<py::bytes>();
                 return hbrdf::HybridModel::load(bytes);
             }), py::arg("path"))
        .def_property_readonly("materials", [](const hbrdf::HybridModel& md) {
            std::vector<std::string> names;
            for (const auto& mat : md.materials()) names.push_back(mat.name);
            return names;
        })
        .def("find", &hbrdf::HybridModel::find, py::arg("name"), "Index of a material, or -1.")
        .def("eval", [](const hbrdf::HybridModel& md, const FloatArray& wi, const FloatArray& wo, int material) {
            const py::ssize_t n = check_pairs(wi, wo);
            check_material(md, material);
            FloatArray f({n, py::ssize_t(3)});
            {
                py::gil_scoped_release release;
                md.eval_batch(material, std::size_t(n), wi.data(), wo.data(), f.mutable_data());
            }
            return f;
        }, py::arg("wi"), py::arg("wo"), py::arg("material"), "f_t for (N,3) wi, wo; returns (N,3).")
        .def("eval_scalar", [](const hbrdf::HybridModel& md, const FloatArray& wi, const FloatArray& wo, int material) {
            const py::ssize_t n = check_pairs(wi, wo);
            check_material(md, material);
            FloatArray f({n, py::ssize_t(3)});
            {
                py::gil_scoped_release release;
                float* o = f.mutable_data();
                for (py::ssize_t i = 0; i < n; ++i) {
                    const auto v = md.eval(material, row3(wi.data(), i), row3(wo.data(), i));
                    o[3 * i] = v.x, o[3 * i + 1] = v.y, o[3 * i + 2] = v.z;
                }
            }
            return f;
        }, py::arg("wi"), py::arg("wo"), py::arg("material"),
           "f_t through the scalar (tracer and shader twin) path, one pair at a time.")
        .def("eval_texels", [](const hbrdf::HybridModel& md, const FloatArray& wi, const FloatArray& wo,
                               const py::array_t<std::int32_t, py::array::c_style | py::array::forcecast>& material,
                               const FloatArray& weight, const FloatArray& kd, const FloatArray& eta,
                               const FloatArray& alpha, const FloatArray& latent) {
            const py::ssize_t n = check_pairs(wi, wo);
            if (material.ndim() != 2 || material.shape(0) != n || material.shape(1) < 1 ||
                material.shape(1) > hbrdf::spec::kSvbrdfMaxLayers)
                throw std::invalid_argument("material must have shape (N, L), L = 1.." +
                                            std::to_string(hbrdf::spec::kSvbrdfMaxLayers));
            const py::ssize_t L = material.shape(1), l = md.latent_dim();
            const auto shaped = [&](const FloatArray& a, py::ssize_t c, const char* what) {
                if (a.ndim() != 3 || a.shape(0) != n || a.shape(1) != L || a.shape(2) != c)
                    throw std::invalid_argument(std::string(what) + " must have shape (N, L, " + std::to_string(c) + ")");
            };
            if (weight.ndim() != 2 || weight.shape(0) != n || weight.shape(1) != L)
                throw std::invalid_argument("weight must have shape (N, L)");
            shaped(kd, 3, "kd"), shaped(eta, 3, "eta"), shaped(alpha, 2, "alpha"), shaped(latent, l, "latent");
            for (py::ssize_t i = 0; i < n * L; ++i) check_material(md, material.data()[i]);
            FloatArray f({n, py::ssize_t(3)});
            {
                py::gil_scoped_release release;
                float* o = f.mutable_data();
                hbrdf::TexelLayer layers[hbrdf::spec::kSvbrdfMaxLayers];
                for (py::ssize_t i = 0; i < n; ++i) {
                    for (py::ssize_t k = 0; k < L; ++k) {
                        const py::ssize_t r = i * L + k;
                        hbrdf::TexelLayer& t = layers[k];
                        t.material = material.data()[r];
                        t.weight = weight.data()[r];
                        t.params.kd = hbrdf::Vec3<float>(kd.data()[3 * r], kd.data()[3 * r + 1], kd.data()[3 * r + 2]);
                        t.params.eta = hbrdf::Vec3<float>(eta.data()[3 * r], eta.data()[3 * r + 1], eta.data()[3 * r + 2]);
                        t.params.alpha = hbrdf::Vec2<float>(alpha.data()[2 * r], alpha.data()[2 * r + 1]);
                        t.latent = latent.data() + r * l;
                    }
                    const auto v = md.eval_texel(layers, int(L), row3(wi.data(), i), row3(wo.data(), i));
                    o[3 * i] = v.x, o[3 * i + 1] = v.y, o[3 * i + 2] = v.z;
                }
            }
            return f;
        }, py::arg("wi"), py::arg("wo"), py::arg("material"), py::arg("weight"), py::arg("kd"), py::arg("eta"),
           py::arg("alpha"), py::arg("latent"),
           "f of textured-material texels through the scalar path (HybridModel::eval_texel): per pair i, layers k "
           "of material[i, k] with weight[i, k], kd, eta (N, L, 3), alpha (N, L, 2), latent (N, L, latent_dim).")
        .def_property_readonly("flops_per_eval", &hbrdf::HybridModel::flops_per_eval,
                               "Network FLOPs of one batched evaluation (multiply-add = 2).")
        .def_property_readonly("pre_exp_max", &hbrdf::HybridModel::pre_exp_max,
                               "Bound on every value passed to exp(), as the file records it.")
        .def("tensors", [](const hbrdf::HybridModel& md) {
            // What the loader read, under the model file's tensor names: for tests that hold
            // the C++ reader against the safetensors package bit for bit.
            py::dict out;
            auto array = [](const std::vector<float>& v, std::vector<py::ssize_t> shape) {
                FloatArray a(shape);
                std::copy(v.begin(), v.end(), a.mutable_data());
                return a;
            };
            const auto& layers = md.layers();
            for (std::size_t l = 0; l < layers.size(); ++l) {
                const std::string name = int(l) == md.depth() ? "mlp.out" : "mlp.hidden." + std::to_string(l);
                out[py::str(name + ".weight")] = array(layers[l].weight, {layers[l].n_out, layers[l].n_in});
                out[py::str(name + ".bias")] = array(layers[l].bias, {layers[l].n_out});
            }
            const auto& mats = md.materials();
            const py::ssize_t n = py::ssize_t(mats.size()), l = md.latent_dim();
            if (md.output_layer_kind() == hbrdf::OutputLayer::Material) {
                std::vector<float> hw, hb;
                for (const auto& mat : mats) {
                    hw.insert(hw.end(), mat.head.weight.begin(), mat.head.weight.end());
                    hb.insert(hb.end(), mat.head.bias.begin(), mat.head.bias.end());
                }
                const py::ssize_t n_out = mats.empty() ? 0 : mats[0].head.n_out;
                out["materials.head_weight"] = array(hw, {n, n_out, py::ssize_t(md.width())});
                out["materials.head_bias"] = array(hb, {n, n_out});
            }
            std::vector<float> z, kd, eta, alpha;
            for (const auto& mat : mats) {
                z.insert(z.end(), mat.latent.begin(), mat.latent.end());
                for (int c = 0; c < 3; ++c) kd.push_back(mat.params.kd[c]), eta.push_back(mat.params.eta[c]);
                for (int c = 0; c < 2; ++c) alpha.push_back(mat.params.alpha[c]);
            }
            out["materials.z"] = array(z, {n, l});
            if (md.arch().analytic) {
                out["materials.kd"] = array(kd, {n, 3});
                out["materials.eta"] = array(eta, {n, 3});
                out["materials.alpha"] = array(alpha, {n, 2});
            }
            return out;
        }, "The network and per-material tensors as loaded (the neural baseline's frame layer excepted).")
        .def("eval_analytic", [](const hbrdf::HybridModel& md, const FloatArray& wi, const FloatArray& wo, int material) {
            const py::ssize_t n = check_pairs(wi, wo);
            if (md.kind() == hbrdf::ModelKind::Neural) throw py::value_error("the neural baseline has no analytic part");
            check_material(md, material);
            return hbrdf_eval_analytic_rows(md.materials()[material].params, wi, wo, n);
        }, py::arg("wi"), py::arg("wo"), py::arg("material"), "f_a of a hybrid material for (N,3) wi, wo.");

    m.def("simd_path", &hbrdf::simd_path, "Instruction set the batched kernels use on this CPU.");
    m.def("model_simd_path", &hbrdf::model_simd_path,
          "Kernel the batched model evaluation (Model.eval) uses on this CPU: avx512, avx2+fma or baseline.");
    m.def("limit_model_simd", &hbrdf::limit_model_simd, py::arg("path"),
          "Cap the kernel of Model.eval: avx512 (no cap), avx2+fma or baseline; for tests and benchmarks.");
    m.def("force_baseline_simd", &hbrdf::force_baseline_simd, py::arg("force"),
          "Force the baseline (non-AVX2) kernels; for tests and benchmarks.");
    m.def("_contract_math", [](const std::string& kind, const std::string& name, const FloatArray& inputs,
                               const std::string& path) {
        int arity = 0;
        try {
            arity = hbrdf::detail::contract_math_arity(kind);
        } catch (const std::invalid_argument& e) {
            throw py::value_error(e.what());
        }
        if (inputs.ndim() != 2 || inputs.shape(1) != arity)
            throw py::value_error("_contract_math: inputs must be (N, " + std::to_string(arity) + ") for " + kind);
        const py::ssize_t n = inputs.shape(0);
        FloatArray out(std::vector<py::ssize_t>{n});
        try {
            py::gil_scoped_release release;
            hbrdf::detail::contract_math(kind, name, path, std::size_t(n), inputs.data(), out.mutable_data());
        } catch (const std::invalid_argument& e) {
            throw py::value_error(e.what());
        }
        return out;
    }, py::arg("kind"), py::arg("name"), py::arg("inputs"), py::arg("path"),
          "Test hook (tests/python/test_contract_table_cpp.py): the contract's activation (kind 'activation', "
          "inputs (N, 1): x) or combine rule (kind 'combine', inputs (N, 4): o, g, fa, bound) named `name`, "
          "through path 'scalar' (HybridModel::eval's functions) or 'batched' (the per-lane functions of the "
          "kernel model_simd_path() names); float32 (N,) out.");
    m.def("fma_peak_gflops", [](double seconds) {
        if (!(seconds > 0.0 && seconds <= 60.0)) throw py::value_error("fma_peak_gflops: seconds must be in (0, 60]");
        py::dict out;
#ifdef HBRDF_HAVE_FMA_PEAK
        hbrdf::fma_peak::Peak p;
        {
            py::gil_scoped_release release;
            p = hbrdf::fma_peak::measure(seconds);
        }
        out["avx2_fma"] = p.avx2_fma;
        out["avx512"] = p.avx512;
        out["peak"] = p.peak();
#else
        out["avx2_fma"] = out["avx512"] = out["peak"] = 0.0;
#endif
        return out;
    }, py::arg("seconds") = 1.0,
          "One core's single-precision FMA peak in GFLOP/s on the calling thread: {avx2_fma, avx512, peak} "
          "(0 for an instruction set the CPU lacks, or on a non-x86 build). The denominator of the "
          "benchmarks' fraction-of-peak figures; pin the process to one core first.");

    bind_tabulated(m);  // after Model, which TabulatedSampler.build_model takes
    bind_baselines(m);
    bind_render(m);     // the path tracer (cpp/bindings/render.cpp)
    bind_ktx2(m);       // BC decoders and the KTX2 reader (cpp/bindings/ktx2.cpp); after bind_render: its FileError
}
