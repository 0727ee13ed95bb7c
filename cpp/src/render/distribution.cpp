// hybridbrdf renderer — piecewise-constant 1D and 2D distributions.
#include "hybridbrdf/render/distribution.hpp"

#include <algorithm>
#include <cmath>

#include "hybridbrdf/warp.hpp"

namespace hbrdf::render {

Distribution1D::Distribution1D(std::vector<float> weights) : func_(std::move(weights)) {
    if (func_.empty()) func_.assign(1, 1.0f);
    for (float& f : func_)
        if (!(f > 0.0f) || !is_finite(f)) f = 0.0f;  // negatives, NaN and Inf carry no probability
    const std::size_t n = func_.size();
    cdf_.assign(n + 1, 0.0);
    // Prefix sums in double: images of 10^6 texels lose ~1e-7 per addition in float.
    for (std::size_t i = 0; i < n; ++i) cdf_[i + 1] = cdf_[i] + double(func_[i]);
    double total = cdf_[n];
    if (!(total > 0.0)) {
        std::fill(func_.begin(), func_.end(), 1.0f);
        for (std::size_t i = 0; i < n; ++i) cdf_[i + 1] = double(i + 1);
        total = double(n);
    }
    integral_ = total / double(n);
    for (double& c : cdf_) c /= total;
    cdf_[n] = 1.0;
}

float Distribution1D::sample(float u, float* pdf, std::size_t* bin) const {
    const double uu = double(clamp_nan_lo(u, 0.0f, kOneMinusEps<float>));
    // Largest i with cdf_[i] <= u; bins of zero probability are never chosen
    // because upper_bound skips equal cdf values.
    const auto it = std::upper_bound(cdf_.begin(), cdf_.end(), uu);
    std::size_t i = std::size_t(std::max<std::ptrdiff_t>(0, (it - cdf_.begin()) - 1));
    i = std::min(i, size() - 1);
    const double width = cdf_[i + 1] - cdf_[i];
    const double du = width > 0.0 ? (uu - cdf_[i]) / width : 0.5;
    if (pdf) *pdf = float(double(func_[i]) / integral_);
    if (bin) *bin = i;
    const float x = float((double(i) + std::clamp(du, 0.0, 1.0)) / double(size()));
    return std::min(x, kOneMinusEps<float>);
}

float Distribution1D::pdf(float x) const {
    const float xc = clamp_nan_lo(x, 0.0f, kOneMinusEps<float>);
    const std::size_t i = std::min(size() - 1, std::size_t(xc * float(size())));
    return float(double(func_[i]) / integral_);
}

Distribution2D::Distribution2D(const std::vector<float>& weights, int width, int height)
    : width_(width), height_(height) {
    std::vector<float> row_integrals(static_cast<std::size_t>(height));
    conditional_.reserve(std::size_t(height));
    for (int y = 0; y < height; ++y) {
        conditional_.emplace_back(std::vector<float>(weights.begin() + std::ptrdiff_t(y) * width,
                                                     weights.begin() + std::ptrdiff_t(y + 1) * width));
        // A row of zeros was made uniform inside Distribution1D, but its
        // marginal weight stays 0, so it is never chosen.
        double s = 0;
        for (int x = 0; x < width; ++x) {
            const float w = weights[std::size_t(y) * std::size_t(width) + std::size_t(x)];
            s += (w > 0.0f && is_finite(w)) ? double(w) : 0.0;
        }
        row_integrals[std::size_t(y)] = float(s / double(width));
    }
    marginal_ = Distribution1D(std::move(row_integrals));
}

Vec2<float> Distribution2D::sample(const Vec2<float>& u2, float* pdf) const {
    float pdf_v = 0, pdf_u = 0;
    std::size_t row = 0;
    const float v = marginal_.sample(u2.y, &pdf_v, &row);
    const float u = conditional_[row].sample(u2.x, &pdf_u, nullptr);
    if (pdf) *pdf = pdf_u * pdf_v;
    return Vec2<float>(u, v);
}

float Distribution2D::pdf(const Vec2<float>& uv) const {
    const float vc = clamp_nan_lo(uv.y, 0.0f, kOneMinusEps<float>);
    const std::size_t row = std::min(std::size_t(height_ - 1), std::size_t(vc * float(height_)));
    return marginal_.pdf(uv.y) * conditional_[row].pdf(uv.x);
}

}  // namespace hbrdf::render
