// hybridbrdf — the representations a user would pick instead of the hybrid model,
// in C++ so that the cost table (bench/bench_inference.py, docs/BENCHMARKS.md)
// times them on the same footing as the hybrid model's batched path:
//
//   * MerlTable: a tabulated measured BRDF in the layout of the MERL database
//     (Matusik et al. 2003): 90 theta_h x 90 theta_d x 180 phi_d cells per RGB
//     channel, indexed in Rusinkiewicz's half/difference angles (theta_h on a
//     square-root scale), looked up at the cell holding the pair, as the MERL
//     reading code BRDFRead.cpp does (the Python reader's interpolation="nearest").
//   * NbrdfNetwork: one material's NBRDF network (Sztrajman et al. 2021): input
//     (sin theta_h, 0, cos theta_h, d) of the half vector h and difference vector
//     d, ReLU hidden layers, f = max(exp(y) - 1, 0); the published networks are
//     6 -> 21 -> 21 -> 3 (the Python reader hybridbrdf.sources.nbrdf).
//
// Both take direction pairs as (n, 3) row-major arrays (local frame, wi toward
// the light) and write f (n, 3) without the cosine; pairs with a direction at or
// below the horizon (or not normalisable) give 0.
#pragma once

#include <cstddef>
#include <vector>

namespace hbrdf {

/// MERL table dimensions.
inline constexpr int kMerlThetaH = 90, kMerlThetaD = 90, kMerlPhiD = 180;

class MerlTable {
public:
    /// `rgb`: kMerlThetaH x kMerlThetaD x kMerlPhiD cells (theta_h slowest) of RGB
    /// values (physical, scale applied), 3 floats per cell. Throws
    /// std::invalid_argument for another size.
    explicit MerlTable(std::vector<float> rgb);
    /// f for n pairs, the nearest-cell lookup of BRDFRead.cpp.
    void eval_batch(std::size_t n, const float* wi, const float* wo, float* f) const;
    /// Bytes of the table (float32; the MERL files store float64, twice this).
    std::size_t memory_bytes() const { return rgb_.size() * sizeof(float); }

private:
    std::vector<float> rgb_;
};

class NbrdfNetwork {
public:
    /// One dense layer: weight (n_out x n_in, row-major), bias (n_out).
    struct Layer {
        int n_in = 0, n_out = 0;
        std::vector<float> weight, bias;
    };
    /// Layers in order: 6 inputs, 3 outputs, chained sizes, ReLU after every
    /// layer but the last. Throws std::invalid_argument otherwise.
    explicit NbrdfNetwork(std::vector<Layer> layers);
    /// f for n pairs.
    void eval_batch(std::size_t n, const float* wi, const float* wo, float* f) const;
    /// Bytes of the weights and biases (float32): what one material costs.
    std::size_t memory_bytes() const;

private:
    std::vector<Layer> layers_;
    int max_width_ = 0;
};

}  // namespace hbrdf
