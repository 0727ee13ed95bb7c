// hybridbrdf._core.TabulatedSampler — the tabulated importance-sampling
// baseline (hybridbrdf/tabulated.hpp) for Python: built from analytic
// parameters or from a material of a loaded model, sampled in batches.
// Arrays are float32, C-contiguous (others converted); the GIL is released
// while tables are built and while samples are drawn.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "checks.hpp"
#include "hybridbrdf/batch.hpp"
#include "hybridbrdf/model.hpp"
#include "hybridbrdf/tabulated.hpp"

namespace py = pybind11;

namespace {

using hbrdf_bindings::check_material;
using hbrdf_bindings::check_pairs;
using hbrdf_bindings::check_rows;
using hbrdf_bindings::FloatArray;
using hbrdf_bindings::row3;

hbrdf::TabulatedStorage parse_storage(const std::string& name) {
    if (name == "compact") return hbrdf::TabulatedStorage::Compact;
    if (name == "full") return hbrdf::TabulatedStorage::Full;
    throw py::value_error("storage must be 'compact' or 'full', got '" + name + "'");
}

hbrdf::TabulatedSampler build_or_raise(const hbrdf::BatchEval& eval, bool isotropic, int resolution_deg,
                                       const std::string& storage_name) {
    const hbrdf::TabulatedStorage storage = parse_storage(storage_name);
    try {
        py::gil_scoped_release release;
        return hbrdf::TabulatedSampler::build(eval, isotropic, resolution_deg, storage);
    } catch (const std::invalid_argument& e) {
        throw py::value_error(e.what());
    }
}

}  // namespace

void bind_tabulated(py::module_& m) {
    py::class_<hbrdf::TabulatedSampler>(
        m, "TabulatedSampler",
        "Tabulated importance sampling (the paper's Sec. 5.2 baseline, after Lawrence et al. 2004): per "
        "outgoing bin a piecewise-constant distribution of mean_rgb(f) cos(theta_i) over (theta_i, phi_i) "
        "cells of resolution_deg, mixed with 10% cosine sampling. See docs/SAMPLING.md.")
        .def_static(
            "build_analytic",
            [](py::object params_in, bool isotropic, int resolution_deg, const std::string& storage) {
                // hybridbrdf.AnalyticParams (the validated Python class) converts itself.
                if (!py::isinstance<hbrdf::AnalyticParams>(params_in) && py::hasattr(params_in, "to_core"))
                    params_in = params_in.attr("to_core")();
                const hbrdf::AnalyticParams params = params_in.cast<hbrdf::AnalyticParams>();
                const hbrdf::BatchEval eval = [params](std::size_t n, const float* wi, const float* wo, float* f) {
                    hbrdf::eval_analytic_aos(params, n, wi, wo, f);
                };
                return build_or_raise(eval, isotropic, resolution_deg, storage);
            },
            py::arg("params"), py::arg("isotropic") = true, py::arg("resolution_deg") = 1,
            py::arg("storage") = "compact",
            "Tabulate the analytic BRDF f_a; params is a _core.AnalyticParams or a hybridbrdf.AnalyticParams. "
            "resolution_deg must divide 90. storage: 'compact' (16-bit CDFs, isotropic azimuth folded by mirror "
            "symmetry; 2.9 MB at 1 degree) or 'full' (float CDFs, 11.7 MB); docs/SAMPLING.md.")
        .def_static(
            "build_model",
            [](const hbrdf::HybridModel& model, int material_index, py::object isotropic, int resolution_deg,
               const std::string& storage) {
                check_material(model, material_index);
                const bool iso = isotropic.is_none() ? model.materials()[std::size_t(material_index)].isotropic
                                                     : isotropic.cast<bool>();
                // The sampler keeps this callable (sample() evaluates f for the
                // weight); keep_alive below keeps the model alive as long.
                const hbrdf::HybridModel* md = &model;
                const hbrdf::BatchEval eval = [md, material_index](std::size_t n, const float* wi, const float* wo,
                                                                   float* f) {
                    md->eval_batch(material_index, n, wi, wo, f);
                };
                return build_or_raise(eval, iso, resolution_deg, storage);
            },
            py::arg("model"), py::arg("material_index"), py::arg("isotropic") = py::none(),
            py::arg("resolution_deg") = 1, py::arg("storage") = "compact", py::keep_alive<0, 1>(),
            "Tabulate material `material_index` of a Model (f_t as Model.eval computes it). isotropic=None takes "
            "the material's own flag from the model file. storage: 'compact' or 'full', as for build_analytic.")
        .def(
            "sample",
            [](const hbrdf::TabulatedSampler& s, const FloatArray& wo, const FloatArray& u) {
                const py::ssize_t n = check_rows(wo, "wo", 3, -1);
                check_rows(u, "u", 2, n);
                FloatArray wi({n, py::ssize_t(3)}), pdf({n});
                {
                    py::gil_scoped_release release;
                    const float* uu = u.data();
                    float* w = wi.mutable_data();
                    float* p = pdf.mutable_data();
                    for (py::ssize_t k = 0; k < n; ++k) {
                        const hbrdf::BrdfSample b =
                            s.sample(row3(wo.data(), k), hbrdf::Vec2<float>(uu[2 * k], uu[2 * k + 1]));
                        w[3 * k] = b.wi.x, w[3 * k + 1] = b.wi.y, w[3 * k + 2] = b.wi.z;
                        p[k] = b.pdf;
                    }
                }
                return py::make_tuple(wi, pdf);
            },
            py::arg("wo"), py::arg("u"),
            "Sample wi for each wo (N,3) from u (N,2) in [0,1)^2: returns (wi (N,3), pdf (N,)); pdf 0 = no sample.")
        .def(
            "pdf",
            [](const hbrdf::TabulatedSampler& s, const FloatArray& wi, const FloatArray& wo) {
                const py::ssize_t n = check_pairs(wi, wo);
                FloatArray out({n});
                {
                    py::gil_scoped_release release;
                    float* p = out.mutable_data();
                    for (py::ssize_t k = 0; k < n; ++k) p[k] = s.pdf(row3(wi.data(), k), row3(wo.data(), k));
                }
                return out;
            },
            py::arg("wi"), py::arg("wo"), "Solid-angle density of sample() for (N,3) wi, wo, over the whole sphere.")
        .def_property_readonly("memory_bytes", &hbrdf::TabulatedSampler::memory_bytes,
                               "Bytes of the tables held (CDFs and per-row constants).")
        .def_property_readonly("isotropic", &hbrdf::TabulatedSampler::isotropic)
        .def_property_readonly("mirrored", &hbrdf::TabulatedSampler::mirrored,
                               "True when the azimuth is folded by mirror symmetry (compact and isotropic).")
        .def_property_readonly("resolution_deg", &hbrdf::TabulatedSampler::resolution_deg)
        .def_property_readonly("table_count", &hbrdf::TabulatedSampler::table_count,
                               "Number of 2D tables: theta_o bins x phi_o bins.")
        .def_property_readonly("phi_o_bins", &hbrdf::TabulatedSampler::phi_o_bins,
                               "phi_o bins (1 for isotropic samplers).");
}
