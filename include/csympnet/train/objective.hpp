// The training objective of a model on its data: the one-step loss for map models, the
// midpoint loss for vector-field models (docs/protocol.md, "Losses and rollout").
#pragma once

#include <functional>
#include <optional>

#include "csympnet/data/dataset.hpp"
#include "csympnet/models/model.hpp"
#include "csympnet/models/one_step_map.hpp"

namespace csympnet {

// What the training loop needs of a model and its data: a training loss with gradient, a
// validation loss, and optionally the damping rate for progress reports.
struct Objective {
  Index n_params = 0;
  std::optional<Index> damping_index;  // excluded from weight decay when asked
  std::function<double(const Vector& theta, Vector& grad)> train_loss;  // overwrites grad
  std::function<double(const Vector& theta)> val_loss;
  std::function<std::optional<double>(const Vector& theta)> damping_rate;
};

// The one-step loss of a map on (train, val): what make_objective builds for a map model.
// The objective refers to `map`, which must outlive it, and keeps copies of the data.
Objective make_one_step_objective(const OneStepMap& map, const PairSet& train, const PairSet& val,
                                  int threads = 1);

// The returned objective refers to `model` and keeps its own copies of what it needs of the
// data; `model` must outlive it. With threads > 1 its training loss runs on a team of that
// many threads when the model splits its batch (LossSplit, loss.hpp); the results are the same.
Objective make_objective(const Model& model, const PairSet& train, const PairSet& val,
                         int threads = 1);

}  // namespace csympnet
