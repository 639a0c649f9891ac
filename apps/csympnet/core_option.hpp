// The --core option of `train`, `fit` and `run`: a symplectic core as "la:L:m" or "g:L:w".
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace csympnet::cli {

// {"type": "la", "layers": L, "sublayers": m} or {"type": "g", "layers": L, "width": w};
// throws Error naming --core and the expected form.
nlohmann::json parse_core(const std::string& s);

}  // namespace csympnet::cli
