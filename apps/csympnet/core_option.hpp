// The --core option of `train`, `fit` and `run`: a symplectic core as "la:L:m" or "g:L:w".
#pragma once

#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

namespace csympnet::cli {

// {"type": "la", "layers": L, "sublayers": m} (plus "step_terms": 2 for "la:L:m:h2") or
// {"type": "g", "layers": L, "width": w};
// throws Error naming --core and the expected form.
nlohmann::json parse_core(const std::string& s);

// The same check as a CLI11 validator, so a bad --core is refused while parsing the options,
// before the output directory exists.
extern const CLI::Validator kCoreSpec;

}  // namespace csympnet::cli
