// hybridbrdf — tabulated importance sampling of an arbitrary BRDF: the baseline
// of the paper's importance-sampling comparison (Sec. 5.2), in the spirit of
// Lawrence et al. 2004 ("Efficient BRDF importance sampling using a factored
// representation"), without the factorisation: plain per-material tables.
//
// For each outgoing bin the sampler holds a piecewise-constant distribution of
//
//     g(wi; wo) = mean_rgb f(wi, wo) * cos(theta_i)
//
// over the upper hemisphere of incoming directions, on an equal-angle grid
// (theta_i, phi_i) at `resolution_deg` (1 degree: 90 x 360 cells), stored as a
// marginal CDF over theta_i rows and one conditional CDF over phi per row.
//
//   * Isotropic materials: phi is the azimuth of wi relative to wo's, so one
//     table per theta_o bin (90 at 1 degree).
//   * Anisotropic materials: absolute azimuths, and a phi_o axis of
//     kAnisotropicPhiOStepFactor x resolution_deg (10 degrees at 1 degree):
//     90 x 36 tables. A 1-degree phi_o axis would be 4.2 GB per material.
//
// The table for wo is the one of the bin *containing* wo (not the nearest bin
// centre); each table is built as the average of g over its bin (theta_o and,
// anisotropic, phi_o are jittered per sub-sample), so it covers where the lobe
// goes as wo moves across the bin.
//
// Sampling is a one-sample mixture with a defensive cosine lobe:
//
//     pdf(wi | wo) = c cos(theta_i) / pi + (1 - c) P(cell) / |cell|,   c = kTabulatedDefensiveFraction
//
// where |cell| = (cos theta_0 - cos theta_1) dphi is the cell's solid angle, and
// the position inside the cell is uniform in (cos theta, phi), i.e. uniform in
// solid angle. The cosine part keeps the pdf positive wherever f cos can be
// positive, so the estimator f cos / pdf stays unbiased even where the table
// missed a peak narrower than its cells or was built with the wrong isotropy.
// Densities are over the whole sphere (0 below the horizon) and integrate to 1.
// See docs/SAMPLING.md.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "hybridbrdf/sampling.hpp"

namespace hbrdf {

/// A BRDF evaluated in batches: wi, wo (n, 3) row-major in (local frame of
/// docs/CONVENTIONS.md: +z normal, +x tangent; wi toward the light, wo toward
/// the viewer), f (n, 3) RGB out, without the cosine. Negative or non-finite
/// outputs are treated as 0 by the tabulation.
using BatchEval = std::function<void(std::size_t n, const float* wi, const float* wo, float* f)>;

/// Probability of the defensive cosine lobe in TabulatedSampler's mixture.
inline constexpr double kTabulatedDefensiveFraction = 0.1;
/// Sub-samples of g per table cell (a 2 x 2 stratified, jittered grid in
/// (cos theta_i, phi_i), each paired with its own jittered wo in the bin).
inline constexpr int kTabulatedSubsamples = 4;
/// Anisotropic tables: the phi_o step is about this many times resolution_deg.
inline constexpr int kAnisotropicPhiOStepFactor = 10;
/// Directions per eval() call while building (pairs).
inline constexpr std::size_t kTabulatedBuildBatch = 65536;

/// How a TabulatedSampler stores its tables.
enum class TabulatedStorage {
    /// Conditional CDFs as 16-bit fixed point (k / 65535) and, for isotropic
    /// tables, the azimuth folded by the mirror symmetry phi -> -phi (half the
    /// columns; the build averages g over each mirrored pair of cells): 2.9 MB
    /// per isotropic material at 1 degree, a quarter of Full, under the 5.62 MB
    /// of the paper's 1-degree table. The default.
    Compact,
    /// float32 CDFs over the full azimuth (11.7 MB isotropic at 1 degree): the
    /// uncompressed reference Compact is measured against (docs/SAMPLING.md).
    Full,
};

/// Tabulated importance sampler for one material. Immutable once built;
/// pdf() is thread-safe, sample() is thread-safe if the BatchEval it was built
/// with is (it calls it once per sample for the weight).
class TabulatedSampler {
public:
    /// An empty sampler: sample() returns "no sample", pdf() is 0, no memory.
    TabulatedSampler() = default;

    /// Tabulates g = mean_rgb(f) cos(theta_i) through `eval` (batched,
    /// kTabulatedBuildBatch pairs per call; kTabulatedSubsamples evaluations per
    /// cell: 11.7 M at 1 degree isotropic, 420 M anisotropic) and builds the
    /// CDFs. `isotropic` selects relative-azimuth tables (see the file comment).
    /// `resolution_deg` must divide 90 (1, 2, 3, 5, 6, 9, 10, 15, 18, 30, 45, 90);
    /// throws std::invalid_argument otherwise.
    ///
    /// `eval` is copied into the sampler and called again by sample() for the
    /// weight: whatever it refers to must outlive the sampler.
    ///
    /// `storage` chooses the table layout (TabulatedStorage; Compact by default).
    static TabulatedSampler build(const BatchEval& eval, bool isotropic, int resolution_deg = 1,
                                  TabulatedStorage storage = TabulatedStorage::Compact);

