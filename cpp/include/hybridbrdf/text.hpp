// hybridbrdf — text that input checks share: one printable line of error text, JSON nesting depth.
#pragma once

#include <string>

namespace hbrdf {

/// `text` with every control character (U+0000-U+001F, U+007F) and every byte that is not part
/// of valid UTF-8 written as \xNN: one printable line, whatever a damaged file or a hostile scene
/// key put in it. Every input error of the library passes its message through here; the Python
/// package applies the same rule (hybridbrdf.errors.one_line_text), so both report alike.
std::string one_line_text(const std::string& text);

/// Deepest nesting of arrays and objects in JSON `text`, brackets inside strings not counted
/// (python/hybridbrdf/inputs.py json_depth, the same rule): the contract bounds it
/// (spec::kMaxJsonDepth) so that both loaders refuse the same files, and before parsing, as
/// Python's parser recurses once per level. On malformed text it is a bound the parser then
/// rejects for another reason.
int json_depth(const std::string& text);

}  // namespace hbrdf
