// The one-step loss of the paper, eq. (one_step_loss):
//   L(θ) = (1/N) Σ_i ‖z1_i − Φ̂_{h_i}(z0_i)‖².
// (The sum runs over the 2d components; the mean over pairs only, as in the paper.)
#pragma once

#include <vector>

#include "csympnet/core/thread_team.hpp"
#include "csympnet/data/dataset.hpp"
#include "csympnet/models/column_split.hpp"
#include "csympnet/models/one_step_map.hpp"

namespace csympnet {

// Loss value; when grad is not null it is overwritten with dL/dθ. `cache` may be null or a
// cache reused across calls with the same batch.
double one_step_loss(const OneStepMap& map, ConstParams theta, const PairSet& pairs,
                     Vector* grad = nullptr, ForwardCache* cache = nullptr);

// The part of the loss over n_mean pairs that `pairs` (a chunk of them) contribute:
// Σ_{i in chunk} ‖z1_i − Φ̂(z0_i)‖² / n_mean, and its gradient in grad (overwritten) when not
// null. With n_mean = pairs.size() it is one_step_loss(), operation for operation.
double one_step_loss_part(const OneStepMap& map, ConstParams theta, const PairSet& pairs,
                          Index n_mean, Vector* grad = nullptr, ForwardCache* cache = nullptr);

// How one_step_loss() runs on a team of threads: one column range of the batch per part,
// through the model's column-split passes (column_split.hpp). Planned once per batch size,
// since asking whether a model splits runs a few products.
struct LossSplit {
  ThreadTeam* team = nullptr;
  std::vector<Columns> ranges;  // empty: the serial passes
  bool active() const { return team != nullptr && ranges.size() > 1; }
};

// The split for batches of n columns of `map` on `team`: active only when the team has more
// than one thread, the model has column-split passes and they accept the ranges.
LossSplit plan_loss_split(const OneStepMap& map, Index n, ThreadTeam* team);

// one_step_loss() with `split`: the same value and gradient, to the bit, on split.team when
// split.active() (cache must then not be null and pairs must have the planned size).
double one_step_loss(const OneStepMap& map, ConstParams theta, const PairSet& pairs, Vector* grad,
                     ForwardCache* cache, const LossSplit& split);

}  // namespace csympnet
