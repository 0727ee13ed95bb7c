// hybridbrdf renderer — reading a textured material's folder (docs/SVBRDF.md; spec/model.json,
// svbrdf): the index svbrdf.json, the model file it names and its 3-channel maps (8-bit PNG
// through stb_image, float32 OpenEXR through tinyexr), decoded into a Svbrdf. The checks and
// their words are hybridbrdf.svbrdf.asset.load_svbrdf's (tests/python/test_svbrdf.py runs the
// same table of broken folders through both).
#pragma once

#include <memory>
#include <string>

#include "hybridbrdf/svbrdf.hpp"

namespace hbrdf::render {

/// Reads and validates the folder; throws FileError("<file>: <problem>") naming the file at fault
/// (the index, a map, or the model's ModelFileError).
std::shared_ptr<const Svbrdf> load_svbrdf(const std::string& folder);

}  // namespace hbrdf::render
