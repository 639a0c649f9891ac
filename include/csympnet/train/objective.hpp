// The training objective of a model on its data: the one-step loss for map models, the
// midpoint loss for vector-field models (docs/protocol.md, "Losses and rollout").
#pragma once

#include <memory>

#include "csympnet/data/dataset.hpp"
#include "csympnet/models/model.hpp"
#include "csympnet/train/trainer.hpp"

namespace csympnet {

// The returned objective refers to `model` and keeps its own copies of what it needs of the
// data; `model` must outlive it. With threads > 1 its training loss runs on a team of that
// many threads when the model splits its batch (LossSplit, loss.hpp); the results are the same.
Objective make_objective(const Model& model, const PairSet& train, const PairSet& val,
                         int threads = 1);

// Trains theta in place with the model's own loss.
TrainSummary train_model(const Model& model, Vector& theta, const PairSet& train,
                         const PairSet& val, const TrainOptions& options,
                         const ProgressCallback& progress = {});

}  // namespace csympnet
