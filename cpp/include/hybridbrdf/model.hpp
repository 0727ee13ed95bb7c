// hybridbrdf — fitted models at run time: read a model file (safetensors +
// JSON metadata, docs/FITTING.md) and evaluate the hybrid model
//
//     f_t(wi, wo) = f_c + f_g f_a,   (f_c, f_g) = psi(wi, wo, z)      (paper Eq. 1)
//
// its ablation variants and the fully neural baseline, without Python.
// Thread-safe: a loaded model is immutable and every evaluation keeps its own
// scratch space (on the stack for the scalar path, per call for the batched one).
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

#include "hybridbrdf/analytic.hpp"
#include "hybridbrdf/batch.hpp"
#include "hybridbrdf/spec.hpp"
#include "hybridbrdf/text.hpp"

namespace hbrdf {

/// Kernel HybridModel::eval_batch uses on this CPU: "avx512", "avx2+fma" or "baseline"
/// (force_baseline_simd(true) selects "baseline").
const char* model_simd_path();

/// Caps the kernel model_simd_path() may pick ("avx512" = no cap, "avx2+fma", "baseline"),
/// so that tests and benchmarks can run every kernel on one machine. Throws
/// std::invalid_argument for any other name.
void limit_model_simd(const std::string& path);

/// A model file that is missing, truncated, malformed or inconsistent.
/// what() is "<path>: <problem>", one line.
/// The problem is made printable (one_line_text): a damaged file's bytes never reach a
/// terminal or a Python str raw.
class ModelFileError : public std::runtime_error {
public:
    ModelFileError(const std::string& path, const std::string& problem)
        : std::runtime_error(path + ": " + one_line_text(problem)), path_(path), problem_(one_line_text(problem)) {}
    const std::string& path() const { return path_; }
    const std::string& problem() const { return problem_; }

private:
    std::string path_, problem_;
};

/// Architectures and activations are declared once, in the model contract (spec/model.json).
using ModelKind = spec::ModelKind;
using Activation = spec::Activation;
using OutputLayer = spec::OutputLayer;
using EnergyBound = spec::EnergyBound;

/// Widest layer and longest input the scalar path keeps on the stack.
inline constexpr int kMaxLayerWidth = spec::kMaxWidth;

/// One dense layer, y = W x + b, W row-major (n_out rows of n_in).
struct DenseLayer {
    int n_in = 0, n_out = 0;
    std::vector<float> weight;
    std::vector<float> bias;
};

struct ModelMaterial {
    std::string name;
    std::string origin;
    bool isotropic = true;
    AnalyticParams params;     ///< unused by the neural baseline
    std::vector<float> latent; ///< z
    DenseLayer head;           ///< the material's own output layer (OutputLayer::Material), else empty
    /// k_j of the energy bound f = k(wi.z) k(wo.z) f_t (EnergyBound::AlbedoTable: spec::kEnergyNodes
    /// values in [0, 1]), else empty. docs/ENERGY.md.
    std::vector<float> energy_bound;
};

/// k(cos_theta) of an energy-bound table (spec/model.json, energy_bounds): the hat-function sum
/// sum_j k_j max(0, 1 - |x (K - 1) - j|), linear between the nodes x_j = j / (K - 1). Written as
/// the generated shaders write it (a loop over the nodes, no index arithmetic), so that every
/// implementation rounds alike; 1 for an empty table.
float energy_bound_scale(const std::vector<float>& table, float cos_theta);

/// One layer of a texel of a textured material (spec/model.json, svbrdf; docs/SVBRDF.md): material
/// `material`'s output layer and energy table with the texel's own analytic parameters and latent
/// code (`latent`: latent_dim() floats), weighted by `weight` in the texel's mixture.
struct TexelLayer {
    int material = 0;
    AnalyticParams params;
    const float* latent = nullptr;
    float weight = 0.f;
};

class HybridModel {
public:
    /// Pairs per structure-of-arrays chunk of the batched kernels: a call of a multiple of it
    /// leaves no lane idle (a partial last chunk costs a whole one).
    static constexpr std::size_t kBatchChunk = 64;
    /// Reads and validates a model file; throws ModelFileError naming the file and the problem.
    static HybridModel load(const std::string& path);

