// hybridbrdf — tabulated importance sampling (see hybridbrdf/tabulated.hpp and
// docs/SAMPLING.md for the design and its numbers).
#include "hybridbrdf/tabulated.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace hbrdf {

namespace {

constexpr double kHalfPi = 0.5 * kPi<double>;
constexpr double kTwoPi = 2.0 * kPi<double>;
/// Largest double below 1: remainders are clamped to [0, kOneMinusEpsD].
constexpr double kOneMinusEpsD = kOneMinusEps<double>;

/// Jittered wo per stratum of the outgoing bin: a pool of kWoStrata x
/// kWoJitters directions per table, from which every (cell, sub-sample) picks
/// one by hash. Precomputing them keeps trigonometry out of the 11.7 M (420 M
/// anisotropic) evaluation loop while still giving each cell its own wo.
constexpr int kWoStrata = kTabulatedSubsamples;  // theta_o strata
constexpr int kWoJitters = 16;                   // jittered wo per stratum (phi_o strata, anisotropic)

/// 32-bit integer hash (a multiply-xorshift finaliser in the style of
/// MurmurHash3's fmix32): decorrelates consecutive indices for the jitter.
inline std::uint32_t hash32(std::uint32_t x) {
    x ^= x >> 16;
    x *= 0x7feb352dU;
    x ^= x >> 15;
    x *= 0x846ca68bU;
    x ^= x >> 16;
    return x;
}

/// Deterministic jitter in [0, 1) for a (stream, index) pair: the build must be
/// reproducible, so no global random state.
inline double jitter(std::uint32_t stream, std::uint32_t index) {
    return double(hash32(index ^ hash32(stream + 0x9e3779b9U)) >> 8) * (1.0 / 16777216.0);
}

/// Unit direction from the cosine of its polar angle and its azimuth; sin
/// theta from (1 - z)(1 + z), which keeps its precision near the pole.
inline Vec3<double> direction(double cos_theta, double phi) {
    const double sin_theta = std::sqrt(std::max(0.0, (1.0 - cos_theta) * (1.0 + cos_theta)));
    return Vec3<double>(sin_theta * std::cos(phi), sin_theta * std::sin(phi), cos_theta);
}

/// Normalises a float direction in double; returns false (and leaves `out`
/// unspecified) when it cannot be normalised (CONVENTIONS: invalid directions).
inline bool normalized(const Vec3<float>& v, Vec3<double>& out) {
    const float inv_len = inverse_length_or_zero(v);
    if (!(inv_len > 0.0f)) return false;
    out = Vec3<double>(v) * (1.0 / std::sqrt(dot(Vec3<double>(v), Vec3<double>(v))));
    return true;
}

/// Azimuth in [0, 2 pi); 0 on the pole, where atan2(+-0, +-0) would give 0, pi
/// or -pi depending on the signs of the zeros.
inline double azimuth(double x, double y) {
    if (x == 0.0 && y == 0.0) return 0.0;
    const double phi = std::atan2(y, x);
    return phi < 0.0 ? phi + kTwoPi : phi;
}

/// Index of the equal-width bin of [0, n width) holding x, clamped to [0, n - 1]
/// (x may round onto the upper end).
inline int bin_index(double x, double width, int n) {
    const double b = std::floor(x / width);
    return b <= 0.0 ? 0 : (b >= double(n - 1) ? n - 1 : int(b));
}

/// Inverts an inclusive CDF of n entries (entry k is P(cell <= k) / scale; the
/// last is 1 / scale) at u in [0, 1): the first entry above u, i.e. the cell
/// whose [cdf[k-1], cdf[k]) holds u. Cells of zero probability (equal
/// neighbours) are never returned. `remainder` is u's position inside that
/// cell, rescaled to [0, 1) for reuse. float CDFs have scale 1, 16-bit ones
/// 1 / 65535.
template <class T> inline int invert_cdf(const T* cdf, int n, double scale, double u, double& remainder) {
    const double v = u / scale;
    const int k = int(std::upper_bound(cdf, cdf + n, v, [](double a, T b) { return a < double(b); }) - cdf);
    const int idx = std::min(k, n - 1);  // only reached if u >= 1, which callers rule out
    const double lo = idx > 0 ? double(cdf[idx - 1]) * scale : 0.0;
    const double hi = double(cdf[idx]) * scale;
    const double r = hi > lo ? (u - lo) / (hi - lo) : 0.0;
    remainder = clamp_nan_lo(r, 0.0, kOneMinusEpsD);
    return idx;
}

/// Writes the inclusive CDF of `mass` (n non-negative values, positive sum) to
/// `cdf` in float, with the last entry exactly 1. Accumulated in double;
/// rounding to float is monotone, so the CDF stays non-decreasing.
inline void write_cdf(const double* mass, int n, double total, float* cdf) {
    double acc = 0.0;
    for (int k = 0; k < n; ++k) {
        acc += mass[k];
        cdf[k] = float(std::min(acc / total, 1.0));
    }
    cdf[n - 1] = 1.0f;
}

/// The same CDF in 16-bit fixed point, entry = round(65535 P(cell <= k)): the
/// rounding of a non-decreasing sequence is non-decreasing, and the last entry
/// is exactly 65535. A cell whose probability is below half a step can round to
/// an empty cell; the defensive cosine lobe keeps the sampler unbiased there.
inline void write_cdf_q16(const double* mass, int n, double total, std::uint16_t* cdf) {
    double acc = 0.0;
    for (int k = 0; k < n; ++k) {
        acc += mass[k];
        cdf[k] = std::uint16_t(std::lround(std::min(acc / total, 1.0) * 65535.0));
    }
    cdf[n - 1] = 65535;
}

}  // namespace

