// hybridbrdf — error text that is safe to show: one printable line.
#pragma once

#include <string>

namespace hbrdf {

/// `text` with every control character (U+0000-U+001F, U+007F) and every byte that is not part
/// of valid UTF-8 written as \xNN: one printable line, whatever a damaged file or a hostile scene
/// key put in it. Every input error of the library passes its message through here; the Python
/// package applies the same rule (hybridbrdf.errors.one_line_text), so both report alike.
std::string one_line_text(const std::string& text);

}  // namespace hbrdf
