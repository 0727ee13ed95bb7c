// Python bindings of the baseline representations (hybridbrdf/baselines.hpp):
// _core.MerlTable and _core.NbrdfNetwork, for the cost table and its tests.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <stdexcept>
#include <vector>

#include "checks.hpp"
#include "hybridbrdf/baselines.hpp"

namespace py = pybind11;

namespace {

using hbrdf_bindings::check_pairs;
using hbrdf_bindings::FloatArray;

template <class T> FloatArray eval_pairs(const T& brdf, const FloatArray& wi, const FloatArray& wo) {
    const py::ssize_t n = check_pairs(wi, wo);
    FloatArray f({n, py::ssize_t(3)});
    {
        py::gil_scoped_release release;
        brdf.eval_batch(std::size_t(n), wi.data(), wo.data(), f.mutable_data());
    }
    return f;
}

template <class F> auto value_errors(F&& make) {
    try {
        return make();
    } catch (const std::invalid_argument& e) {
        throw py::value_error(e.what());
    }
}

}  // namespace

void bind_baselines(py::module_& m) {
    py::class_<hbrdf::MerlTable>(m, "MerlTable",
                                 "A tabulated measured BRDF in the MERL layout (90 theta_h x 90 theta_d x 180 phi_d, "
                                 "RGB), looked up at the nearest cell as BRDFRead.cpp does. See docs/BENCHMARKS.md.")
        .def(py::init([](const FloatArray& rgb) {
                 std::vector<float> v(rgb.data(), rgb.data() + rgb.size());
                 return value_errors([&] { return hbrdf::MerlTable(std::move(v)); });
             }),
             py::arg("rgb"), "rgb: (90, 90, 180, 3) physical values (scale applied), theta_h slowest.")
        .def("eval", &eval_pairs<hbrdf::MerlTable>, py::arg("wi"), py::arg("wo"),
             "f (N,3) without the cosine for (N,3) wi, wo; 0 at or below the horizon.")
        .def_property_readonly("memory_bytes", &hbrdf::MerlTable::memory_bytes, "Bytes of the float32 table.");
    py::class_<hbrdf::NbrdfNetwork>(m, "NbrdfNetwork",
                                    "One material's NBRDF network (Sztrajman et al. 2021): f = max(exp(MLP(x)) - 1, 0), "
                                    "x = (sin theta_h, 0, cos theta_h, d), ReLU hidden layers.")
        .def(py::init([](const std::vector<std::pair<FloatArray, FloatArray>>& layers) {
                 std::vector<hbrdf::NbrdfNetwork::Layer> ls;
                 for (const auto& [w, b] : layers) {
                     if (w.ndim() != 2 || b.ndim() != 1) throw py::value_error("NbrdfNetwork: a layer is (weight (out, in), bias (out,))");
                     hbrdf::NbrdfNetwork::Layer L;
                     L.n_out = int(w.shape(0)), L.n_in = int(w.shape(1));
                     L.weight.assign(w.data(), w.data() + w.size());
                     L.bias.assign(b.data(), b.data() + b.size());
                     ls.push_back(std::move(L));
                 }
                 return value_errors([&] { return hbrdf::NbrdfNetwork(std::move(ls)); });
             }),
             py::arg("layers"), "layers: [(weight (out, in), bias (out,)), ...], 6 inputs, 3 outputs.")
        .def("eval", &eval_pairs<hbrdf::NbrdfNetwork>, py::arg("wi"), py::arg("wo"),
             "f (N,3) without the cosine for (N,3) wi, wo; 0 at or below the horizon.")
        .def_property_readonly("memory_bytes", &hbrdf::NbrdfNetwork::memory_bytes, "Bytes of the weights (float32).");
}
