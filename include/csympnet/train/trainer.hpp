// Full-batch training of a one-step map on the one-step loss, keeping the parameters with
// the lowest validation loss (the paper's checkpoint rule).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/core/options.hpp"
#include "csympnet/core/thread_team.hpp"
#include "csympnet/data/dataset.hpp"
#include "csympnet/models/model.hpp"
#include "csympnet/train/adamw.hpp"
#include "csympnet/train/callbacks.hpp"
#include "csympnet/train/objective.hpp"

namespace csympnet {

// The share of the data held out for validation, in every recipe (paper/fit.hpp's classic fit,
// identify/identify.hpp's blocks): below 1% or above 99% leaves one side nearly empty on the
// data sizes they are for.
inline constexpr OptionRange kValFractionRange{.key = "val_fraction", .lo = 0.01, .hi = 0.99};

// The learning rate over the budget: constant (the paper's recipe) or cosine, which anneals
// it from adamw.lr to lr_final_fraction·adamw.lr (a switchable improvement: it removes the
// late oscillation of a constant rate; docs/training.md). Spelt "constant", "cosine".
enum class LrSchedule { kConstant, kCosine };
std::string to_string(LrSchedule s);
const std::vector<std::string>& lr_schedule_names();  // in enum order
// Refuses any other text with an Error naming `option` and the accepted spellings.
LrSchedule parse_lr_schedule(const std::string& text,
                             const std::string& option = "train.lr_schedule");

// The ranges of TrainOptions' options as the front ends give them (core/options.hpp). An
// epoch budget of 0 trains nothing (`run --epochs 0` evaluates the initial parameters).
inline constexpr OptionRange kEpochsRange{.key = "epochs", .lo = 0, .hi = 1e8, .whole = true};
inline constexpr OptionRange kValEveryRange{.key = "val_every", .lo = 1, .hi = 1e8, .whole = true};
inline constexpr OptionRange kThreadsRange{
    .key = "threads", .lo = 1, .hi = ThreadTeam::kMaxThreads, .whole = true};
inline constexpr OptionRange kChunkPairsRange{
    .key = "chunk_pairs", .lo = 0, .hi = 1e9, .whole = true};
inline constexpr OptionRange kBatchSizeRange{
    .key = "batch_size", .lo = 0, .hi = 1e12, .whole = true};
inline constexpr OptionRange kLrFinalFractionRange{
    .key = "lr_final_fraction", .lo = 0.0, .hi = 1.0, .lo_open = true};

struct TrainOptions {
  long epochs = 20000;  // epoch budget (one full-batch AdamW step per epoch)
  long val_every = 10;  // evaluate the validation loss every this many epochs (and at the end)
  AdamWOptions adamw;   // optimiser settings (defaults: docs/protocol.md, "Training")
  LrSchedule lr_schedule = LrSchedule::kConstant;
  double lr_final_fraction = 1e-3;
  // Threads for the training loss of models with column-split passes (CSympNet-ID with a core
  // of d > 1: column_split.hpp); other models train on one. Results are the same to the bit
  // for any value, so it is not part of the configuration's JSON.
  int threads = 1;
  // Pairs per chunk of the training and validation losses (chunk_tree.hpp); 0 (default): one
  // chunk up to 512 pairs (today's single pass), 256 above. The chunks fix the order of the
  // sums, so a value other than 0 is part of the configuration (and its JSON).
  long chunk_pairs = 0;
  // Mini-batches: 0 (default) takes one full-batch step per epoch; B > 0 shuffles the training
  // pairs each epoch (the stream Rng(shuffle_seed, "minibatch")) and takes one step per batch
  // of B of them in that order (⌈N/B⌉ steps; the last batch holds the rest).
  long batch_size = 0;
  std::uint64_t shuffle_seed = 0;
  // The ranks one training runs on (each its share of the chunks, the same steps on all);
  // null: this process alone. Like threads, not part of the configuration.
  const Communicator* communicator = nullptr;
  void validate() const;
  // adamw.lr scaled by the schedule at epoch (1-based) of the budget.
  double lr_at(long epoch) const;
};
void to_json(nlohmann::json& j, const TrainOptions& o);
void from_json(const nlohmann::json& j, TrainOptions& o);

// Why training ended: its epoch budget ran out, the progress callback asked to stop, or the
// loss or gradient became non-finite. Spelt "budget", "callback", "diverged" in reports.
enum class StopReason { kBudget, kCallback, kDiverged };
std::string to_string(StopReason r);
const std::vector<std::string>& stop_reason_names();  // in enum order
// Refuses any other text with an Error naming `option` and the accepted spellings.
StopReason parse_stop_reason(const std::string& text, const std::string& option = "stop_reason");

struct TrainSummary {
  long epochs_run = 0;
  long best_epoch = 0;  // epoch whose parameters were kept (0 = initial parameters)
  double best_val_loss = 0.0;
  double final_train_loss = 0.0;
  double seconds = 0.0;
  StopReason stop_reason = StopReason::kBudget;
  // The training loss's chunk plan (reported when it has more than one chunk) and the AdamW
  // steps taken (more than epochs_run with mini-batches).
  long chunk_pairs = 0;
  long chunks = 1;
  long steps = 0;
  // Bytes this rank sent in the all-gather of the last training step (0 in one process).
  long bytes_sent_per_step = 0;
  std::string brief_report() const;
};
void to_json(nlohmann::json& j, const TrainSummary& s);

// AdamW on `objective` (full batch, or mini-batches when options.batch_size > 0 and the
// objective has a batch loss), keeping the best-validation parameters (IterationMonitor,
// callbacks.hpp): on return theta holds them. `progress` sees every validation; returning
// false ends the run (stop reason "callback").
TrainSummary train_parameters(const Objective& objective, Vector& theta,
                              const TrainOptions& options, const ProgressCallback& progress = {});

// Trains theta in place with the model's own loss (make_objective).
TrainSummary train_model(const Model& model, Vector& theta, const PairSet& train,
                         const PairSet& val, const TrainOptions& options,
                         const ProgressCallback& progress = {});

}  // namespace csympnet
