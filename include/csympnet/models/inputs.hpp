// Known inputs u(t) of a driven (forced) map (docs/derivations.md, "Known inputs"): m channels,
// sampled at the data's times, entering the Hamiltonian as H(q, p, t) = H₀(q, p) − qᵀB u(t).
//
// A map with inputs reads, per step (per column of Z), the input at the step's start and at its
// end: a 2m-row column, rows 0 … m−1 u(t₀), rows m … 2m−1 u(t₀ + h). Between the two the input is
//
//   held (zero-order hold, "zoh"):           u(t₀ + σh) = u(t₀)
//   interpolated (first-order hold, "foh"):  u(t₀ + σh) = u(t₀) + σ (u(t₀ + h) − u(t₀))
//
// for every σ, also outside [0, 1] (a composition's stages with negative weights reach there;
// the first-order hold then extrapolates the line, the zero-order hold keeps its value).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "csympnet/core/types.hpp"

namespace csympnet {

enum class InputHold { kZero, kFirst };

// "zoh" or "foh".
std::string hold_name(InputHold hold);
// Refuses any other text with an Error naming `where` and the two spellings.
InputHold parse_hold(const std::string& text, const std::string& where);

// The inputs of a map: m channels (0: a free map) and how they are held between samples.
struct InputSpec {
  Index m = 0;
  InputHold hold = InputHold::kFirst;
  bool operator==(const InputSpec&) const = default;
};

// A spec's "inputs": {"m": m, "hold": "foh"|"zoh", "B": "row-major"} (absent: no inputs).
// Throws Error naming `where`, the key and what was expected.
InputSpec read_input_spec(const nlohmann::json& v, const std::string& where);
nlohmann::json input_spec_json(const InputSpec& spec);

// u(t₀ + σh) of one step's column `u` (2m values: start, then end) into out (m values).
inline void input_at(InputHold hold, Index m, const double* u, double sigma, double* out) {
  for (Index j = 0; j < m; ++j)
    out[j] = hold == InputHold::kZero ? u[j] : u[j] + sigma * (u[m + j] - u[j]);
}

}  // namespace csympnet