TabulatedSampler TabulatedSampler::build(const BatchEval& eval, bool isotropic, int resolution_deg,
                                         TabulatedStorage storage) {
    if (!eval) throw std::invalid_argument("TabulatedSampler::build: empty BatchEval");
    if (resolution_deg < 1 || resolution_deg > 90 || 90 % resolution_deg != 0)
        throw std::invalid_argument("TabulatedSampler::build: resolution_deg = " + std::to_string(resolution_deg) +
                                    " must divide 90 (1, 2, 3, 5, 6, 9, 10, 15, 18, 30, 45 or 90)");

    TabulatedSampler s;
    s.isotropic_ = isotropic;
    s.storage_ = storage;
    // Mirror symmetry of isotropic BRDFs about the plane of incidence: cell c and
    // cell n_phi - 1 - c of relative azimuth share one stored column.
    s.mirrored_ = isotropic && storage == TabulatedStorage::Compact;
    s.resolution_deg_ = resolution_deg;
    s.n_theta_ = 90 / resolution_deg;
    s.n_phi_ = 360 / resolution_deg;  // even for every allowed resolution
    s.n_col_ = s.mirrored_ ? s.n_phi_ / 2 : s.n_phi_;
    // Anisotropic: phi_o every ~10 x resolution_deg (36 bins at 1 degree). The
    // exact step is 360 / n_phi_o_, so the bins tile the circle.
    s.n_phi_o_ = isotropic ? 1 : std::max(1, int(std::lround(36.0 / resolution_deg)));
    s.dtheta_ = kHalfPi / s.n_theta_;
    s.dphi_ = kTwoPi / s.n_phi_;
    s.dphi_o_ = kTwoPi / s.n_phi_o_;
    s.eval_ = eval;

    const int n_theta = s.n_theta_, n_phi = s.n_phi_;
    s.cos_bound_.resize(std::size_t(n_theta) + 1);
    for (int r = 0; r <= n_theta; ++r) s.cos_bound_[std::size_t(r)] = std::cos(r * s.dtheta_);
    s.cos_bound_[std::size_t(n_theta)] = 0.0;  // cos(pi/2) exactly: the table ends at the horizon
    s.inv_cell_solid_angle_.resize(std::size_t(n_theta));
    std::vector<double> cell_solid_angle(static_cast<std::size_t>(n_theta));
    for (int r = 0; r < n_theta; ++r) {
        // cos a - cos b = 2 sin((a+b)/2) sin((b-a)/2): no cancellation near the pole.
        const double a = r * s.dtheta_, b = (r + 1) * s.dtheta_;
        cell_solid_angle[std::size_t(r)] = 2.0 * std::sin(0.5 * (a + b)) * std::sin(0.5 * (b - a)) * s.dphi_;
        s.inv_cell_solid_angle_[std::size_t(r)] = float(1.0 / cell_solid_angle[std::size_t(r)]);
    }

    // Sub-sample positions of wi, shared by every table: per cell a 2 x 2
    // stratified grid in (cos theta, phi), jittered, i.e. stratified uniform in
    // solid angle, so that mean(g) * |cell| estimates the cell's integral of g.
    const int n_cells = n_theta * n_phi;
    const std::size_t n_pairs = std::size_t(n_cells) * kTabulatedSubsamples;
    std::vector<float> wi_sub(3 * n_pairs), cos_i_sub(n_pairs);
    for (int r = 0; r < n_theta; ++r) {
        const double c0 = s.cos_bound_[std::size_t(r)], c1 = s.cos_bound_[std::size_t(r) + 1];
        for (int c = 0; c < n_phi; ++c)
            for (int k = 0; k < kTabulatedSubsamples; ++k) {
                const std::size_t p = (std::size_t(r) * n_phi + c) * kTabulatedSubsamples + k;
                const double tc = ((k & 1) + jitter(1, std::uint32_t(p))) * 0.5;
                const double tp = ((k >> 1) + jitter(2, std::uint32_t(p))) * 0.5;
                const Vec3<double> w = direction(c0 - tc * (c0 - c1), (c + tp) * s.dphi_);
                wi_sub[3 * p] = float(w.x), wi_sub[3 * p + 1] = float(w.y), wi_sub[3 * p + 2] = float(w.z);
                cos_i_sub[p] = float(w.z);
            }
    }

    const int n_tables = s.table_count(), n_col = s.n_col_;
    s.marginal_cdf_.resize(std::size_t(n_tables) * n_theta);
    if (storage == TabulatedStorage::Full)
        s.conditional_cdf_.resize(std::size_t(n_tables) * n_theta * n_col);
    else
        s.conditional_cdf_q_.resize(std::size_t(n_tables) * n_theta * n_col);

    const std::size_t batch = std::min(kTabulatedBuildBatch, n_pairs);
    std::vector<float> wo_buf(3 * batch), f_buf(3 * batch);
    std::vector<float> wo_pool(3 * kWoStrata * kWoJitters);
    std::vector<double> mean_g(static_cast<std::size_t>(n_cells)), row_mass(static_cast<std::size_t>(n_theta));

    for (int t = 0; t < n_tables; ++t) {
        const int bin_theta_o = t / s.n_phi_o_, bin_phi_o = t % s.n_phi_o_;
        // wo pool: theta_o stratified in kWoStrata strata over the bin, phi_o
        // (anisotropic) stratified in kWoJitters strata; isotropic tables put wo
        // in the xz-plane, so phi_i of a sub-sample is its azimuth relative to wo.
        for (int k = 0; k < kWoStrata; ++k)
            for (int m = 0; m < kWoJitters; ++m) {
                const std::uint32_t id = std::uint32_t((t * kWoStrata + k) * kWoJitters + m);
                const double theta_o = (bin_theta_o + (k + jitter(3, id)) / kWoStrata) * s.dtheta_;
                const double phi_o = isotropic ? 0.0 : (bin_phi_o + (m + jitter(4, id)) / kWoJitters) * s.dphi_o_;
                const Vec3<double> w = direction(std::cos(theta_o), phi_o);
                float* o = &wo_pool[3 * std::size_t(k * kWoJitters + m)];
                o[0] = float(w.x), o[1] = float(w.y), o[2] = float(w.z);
            }

        std::fill(mean_g.begin(), mean_g.end(), 0.0);
        for (std::size_t start = 0; start < n_pairs; start += batch) {
            const std::size_t nb = std::min(batch, n_pairs - start);
            for (std::size_t q = 0; q < nb; ++q) {
                const std::size_t p = start + q;
                // Sub-sample k of a cell takes theta_o stratum (k + 1) mod 4: the
                // pairing is a Latin square over (wi stratum, wo stratum), so no
                // wi stratum always sees the same end of the wo bin.
                const int k = int(p % kTabulatedSubsamples);
                const int stratum = (k + 1) % kWoStrata;
                const int m = int(hash32(std::uint32_t(p) ^ hash32(std::uint32_t(t) + 0x632be5abU)) >> 28);
                const float* o = &wo_pool[3 * std::size_t(stratum * kWoJitters + m)];
                wo_buf[3 * q] = o[0], wo_buf[3 * q + 1] = o[1], wo_buf[3 * q + 2] = o[2];
            }
            eval(nb, &wi_sub[3 * start], wo_buf.data(), f_buf.data());
            for (std::size_t q = 0; q < nb; ++q) {
                const std::size_t p = start + q;
                const double f_mean = (double(f_buf[3 * q]) + f_buf[3 * q + 1] + f_buf[3 * q + 2]) * (1.0 / 3.0);
                const double g = f_mean * cos_i_sub[p];
                // Measured data can be negative (noise) and a model may return
                // NaN/Inf: neither is a probability. Written so that NaN fails.
                const bool usable = g > 0.0 && g <= double(std::numeric_limits<float>::max());
                mean_g[p / kTabulatedSubsamples] += usable ? g * (1.0 / kTabulatedSubsamples) : 0.0;
            }
        }

        // Mirrored tables: the first n_col cells of a row become the mean of each
        // cell and its mirror image (the same 4 sub-samples per cell, 8 per column).
        if (s.mirrored_)
            for (int r = 0; r < n_theta; ++r) {
                double* row = &mean_g[std::size_t(r) * n_phi];
                for (int c = 0; c < n_col; ++c) row[c] = 0.5 * (row[c] + row[n_phi - 1 - c]);
            }
        // Cell integral = mean(g) x cell solid angle; all cells of a row share
        // the solid angle, so it only enters the marginal. Only the first n_col
        // cells of each row are read from here on.
        double total = 0.0;
        for (int r = 0; r < n_theta; ++r) {
            double sum = 0.0;
            for (int c = 0; c < n_col; ++c) sum += mean_g[std::size_t(r) * n_phi + c];
            row_mass[std::size_t(r)] = sum * cell_solid_angle[std::size_t(r)] * (double(n_phi) / n_col);
            total += row_mass[std::size_t(r)];
        }
        if (!(total > 0.0) || !std::isfinite(total)) {
            // f = 0 everywhere for this bin (a black material) or overflow: fall
            // back to the cosine distribution, so the table part is still a
            // valid density. Cell integral of cos: (c0^2 - c1^2) / 2 dphi.
            total = 0.0;
            for (int r = 0; r < n_theta; ++r) {
                const double c0 = s.cos_bound_[std::size_t(r)], c1 = s.cos_bound_[std::size_t(r) + 1];
                row_mass[std::size_t(r)] = 0.5 * (c0 - c1) * (c0 + c1) * s.dphi_ * n_phi;
                total += row_mass[std::size_t(r)];
                for (int c = 0; c < n_phi; ++c) mean_g[std::size_t(r) * n_phi + c] = 1.0;
            }
        }
        write_cdf(row_mass.data(), n_theta, total, &s.marginal_cdf_[std::size_t(t) * n_theta]);
        for (int r = 0; r < n_theta; ++r) {
            const double* row = &mean_g[std::size_t(r) * n_phi];
            std::vector<double> uniform;
            double sum = 0.0;
            for (int c = 0; c < n_col; ++c) sum += row[c];
            if (!(sum > 0.0)) {
                // A row the marginal never picks (probability 0): any valid CDF.
                uniform.assign(std::size_t(n_col), 1.0);
                row = uniform.data();
                sum = n_col;
            }
            const std::size_t at = (std::size_t(t) * n_theta + r) * n_col;
            if (storage == TabulatedStorage::Full)
                write_cdf(row, n_col, sum, &s.conditional_cdf_[at]);
            else
                write_cdf_q16(row, n_col, sum, &s.conditional_cdf_q_[at]);
        }
    }
    return s;
}