    /// Samples wi for viewing direction wo (normalised; any length) from u in
    /// [0, 1)^2 (clamped into it, NaN -> 0). u.x picks the defensive cosine lobe
    /// (u.x < kTabulatedDefensiveFraction) or the table and is rescaled to pick
    /// the theta_i row and the position in cos theta inside it; u.y picks the
    /// phi cell and the position in phi inside it. Returns pdf == pdf(wi, wo)
    /// and weight = f(wi, wo) cos(theta_i) / pdf. pdf == 0 means no sample (wo
    /// invalid or at/below the horizon, or an empty sampler): then wi = +z and
    /// weight = 0, the contract of hbrdf::sample().
    BrdfSample sample(const Vec3<float>& wo, const Vec2<float>& u) const;

    /// sample() without the weight: the same wi and pdf, weight = 0, and no
    /// call into the BRDF. For callers that evaluate f themselves (in batches,
    /// like the path tracer), where one scalar evaluation per sample through a
    /// network or a Python reader would cost more than the sampling.
    BrdfSample sample_direction(const Vec3<float>& wo, const Vec2<float>& u) const;

    /// Solid-angle density with which sample() draws wi given wo, over the
    /// whole sphere. Directions are normalised; 0 when either is invalid (zero
    /// length, NaN/Inf), wo.z <= 0 or wi.z <= 0.
    float pdf(const Vec3<float>& wi, const Vec3<float>& wo) const;

    /// Bytes of the tables this sampler holds (CDFs and per-row constants;
    /// excludes the copied BatchEval and the object itself).
    std::size_t memory_bytes() const;

    /// memory_bytes() of a sampler that build() would make, computed without
    /// building it (0 when `resolution_deg` is not one build() accepts): the
    /// renderer checks a scene's tables against its budget before building any.
    static std::size_t table_bytes(bool isotropic, int resolution_deg,
                                   TabulatedStorage storage = TabulatedStorage::Compact);
    /// Bytes of the working buffers build() holds while it runs (freed when it
    /// returns): the sub-sample directions and the per-cell means.
    static std::size_t build_scratch_bytes(int resolution_deg);

    bool isotropic() const { return isotropic_; }
    TabulatedStorage storage() const { return storage_; }
    /// True when the azimuth is folded by mirror symmetry (Compact and isotropic).
    bool mirrored() const { return mirrored_; }
    int resolution_deg() const { return resolution_deg_; }
    /// theta_i rows (= theta_o bins) and phi_i columns of every table.
    int theta_bins() const { return n_theta_; }
    int phi_bins() const { return n_phi_; }
    /// phi_o bins: 1 for isotropic samplers.
    int phi_o_bins() const { return n_phi_o_; }
    /// Number of 2D tables (theta_o bins x phi_o bins).
    int table_count() const { return n_theta_ * n_phi_o_; }

private:
    // Index of the table that holds wo's bin; wo unit with wo.z > 0.
    int table_index(const Vec3<double>& wo) const;
    // P(row) P(col | row) of a cell of table t (the exact probability with
    // which the table part of sample() picks it).
    double cell_probability(int t, int row, int col) const;
    // Table-part pick: row and column from (ux, uy), with the remainders
    // rescaled to [0, 1) for the position inside the cell.
    void sample_cell(int t, double ux, double uy, int& row, int& col, double& rx, double& ry) const;

    // Conditional CDF entry k of (table t, row r), as a probability in [0, 1].
    double conditional(std::size_t row_start, int k) const {
        return storage_ == TabulatedStorage::Full ? double(conditional_cdf_[row_start + std::size_t(k)])
                                                  : conditional_cdf_q_[row_start + std::size_t(k)] * (1.0 / 65535.0);
    }
    bool isotropic_ = true;
    TabulatedStorage storage_ = TabulatedStorage::Compact;
    bool mirrored_ = false;
    int n_col_ = 0;    ///< stored columns per row: n_phi_, or n_phi_ / 2 when mirrored
    int resolution_deg_ = 0;
    int n_theta_ = 0;  ///< theta_i rows and theta_o bins: 90 / resolution_deg
    int n_phi_ = 0;    ///< phi_i columns: 360 / resolution_deg
    int n_phi_o_ = 0;  ///< phi_o bins: 1 (isotropic) or about 36 / resolution_deg
    double dtheta_ = 0, dphi_ = 0, dphi_o_ = 0;  ///< bin widths in radians

    /// cos of the theta_i row boundaries, n_theta_ + 1 values, decreasing from 1 to 0.
    std::vector<double> cos_bound_;
    /// 1 / (cell solid angle) per row: 1 / ((cos_bound_[r] - cos_bound_[r+1]) dphi).
    std::vector<float> inv_cell_solid_angle_;
    /// Per table: n_theta_ marginal CDF values over rows (inclusive: entry r is
    /// P(row <= r); the last is 1).
    std::vector<float> marginal_cdf_;
    /// Per table and row: n_col_ conditional CDF values over the stored columns
    /// (inclusive), float32 (Full) or 16-bit fixed point, k / 65535 (Compact).
    std::vector<float> conditional_cdf_;
    std::vector<std::uint16_t> conditional_cdf_q_;

    BatchEval eval_;
};

}  // namespace hbrdf
