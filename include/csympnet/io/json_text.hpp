// Reading JSON documents a user can edit (suite files, model files) strictly.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace csympnet {

// Parses `text` as JSON. Throws Error naming `where` and saying what was `expected` when the
// text is not valid JSON, holds a number beyond double range, or repeats a key within one
// object: most JSON readers silently keep the last of two equal keys, so an edited file could
// mean something other than what its author sees first.
nlohmann::json parse_json_text(const std::string& text, const std::string& where,
                               const std::string& expected);

}  // namespace csympnet