int TabulatedSampler::table_index(const Vec3<double>& wo) const {
    const int bin_theta = bin_index(std::acos(std::min(wo.z, 1.0)), dtheta_, n_theta_);
    if (isotropic_) return bin_theta;
    const int bin_phi = bin_index(azimuth(wo.x, wo.y), dphi_o_, n_phi_o_);
    return bin_theta * n_phi_o_ + bin_phi;
}

double TabulatedSampler::cell_probability(int t, int row, int col) const {
    const float* m = &marginal_cdf_[std::size_t(t) * n_theta_];
    const std::size_t at = (std::size_t(t) * n_theta_ + row) * n_col_;
    const double p_row = double(m[row]) - (row > 0 ? double(m[row - 1]) : 0.0);
    const double p_col = conditional(at, col) - (col > 0 ? conditional(at, col - 1) : 0.0);
    return p_row * p_col;
}

void TabulatedSampler::sample_cell(int t, double ux, double uy, int& row, int& col, double& rx,
                                   double& ry) const {
    row = invert_cdf(&marginal_cdf_[std::size_t(t) * n_theta_], n_theta_, 1.0, ux, rx);
    const std::size_t at = (std::size_t(t) * n_theta_ + row) * n_col_;
    col = storage_ == TabulatedStorage::Full ? invert_cdf(&conditional_cdf_[at], n_col_, 1.0, uy, ry)
                                             : invert_cdf(&conditional_cdf_q_[at], n_col_, 1.0 / 65535.0, uy, ry);
}

