// Reading JSON documents a user can edit (suite files, model files) strictly.
#pragma once

#include <cmath>
#include <cstddef>
#include <limits>
#include <string>

#include <nlohmann/json.hpp>

namespace csympnet {

// Parses `text` as JSON. Throws Error naming `where` and saying what was `expected` when the
// text is not valid JSON, holds a number beyond double range, or repeats a key within one
// object: most JSON readers silently keep the last of two equal keys, so an edited file could
// mean something other than what its author sees first.
//
// `limits` bounds what the parse may build, checked while parsing (a parsed value takes about
// 20 times its text), so a file too deep or too large for what it claims to be is refused
// with its path instead of exhausting memory. The parse also polls the stop request
// (csympnet/core/stop.hpp).
struct JsonLimits {
  std::size_t max_depth = 64;  // nested objects and arrays
  // Values (numbers, strings, ...) in the top-level array named `bulk_key`, and elsewhere.
  std::string bulk_key;
  std::size_t max_bulk_values = std::numeric_limits<std::size_t>::max();
  std::size_t max_other_values = std::numeric_limits<std::size_t>::max();
};

nlohmann::json parse_json_text(const std::string& text, const std::string& where,
                               const std::string& expected, const JsonLimits& limits = {});

// x as a JSON number, or null where it is not finite (JSON has no NaN or infinity): how the
// reports write a value that could not be computed.
inline nlohmann::json finite_or_null(double x) {
  return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr);
}

}  // namespace csympnet
