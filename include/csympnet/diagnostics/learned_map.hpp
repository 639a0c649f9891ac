// The diagnostics' view of a trained model: its one-step map and that map's Jacobian. For
// vector-field models both come from adaptive dopri5 (the flow, and the variational
// equation integrated with the same controller).
#pragma once

#include "csympnet/diagnostics/diagnostics.hpp"
#include "csympnet/integrators/dopri5.hpp"
#include "csympnet/models/model.hpp"

namespace csympnet {

// `model` and `theta` are referenced, not copied: they must outlive the returned map.
LearnedMap learned_map(const Model& model, const Vector& theta, const OdeOptions& ode = {});

}  // namespace csympnet