namespace {

/// Cosine and sine of wo's azimuth, (1, 0) on the pole: isotropic tables are
/// in the frame rotated so that wo lies in the xz-plane.
inline void azimuth_frame(const Vec3<double>& wo, double& c, double& s) {
    const double r = std::sqrt(wo.x * wo.x + wo.y * wo.y);
    if (r > 0.0) {
        c = wo.x / r, s = wo.y / r;
    } else {
        c = 1.0, s = 0.0;
    }
}

}  // namespace

float TabulatedSampler::pdf(const Vec3<float>& wi_in, const Vec3<float>& wo_in) const {
    Vec3<double> wi, wo;
    if (marginal_cdf_.empty() || !normalized(wi_in, wi) || !normalized(wo_in, wo)) return 0.0f;
    if (!(wi.z > 0.0) || !(wo.z > 0.0)) return 0.0f;

    const int t = table_index(wo);
    double x = wi.x, y = wi.y;
    if (isotropic_) {
        double c, s;
        azimuth_frame(wo, c, s);
        x = c * wi.x + s * wi.y;
        y = -s * wi.x + c * wi.y;
    }
    const int row = bin_index(std::acos(std::min(wi.z, 1.0)), dtheta_, n_theta_);
    const int cell = bin_index(azimuth(x, y), dphi_, n_phi_);
    // A mirrored column's probability is shared by its two cells.
    const int col = mirrored_ && cell >= n_col_ ? n_phi_ - 1 - cell : cell;
    const double p_table =
        cell_probability(t, row, col) * inv_cell_solid_angle_[std::size_t(row)] * (mirrored_ ? 0.5 : 1.0);
    const double p_cos = wi.z * kInvPi<double>;
    return float(kTabulatedDefensiveFraction * p_cos + (1.0 - kTabulatedDefensiveFraction) * p_table);
}

