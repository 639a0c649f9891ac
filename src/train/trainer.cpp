#include "csympnet/train/trainer.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/core/thread_team.hpp"
#include "csympnet/train/loss.hpp"

namespace csympnet {

void TrainOptions::validate() const {
  kEpochsRange.check(epochs);
  kValEveryRange.check(val_every);
  adamw.validate();
  kLrFinalFractionRange.check(lr_final_fraction);
  kThreadsRange.check(static_cast<long>(threads));
  kChunkPairsRange.check(chunk_pairs);
  kBatchSizeRange.check(batch_size);
}

double TrainOptions::lr_at(long epoch) const {
  if (lr_schedule == LrSchedule::kConstant || epochs <= 1) return adamw.lr;
  // Cosine from lr (epoch 1) to lr·f (last epoch).
  const double x = static_cast<double>(epoch - 1) / static_cast<double>(epochs - 1);
  const double f = lr_final_fraction;
  return adamw.lr * (f + (1.0 - f) * 0.5 * (1.0 + std::cos(3.14159265358979323846 * x)));
}

void to_json(nlohmann::json& j, const TrainOptions& o) {
  j = {{"optimizer", "adamw"},
       {"epochs", o.epochs},
       {"val_every", o.val_every},
       {"adamw", o.adamw},
       {"lr_schedule", to_string(o.lr_schedule)},
       {"lr_final_fraction", o.lr_final_fraction},
       {"batch", o.batch_size > 0 ? nlohmann::json(o.batch_size) : nlohmann::json("full")},
       {"checkpoint", "best-validation"}};
  if (o.batch_size > 0) j["shuffle_seed"] = o.shuffle_seed;
  if (o.chunk_pairs > 0) j["chunk_pairs"] = o.chunk_pairs;
}

void from_json(const nlohmann::json& j, TrainOptions& o) {
  o.epochs = j.value("epochs", o.epochs);
  o.val_every = j.value("val_every", o.val_every);
  if (j.contains("adamw")) o.adamw = j.at("adamw").get<AdamWOptions>();
  if (j.contains("lr_schedule"))
    o.lr_schedule = parse_lr_schedule(j.at("lr_schedule").get<std::string>());
  o.lr_final_fraction = j.value("lr_final_fraction", o.lr_final_fraction);
  if (j.contains("batch") && j.at("batch").is_number_integer())
    o.batch_size = j.at("batch").get<long>();
  o.shuffle_seed = j.value("shuffle_seed", o.shuffle_seed);
  o.chunk_pairs = j.value("chunk_pairs", o.chunk_pairs);
}

const std::vector<std::string>& lr_schedule_names() {
  static const std::vector<std::string> names = {"constant", "cosine"};
  return names;
}

std::string to_string(LrSchedule s) {
  return lr_schedule_names().at(static_cast<std::size_t>(s));
}

LrSchedule parse_lr_schedule(const std::string& text, const std::string& option) {
  const auto& names = lr_schedule_names();
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == text) return static_cast<LrSchedule>(i);
  throw Error(option + " must be 'constant' or 'cosine', got '" + text + "'");
}

const std::vector<std::string>& stop_reason_names() {
  static const std::vector<std::string> names = {"budget", "callback", "diverged"};
  return names;
}

std::string to_string(StopReason r) {
  return stop_reason_names().at(static_cast<std::size_t>(r));
}

StopReason parse_stop_reason(const std::string& text, const std::string& option) {
  const auto& names = stop_reason_names();
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == text) return static_cast<StopReason>(i);
  throw Error(option + " must be 'budget', 'callback' or 'diverged', got '" + text + "'");
}

std::string TrainSummary::brief_report() const {
  std::ostringstream s;
  s << "trained " << epochs_run << " epochs in " << seconds << " s; best validation loss "
    << best_val_loss << " at epoch " << best_epoch << " (" << to_string(stop_reason) << ")";
  return s.str();
}

void to_json(nlohmann::json& j, const TrainSummary& s) {
  j = {{"epochs_run", s.epochs_run},
       {"best_epoch", s.best_epoch},
       {"best_val_loss", s.best_val_loss},
       {"final_train_loss", s.final_train_loss},
       {"seconds", s.seconds},
       {"stop_reason", to_string(s.stop_reason)}};
  if (s.chunks > 1) {
    j["chunk_pairs"] = s.chunk_pairs;
    j["chunks"] = s.chunks;
  }
  if (s.steps != s.epochs_run) j["steps"] = s.steps;
  if (s.bytes_sent_per_step > 0) j["bytes_sent_per_step"] = s.bytes_sent_per_step;
}

