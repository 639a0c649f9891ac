// The training objective of a model on its data: the one-step loss for map models, the
// midpoint loss for vector-field models (docs/protocol.md, "Losses and rollout").
#pragma once

#include <functional>
#include <optional>
#include <vector>

#include "csympnet/core/communicator.hpp"
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
  Index train_pairs = 0;  // training pairs (0: not known)
  // The training loss's chunk plan (chunk_tree.hpp): chunks of chunk_pairs pairs.
  Index chunk_pairs = 0;
  Index chunks = 1;
  // When built for mini-batches: the loss (mean over the batch) and its gradient on the
  // training pairs numbered `batch`. Overwrites grad.
  std::function<double(const Vector& theta, Vector& grad, const std::vector<Index>& batch)>
      batch_loss;
  // Bytes this rank sent in the last training loss's all-gather (0 on one process).
  std::function<std::size_t()> bytes_sent;
};

// How an objective's one-step losses run: the same bits for any threads and ranks, and a
// chunk plan of its own (chunk_pairs; 0: plan_chunks' rule, chunk_tree.hpp).
struct LossPlan {
  int threads = 1;                     // this process's threads
  Index chunk_pairs = 0;               // pairs per chunk; 0: one chunk up to 512 pairs, 256 above
  bool batches = false;                // every rank keeps every training pair, for batch_loss
  const Communicator* comm = nullptr;  // the ranks sharing the chunks; null: this process alone
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
Objective make_one_step_objective(const OneStepMap& map, const PairSet& train, const PairSet& val,
                                  const LossPlan& plan);
// The same with chunks, batches and ranks (map models only; a vector-field model takes
// the default plan alone).
Objective make_objective(const Model& model, const PairSet& train, const PairSet& val,
                         const LossPlan& plan);

}  // namespace csympnet