BrdfSample TabulatedSampler::sample_direction(const Vec3<float>& wo_in, const Vec2<float>& u_in) const {
    BrdfSample no_sample;
    no_sample.wi = Vec3<float>(0.0f, 0.0f, 1.0f);
    no_sample.pdf = 0.0f;
    no_sample.weight = Vec3<float>(0.0f);

    Vec3<double> wo;
    if (marginal_cdf_.empty() || !normalized(wo_in, wo) || !(wo.z > 0.0)) return no_sample;
    const Vec2<float> u = clamp_unit_square(u_in);

    Vec3<double> wi;
    const double c_def = kTabulatedDefensiveFraction;
    if (double(u.x) < c_def) {
        // Defensive lobe: u.x rescaled to [0, 1) for the cosine warp.
        const float ux = clamp_nan_lo(float(double(u.x) / c_def), 0.0f, kOneMinusEps<float>);
        wi = Vec3<double>(square_to_cosine_hemisphere(Vec2<float>(ux, u.y)));
    } else {
        const double ux = clamp_nan_lo((double(u.x) - c_def) / (1.0 - c_def), 0.0, kOneMinusEpsD);
        int row, col;
        double rx, ry;
        sample_cell(table_index(wo), ux, double(u.y), row, col, rx, ry);
        if (mirrored_) {
            // The column's two mirrored cells are equally likely: the first half of
            // ry keeps the stored cell, the second takes its mirror image.
            const bool mirror = ry >= 0.5;
            ry = clamp_nan_lo(mirror ? 2.0 * ry - 1.0 : 2.0 * ry, 0.0, kOneMinusEpsD);
            if (mirror) col = n_phi_ - 1 - col;
        }
        // Uniform in cos theta and phi inside the cell = uniform in solid angle.
        const double c0 = cos_bound_[std::size_t(row)], c1 = cos_bound_[std::size_t(row) + 1];
        const Vec3<double> local = direction(c0 - rx * (c0 - c1), (col + ry) * dphi_);
        wi = local;
        if (isotropic_) {
            double c, s;
            azimuth_frame(wo, c, s);
            wi.x = c * local.x - s * local.y;
            wi.y = s * local.x + c * local.y;
        }
    }

    BrdfSample out;
    out.wi = Vec3<float>(wi);
    // The reported pdf is pdf() of the returned direction, so that a renderer's
    // MIS weights see one density whichever way they obtain it.
    out.pdf = pdf(out.wi, wo_in);
    if (!(out.pdf > 0.0f)) return no_sample;  // wi rounded onto the horizon
    out.weight = Vec3<float>(0.0f);
    return out;
}

