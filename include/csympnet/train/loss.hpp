// The one-step loss of the paper, eq. (one_step_loss):
//   L(θ) = (1/N) Σ_i ‖z1_i − Φ̂_{h_i}(z0_i)‖².
// (The sum runs over the 2d components; the mean over pairs only, as in the paper.)
#pragma once

#include "csympnet/data/dataset.hpp"
#include "csympnet/models/one_step_map.hpp"

namespace csympnet {

// Loss value; when grad is not null it is overwritten with dL/dθ. `cache` may be null or a
// cache reused across calls with the same batch.
double one_step_loss(const OneStepMap& map, ConstParams theta, const PairSet& pairs,
                     Vector* grad = nullptr, ForwardCache* cache = nullptr);

}  // namespace csympnet
