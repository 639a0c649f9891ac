// What the Hamiltonian library map's two files (hamiltonian_library.cpp, its steps and
// gradients; hamiltonian_library_tangents.cpp, its tangents) share with each other and with
// the maps that take a damping parameter as |θ| (csympnet_id.cpp, hamiltonian_fields.cpp).
#pragma once

#include "csympnet/core/types.hpp"

namespace csympnet::library_detail {

// A step of many substeps (4,000,000 of them take seconds) polls the process-wide stop request
// every this many stages, so Ctrl-C ends it (rollout, evaluate, Python). A map of the
// identification's sizes (at most 256 substeps of 9 stages) never reaches it, so its training
// keeps stopping at its own checkpoints.
inline constexpr Index kStagesPerPoll = 4096;

// d|θ|/dθ, with the subgradient 0 at θ = 0 (rates and damping parameters enter as |θ|).
inline double abs_derivative(double theta) {
  if (theta > 0.0) return 1.0;
  if (theta < 0.0) return -1.0;
  return 0.0;
}

}  // namespace csympnet::library_detail
