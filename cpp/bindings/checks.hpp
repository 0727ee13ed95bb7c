// Argument checks and row access shared by the binding files (module.cpp, tabulated.cpp):
// every array-in function of hybridbrdf._core rejects a wrong shape or material index with
// the same ValueError / IndexError text.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <string>

#include "hybridbrdf/math.hpp"
#include "hybridbrdf/model.hpp"

namespace hbrdf_bindings {

namespace py = pybind11;

/// float32, C-contiguous; arrays of other dtypes and layouts are converted on the way in.
using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;

/// Checks that `a` has shape (n, cols) (n taken from `a` when n < 0) and returns n.
inline py::ssize_t check_rows(const FloatArray& a, const char* name, py::ssize_t cols, py::ssize_t n) {
    if (a.ndim() != 2 || a.shape(1) != cols)
        throw py::value_error(std::string(name) + " must have shape (N, " + std::to_string(cols) + "), got ndim " +
                              std::to_string(a.ndim()) + (a.ndim() >= 2 ? ", shape[1] " + std::to_string(a.shape(1)) : ""));
    if (n >= 0 && a.shape(0) != n)
        throw py::value_error(std::string(name) + " has " + std::to_string(a.shape(0)) + " rows, expected " +
                              std::to_string(n));
    return a.shape(0);
}

/// Checks that wi and wo are both (N, 3) and returns N.
inline py::ssize_t check_pairs(const FloatArray& wi, const FloatArray& wo) {
    const py::ssize_t n = check_rows(wi, "wi", 3, -1);
    check_rows(wo, "wo", 3, n);
    return n;
}

/// Checks that `material` indexes a material of `model`.
inline void check_material(const hbrdf::HybridModel& model, int material) {
    if (material < 0 || material >= static_cast<int>(model.materials().size()))
        throw py::index_error("material index " + std::to_string(material) + " out of range");
}

/// Row k of an (N, 3) float array.
inline hbrdf::Vec3<float> row3(const float* a, py::ssize_t k) {
    return hbrdf::Vec3<float>(a[3 * k], a[3 * k + 1], a[3 * k + 2]);
}

}  // namespace hbrdf_bindings
