// hybridbrdf — version numbers.
#pragma once

#include "hybridbrdf/spec.hpp"

namespace hbrdf {

/// Library version (kept equal to pyproject.toml and CMakeLists.txt by a test).
inline constexpr const char* kVersion = "0.1.0";

/// Version of docs/CONVENTIONS.md this code implements. Model files and
/// generated code record it; a change to any shared formula bumps it.
inline constexpr int kConventionsVersion = spec::kConventionsVersion;

}  // namespace hbrdf