    ModelKind kind() const { return kind_; }
    Activation activation() const { return activation_; }
    int width() const { return width_; }
    int depth() const { return depth_; }
    int latent_dim() const { return latent_; }
    /// Bound on every value passed to exp(), as the file records it (arch.pre_exp_max).
    float pre_exp_max() const { return pre_exp_max_; }
    /// The architecture's row of the model contract: input layout, output count, combine rule.
    const spec::ArchSpec& arch() const { return spec::arch_spec(kind_); }
    int conventions_version() const { return conventions_version_; }
    /// Shared (the paper's model) or one output layer per material (spec/model.json, output_layers).
    OutputLayer output_layer_kind() const { return output_layer_; }
    /// Whether each material's f_t is scaled by its energy-bound table (spec/model.json, energy_bounds).
    EnergyBound energy_bound_kind() const { return energy_bound_; }
    const std::vector<ModelMaterial>& materials() const { return materials_; }
    /// The shared layers: the hidden layers, then the output layer when it is shared.
    const std::vector<DenseLayer>& layers() const { return layers_; }
    /// The output layer material m evaluates with: its own, or the shared one.
    const DenseLayer& output_layer(int m) const {
        return output_layer_ == OutputLayer::Material ? materials_[m].head : layers_.back();
    }
    /// Index of a material by name, or -1.
    int find(const std::string& name) const;

    /// f(wi, wo) for material m (no cosine): f_t, times k(wi.z) k(wo.z) with an energy bound. Directions are normalised; 0 when
    /// either is below the horizon or invalid.
    Vec3<float> eval(int m, const Vec3<float>& wi, const Vec3<float>& wo) const;
    /// f of a texel of a textured material: sum_k weight_k f_t(params_k, latent_k) with material_k's
    /// output layer and energy table (hybrid kinds). Layers of weight 0 are not evaluated, so a pure
    /// texel costs one evaluation; a texel whose layers all equal a material's values is that
    /// material (bit for bit: the same operations in the same order). Throws std::out_of_range for a
    /// material index outside the model, std::invalid_argument for a null latent or a non-finite weight.
    Vec3<float> eval_texel(const TexelLayer* layers, int n_layers, const Vec3<float>& wi, const Vec3<float>& wo) const;
    /// The analytic part f_a of material m (hybrid kinds; throws for the neural baseline).
    Vec3<float> eval_analytic(int m, const Vec3<float>& wi, const Vec3<float>& wo) const;
    /// Batched f_t: wi, wo (n, 3) row-major in, f (n, 3) out. Vectorised: chunks of pairs in
    /// structure-of-arrays layout, each layer a broadcast-weight FMA loop over the pairs
    /// (AVX-512 or AVX2+FMA when the CPU has it: model_simd_path()), the latent code folded
    /// into the first layer's bias.
    void eval_batch(int m, std::size_t n, const float* wi, const float* wo, float* f) const;
    /// Batched f_t of texel layers (no weights applied): entry i evaluates layers[i] (its material's
    /// output layer and energy table, its own p and latent code) on wi, wo (n, 3) row-major; f (n, 3).
    /// Vectorised like eval_batch over runs of entries of one material (sort entries by material for
    /// speed; the latent code enters the first layer per lane). Throws as eval_texel does.
    void eval_batch_layers(std::size_t n, const float* wi, const float* wo, const TexelLayer* layers, float* f) const;
    /// Floating-point operations of one batched evaluation's network (multiply-adds count 2),
    /// with the latent folded as eval_batch does; for throughput benchmarks.
    double flops_per_eval() const;

private:
    HybridModel() = default;
    void check_material(int m) const;
    // Runs material m's network on `x` (n_in values); writes n_out values to `out`.
    void run_mlp(int m, const float* x, float* out) const;
    /// f of material m's network, output layer and energy table with f_a `analytic` and latent code `latent`.
    Vec3<float> eval_with(int m, const AnalyticBrdf& analytic, const float* latent, const Vec3<float>& wi_in,
                          const Vec3<float>& wo_in) const;

    ModelKind kind_ = ModelKind::Hybrid;
    Activation activation_ = Activation::HardGelu;
    OutputLayer output_layer_ = OutputLayer::Shared;
    EnergyBound energy_bound_ = EnergyBound::None;
    int width_ = 0, depth_ = 0, latent_ = 0, n_in_ = 0, n_out_ = 0, conventions_version_ = 0;
    float pre_exp_max_ = float(spec::kPreExpMax);
    std::vector<DenseLayer> layers_;  ///< hidden layers, then the output layer when shared
    DenseLayer frames_;               ///< neural baseline: latent -> 3 frames (18 values)
    std::vector<ModelMaterial> materials_;
    std::vector<AnalyticBrdf> analytic_;  ///< per material, prepared once
    // Batched path, prepared at load (see model_batch.cpp):
    int n_dir_inputs_ = 0;                       ///< first-layer inputs that vary per pair
    std::vector<float> w0_dirs_;                 ///< first-layer weights of those inputs (width x n_dir_inputs)
    std::vector<std::vector<float>> bias0_;      ///< per material: b0 + W0[:, z] z
    std::vector<std::vector<float>> frame_cache_;  ///< neural, per material: 3 frames x (t, b, n) x 3
    void prepare_batch();
    friend struct ModelBatchKernels;
};

}  // namespace hbrdf