TrainSummary train_parameters(const Objective& objective, Vector& theta,
                              const TrainOptions& options, const ProgressCallback& progress) {
  options.validate();
  require(objective.train_loss && objective.val_loss, "train: objective needs both losses");
  require(theta.size() == objective.n_params, "train: parameter vector has the wrong size");

  const auto start = std::chrono::steady_clock::now();
  AdamW opt(objective.n_params, options.adamw, objective.damping_index);
  Vector grad(objective.n_params);

  const IterationCallbacks callbacks{progress, {}, 0};
  // By reference: the objective's functions may hold copies of the data.
  IterationMonitor::DampingRate rate;
  if (objective.damping_rate)
    rate = [&objective](const Vector& t) { return objective.damping_rate(t); };
  IterationMonitor monitor(
      "adamw", options.epochs, [&objective](const Vector& t) { return objective.val_loss(t); },
      theta, callbacks, rate);
  TrainSummary summary;
  summary.stop_reason = StopReason::kBudget;
  summary.chunk_pairs = objective.chunk_pairs;
  summary.chunks = objective.chunks;
  const bool batches = options.batch_size > 0;
  require(!batches || objective.batch_loss,
          "train: mini-batches (batch_size > 0) need an objective built for them");
  // The mini-batch order: a permutation of the pairs, shuffled again every epoch.
  Rng shuffle(options.shuffle_seed, "minibatch");
  std::vector<Index> order(static_cast<std::size_t>(batches ? objective.train_pairs : 0));
  std::iota(order.begin(), order.end(), Index{0});
  const Index batch = batches ? std::min<Index>(options.batch_size, objective.train_pairs) : 0;
  double train_loss = std::numeric_limits<double>::quiet_NaN();
  // A stop request seen inside a loss (a vector-field model's integrator on a stiff field)
  // ends the training like one seen at a validation: the best checkpoint so far is kept.
  try {
    for (long epoch = 1; epoch <= options.epochs; ++epoch) {
      if (options.lr_schedule != LrSchedule::kConstant) opt.set_lr(options.lr_at(epoch));
      bool finite = true;
      if (!batches) {
        train_loss = objective.train_loss(theta, grad);
        finite = std::isfinite(train_loss) && grad.allFinite();
        if (finite) opt.step(theta, grad);
        summary.steps += finite ? 1 : 0;
      } else {
        // Fisher–Yates with our own RNG: the same order on every platform and every rank.
        for (Index i = static_cast<Index>(order.size()) - 1; i > 0; --i) {
          const auto j = static_cast<Index>(shuffle.next_u64() % static_cast<std::uint64_t>(i + 1));
          std::swap(order[static_cast<std::size_t>(i)], order[static_cast<std::size_t>(j)]);
        }
        // The epoch's training loss: the batches' losses weighted by their sizes, before each
        // one's step.
        train_loss = 0.0;
        for (Index b = 0; b < static_cast<Index>(order.size()) && finite; b += batch) {
          const Index e = std::min<Index>(b + batch, static_cast<Index>(order.size()));
          const std::vector<Index> ids(order.begin() + b, order.begin() + e);
          const double l = objective.batch_loss(theta, grad, ids);
          finite = std::isfinite(l) && grad.allFinite();
          if (!finite) break;
          train_loss += l * static_cast<double>(e - b) / static_cast<double>(order.size());
          opt.step(theta, grad);
          ++summary.steps;
        }
      }
      if (!finite) {
        // Keep the best checkpoint; the caller decides how loudly to report it.
        summary.stop_reason = StopReason::kDiverged;
        break;
      }
      summary.epochs_run = epoch;
      if (epoch % options.val_every != 0 && epoch != options.epochs) continue;
      if (!monitor.accept(epoch, theta, train_loss)) {
        summary.stop_reason = StopReason::kCallback;
        break;
      }
    }
  } catch (const StopRequested&) {
    summary.stop_reason = StopReason::kCallback;
  }
  if (objective.bytes_sent) summary.bytes_sent_per_step = static_cast<long>(objective.bytes_sent());
  summary.best_val_loss = monitor.best_loss();
  summary.best_epoch = monitor.best_iteration();
  summary.final_train_loss = train_loss;
  theta = monitor.best();
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

TrainSummary train_model(const Model& model, Vector& theta, const PairSet& train,
                         const PairSet& val, const TrainOptions& options,
                         const ProgressCallback& progress) {
  options.validate();
  LossPlan plan;
  plan.threads = options.threads;
  plan.chunk_pairs = options.chunk_pairs;
  plan.batches = options.batch_size > 0;
  plan.comm = options.communicator;
  return train_parameters(make_objective(model, train, val, plan), theta, options, progress);
}

}  // namespace csympnet
