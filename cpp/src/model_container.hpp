// hybridbrdf — the safetensors container of model files, internal to libhybridbrdf.
// model_container.cpp reads it as strictly as the Python side's serde parser (the
// safetensors package): docs/ARCHITECTURE.md, "Where the project stands", spec/model.json.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace hbrdf::model_file {

/// One float32 tensor of a model file, row-major.
struct Tensor {
    std::vector<std::int64_t> shape;
    std::vector<float> data;
};

/// What a safetensors file holds: its string metadata and its tensors, by name.
struct Container {
    std::map<std::string, std::string> metadata;
    std::map<std::string, Tensor> tensors;
};

/// Reads the safetensors container at `path`; throws ModelFileError naming the file and
/// the problem. The header is checked whole (entries, and the data section laid out exactly
/// against the file's real size) before any tensor memory is allocated, and then only the
/// bytes the header declares are read, so a file's length never sizes a buffer by itself.
Container read_safetensors(const std::string& path);

/// A shape as Python prints a tuple: "(3,)", "(6, 16)".
std::string shape_str(const std::vector<std::int64_t>& s);

}  // namespace hbrdf::model_file