BrdfSample TabulatedSampler::sample(const Vec3<float>& wo_in, const Vec2<float>& u_in) const {
    BrdfSample out = sample_direction(wo_in, u_in);
    if (!(out.pdf > 0.0f)) return out;
    Vec3<double> wo(0.0, 0.0, 1.0);
    if (!normalized(wo_in, wo)) return out;  // unreachable: sample_direction gave pdf > 0
    const float wi_a[3] = {out.wi.x, out.wi.y, out.wi.z};
    const float wo_a[3] = {float(wo.x), float(wo.y), float(wo.z)};
    float f[3] = {0.0f, 0.0f, 0.0f};
    eval_(1, wi_a, wo_a, f);
    const float cos_i = max0(out.wi.z);
    out.weight = Vec3<float>(f[0], f[1], f[2]) * (cos_i / out.pdf);
    return out;
}

std::size_t TabulatedSampler::table_bytes(bool isotropic, int resolution_deg, TabulatedStorage storage) {
    if (resolution_deg < 1 || resolution_deg > 90 || 90 % resolution_deg != 0) return 0;
    // The sizes build() gives its vectors (kept in step with it; a test compares
    // this with memory_bytes() of built samplers).
    const std::size_t n_theta = std::size_t(90 / resolution_deg), n_phi = std::size_t(360 / resolution_deg);
    const bool mirrored = isotropic && storage == TabulatedStorage::Compact;
    const std::size_t n_col = mirrored ? n_phi / 2 : n_phi;
    const std::size_t n_phi_o = isotropic ? 1 : std::size_t(std::max(1, int(std::lround(36.0 / resolution_deg))));
    const std::size_t n_tables = n_theta * n_phi_o;
    const std::size_t cdf_entry = storage == TabulatedStorage::Full ? sizeof(float) : sizeof(std::uint16_t);
    return (n_theta + 1) * sizeof(double) + n_theta * sizeof(float) + n_tables * n_theta * sizeof(float) +
           n_tables * n_theta * n_col * cdf_entry;
}

std::size_t TabulatedSampler::build_scratch_bytes(int resolution_deg) {
    if (resolution_deg < 1 || resolution_deg > 90 || 90 % resolution_deg != 0) return 0;
    const std::size_t n_theta = std::size_t(90 / resolution_deg), n_cells = n_theta * std::size_t(360 / resolution_deg);
    const std::size_t n_pairs = n_cells * kTabulatedSubsamples;
    const std::size_t batch = std::min(kTabulatedBuildBatch, n_pairs);
    // wi_sub, cos_i_sub, wo_buf + f_buf, mean_g + cell_solid_angle + row_mass.
    return 4 * n_pairs * sizeof(float) + 6 * batch * sizeof(float) + (n_cells + 2 * n_theta) * sizeof(double);
}

std::size_t TabulatedSampler::memory_bytes() const {
    return cos_bound_.size() * sizeof(double) + inv_cell_solid_angle_.size() * sizeof(float) +
           marginal_cdf_.size() * sizeof(float) + conditional_cdf_.size() * sizeof(float) +
           conditional_cdf_q_.size() * sizeof(std::uint16_t);
}

}  // namespace hbrdf
