// hybridbrdf — HybridModel::load: a model file (safetensors + JSON metadata, docs/FITTING.md)
// read by model_container.cpp, checked step by step by model_validate.cpp, then assembled into
// the evaluation's layers and materials and prepared for the batched path (model_batch.cpp).
#include <cstdint>
#include <new>
#include <utility>

#include "hybridbrdf/model.hpp"
#include "model_container.hpp"
#include "model_validate.hpp"

namespace hbrdf {
namespace {

using model_file::Tensor;

// The dense layer stored as <prefix>.weight (n_out, n_in) and <prefix>.bias (n_out).
DenseLayer dense_layer(const std::map<std::string, Tensor>& tensors, const std::string& prefix) {
    DenseLayer l;
    const Tensor& w = tensors.at(prefix + ".weight");
    l.n_out = int(w.shape[0]);
    l.n_in = int(w.shape[1]);
    l.weight = w.data;
    l.bias = tensors.at(prefix + ".bias").data;
    return l;
}

// Each material's latent code and, with material output layers, its own output layer: its row
// of materials.z, materials.head_weight and materials.head_bias (shapes checked already).
void read_material_rows(const model_file::Arch& arch, const std::map<std::string, Tensor>& tensors,
                        std::vector<ModelMaterial>& materials) {
    const Tensor& z = tensors.at("materials.z");
    const std::size_t nw = std::size_t(arch.n_out) * arch.width;
    for (std::size_t i = 0; i < materials.size(); ++i) {
        ModelMaterial& mat = materials[i];
        mat.latent.assign(z.data.begin() + i * arch.latent, z.data.begin() + (i + 1) * arch.latent);
        if (arch.output_layer != OutputLayer::Material) continue;
        const Tensor& hw = tensors.at("materials.head_weight");
        const Tensor& hb = tensors.at("materials.head_bias");
        mat.head.n_in = arch.width;
        mat.head.n_out = arch.n_out;
        mat.head.weight.assign(hw.data.begin() + i * nw, hw.data.begin() + (i + 1) * nw);
        mat.head.bias.assign(hb.data.begin() + i * arch.n_out, hb.data.begin() + (i + 1) * arch.n_out);
    }
}

}  // namespace

// The checks and their order follow the model contract (spec/model.json) and are
// the same in the Python loader (model_file.py); tests/data/malformed_models.json
// holds the shared table of broken files both must reject alike.
HybridModel HybridModel::load(const std::string& path) try {
    using namespace model_file;
    const Container file = read_safetensors(path);
    const json doc = read_document(path, file.metadata);
    check_versions(path, doc);
    const Arch arch = read_arch(path, doc);
    std::vector<ModelMaterial> materials = read_materials(path, doc);
    check_tensors(path, file.tensors, expected_tensors(path, arch, std::int64_t(materials.size())));
    read_material_rows(arch, file.tensors, materials);
    if (arch.row().analytic) read_analytic_params(path, file.tensors, materials);
    read_energy_bounds(path, arch, file.tensors, materials);
    // Checked last, as in Python.
    if (const std::string overflow = network_overflow_problem(file.tensors, arch); !overflow.empty())
        throw ModelFileError(path, overflow);

    HybridModel model;
    model.kind_ = arch.kind;
    model.activation_ = arch.activation;
    model.output_layer_ = arch.output_layer;
    model.energy_bound_ = arch.energy_bound;
    model.width_ = arch.width;
    model.depth_ = arch.depth;
    model.latent_ = arch.latent;
    model.n_in_ = arch.n_in;
    model.n_out_ = arch.n_out;
    model.pre_exp_max_ = arch.pre_exp_max;
    model.conventions_version_ = spec::kConventionsVersion;
    for (int i = 0; i < arch.depth; ++i) model.layers_.push_back(dense_layer(file.tensors, "mlp.hidden." + std::to_string(i)));
    if (arch.output_layer == OutputLayer::Shared) model.layers_.push_back(dense_layer(file.tensors, "mlp.out"));
    if (arch.row().directions == spec::DirectionInputs::Frames) model.frames_ = dense_layer(file.tensors, "frames");
    model.materials_ = std::move(materials);
    if (arch.row().analytic)
        for (const ModelMaterial& mat : model.materials_) model.analytic_.emplace_back(mat.params);
    model.prepare_batch();
    return model;
} catch (const std::bad_alloc&) {
    // Whatever the allocation, a model's memory is proportional to its file, which the contract
    // bounds (spec::kMaxDataBytes); what fails below that is this machine's limit, said so.
    throw ModelFileError(path, "needs more memory than this process could allocate");
}

}  // namespace hbrdf
