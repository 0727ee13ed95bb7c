// hybridbrdf renderer — piecewise-constant distributions on [0, 1) and [0, 1)^2,
// sampled by inverting their cumulative distribution (pbrt's construction,
// written from the math).
#pragma once

#include <cstddef>
#include <vector>

#include "hybridbrdf/math.hpp"

namespace hbrdf::render {

/// n bins of equal width 1/n on [0, 1); bin i has probability f_i / sum f.
/// The density at x in bin i is n f_i / sum f. All-zero (or invalid) weights
/// become uniform, so sampling never fails.
class Distribution1D {
public:
    Distribution1D() = default;
    explicit Distribution1D(std::vector<float> weights);

    std::size_t size() const { return func_.size(); }
    /// sum f / n: the integral of the piecewise-constant function over [0, 1).
    double integral() const { return integral_; }
    /// Continuous sample x in [0, 1) for u in [0, 1); `pdf` its density, `bin` its bin.
    float sample(float u, float* pdf, std::size_t* bin) const;
    /// Density of x (in [0, 1)).
    float pdf(float x) const;
    /// Probability of bin i.
    float bin_probability(std::size_t i) const { return float(double(func_[i]) / (integral_ * double(size()))); }

private:
    std::vector<float> func_;   // weights (>= 0)
    std::vector<double> cdf_;   // size n + 1, cdf_[0] = 0, cdf_[n] = 1
    double integral_ = 0;
};

/// A 2D piecewise-constant distribution over (u, v) in [0, 1)^2 on a
/// width x height grid (row v, column u): a marginal over rows and one
/// conditional per row. Density p(u, v) = w(u, v) / integral.
class Distribution2D {
public:
    Distribution2D() = default;
    /// weights: height rows of width values (row-major).
    Distribution2D(const std::vector<float>& weights, int width, int height);

    /// (u, v) for u2 in [0, 1)^2; `pdf` is the density in (u, v).
    Vec2<float> sample(const Vec2<float>& u2, float* pdf) const;
    /// Density at (u, v).
    float pdf(const Vec2<float>& uv) const;

private:
    int width_ = 0, height_ = 0;
    std::vector<Distribution1D> conditional_;
    Distribution1D marginal_;
};

}  // namespace hbrdf::render
