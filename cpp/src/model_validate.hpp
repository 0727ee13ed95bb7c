// hybridbrdf — a model file checked against the model contract (spec/model.json), internal to
// libhybridbrdf. Each function is one step of HybridModel::load (model_load.cpp) and throws
// ModelFileError naming the file and the problem. The checks, their order and their words are
// the Python loader's (python/hybridbrdf/model/file.py); tests/data/malformed_models.json holds
// the shared table of broken files both must reject alike.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "hybridbrdf/model.hpp"
#include "model_container.hpp"

namespace hbrdf::model_file {

using json = nlohmann::json;

/// The arch object's values, each checked against its row of the contract's table.
struct Arch {
    ModelKind kind = ModelKind::Hybrid;
    Activation activation = Activation::HardGelu;
    OutputLayer output_layer = OutputLayer::Shared;
    EnergyBound energy_bound = EnergyBound::None;
    int width = 0, depth = 0, latent = 0, n_in = 0, n_out = 0;
    float pre_exp_max = 0.f;
    const spec::ArchSpec& row() const { return spec::arch_spec(kind); }  ///< the architecture's contract row
};

/// Tensor name -> the shape the architecture needs.
using TensorShapes = std::map<std::string, std::vector<std::int64_t>>;

/// The model's JSON document: present under spec::kMetadataKey, nested no deeper than
/// spec::kMaxJsonDepth (checked before parsing), valid JSON, an object.
json read_document(const std::string& path, const std::map<std::string, std::string>& metadata);

/// format_version and conventions_version are integers this library reads (format_version
/// kOldestFormatVersion .. kFormatVersion).
void check_versions(const std::string& path, const json& doc);

/// Every arch field in the contract's table order (so that the first problem reported is the
/// Python loader's too), then the file's format_version against the architecture's since_format
/// (format 1 hybrid-reciprocal files hold the halves encoding: refused), then n_in / n_out against
/// the architecture's input layout.
Arch read_arch(const std::string& path, const json& doc);

/// The materials' records: names by the contract's rule, distinct, and distinct as shader
/// constants; origin and isotropic typed. Parameters and latent codes are not filled in.
std::vector<ModelMaterial> read_materials(const std::string& path, const json& doc);

/// The tensors the architecture needs and their shapes.
TensorShapes expected_tensors(const std::string& path, const Arch& arch, std::int64_t n_materials);

/// No tensor missing, none extra; then in name order each one's shape, and finite values.
void check_tensors(const std::string& path, const std::map<std::string, Tensor>& tensors,
                   const TensorShapes& expected);

/// Each material's kd, eta, alpha inside the contract's ranges (in float32, as Python), and
/// alpha_x == alpha_y for isotropic ones; fills materials[i].params. Material by material.
void read_analytic_params(const std::string& path, const std::map<std::string, Tensor>& tensors,
                          std::vector<ModelMaterial>& materials);

/// With arch.energy_bound 'albedo_table': each material's table inside [0, 1] (NaN fails); fills
/// materials[i].energy_bound. Material by material, node by node.
void read_energy_bounds(const std::string& path, const Arch& arch, const std::map<std::string, Tensor>& tensors,
                        std::vector<ModelMaterial>& materials);

/// Interval bound of every network value (spec::kMaxNetworkValue; the Python loader's
/// network_overflow_problem computes the same). Empty when the network cannot overflow float32.
std::string network_overflow_problem(const std::map<std::string, Tensor>& tensors, const Arch& arch);

}  // namespace hbrdf::model_file
