#include "csympnet/experiments/fit.hpp"

#include <cmath>
#include <numeric>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/train/objective.hpp"

namespace csympnet {

void FitConfig::validate() const {
  require(model == "csympnet" || model == "sympnet",
          "--model must be 'csympnet' or 'sympnet', got '" + model + "'");
  require(std::isfinite(val_fraction) && val_fraction > 0.0 && val_fraction < 1.0,
          "--val-fraction must be in (0, 1), got " + std::to_string(val_fraction));
  require(std::isfinite(beta_init) && beta_init != 0.0, "--beta-init must be finite and nonzero");
  TrainOptions t = train;
  if (t.epochs <= 0) t.epochs = 0;
  t.validate();
}

void to_json(nlohmann::json& j, const FitConfig& c) {
  j = {{"model", c.model}, {"core", c.core},
       {"seed", c.seed},   {"val_fraction", c.val_fraction},
       {"train", c.train}, {"beta_init", c.beta_init}};
}

nlohmann::json default_core_for(Index d) {
  if (d == 1) return {{"type", "la"}, {"layers", 5}, {"sublayers", 20}};
  if (d <= 20) return {{"type", "la"}, {"layers", 4}, {"sublayers", 10}};
  return {{"type", "la"}, {"layers", 4}, {"sublayers", 4}};
}

long default_epochs_for(Index d) {
  return d <= 20 ? 50000 : 3000;
}

std::pair<PairSet, PairSet> split_pairs(const PairSet& all, double val_fraction, Rng& rng) {
  const Index n = all.size();
  require(n >= 2, "need at least 2 pairs to hold out a validation set, got " + std::to_string(n));
  std::vector<Index> idx(static_cast<std::size_t>(n));
  std::iota(idx.begin(), idx.end(), Index{0});
  // Fisher–Yates with our own RNG, so the split is the same on every platform.
  for (Index i = n - 1; i > 0; --i) {
    const auto j = static_cast<Index>(rng.next_u64() % static_cast<std::uint64_t>(i + 1));
    std::swap(idx[static_cast<std::size_t>(i)], idx[static_cast<std::size_t>(j)]);
  }
  Index n_val = static_cast<Index>(std::llround(val_fraction * static_cast<double>(n)));
  n_val = std::clamp<Index>(n_val, 1, n - 1);
  const std::vector<Index> val_idx(idx.begin(), idx.begin() + n_val);
  const std::vector<Index> train_idx(idx.begin() + n_val, idx.end());
  return {select_pairs(all, train_idx), select_pairs(all, val_idx)};
}

FitResult fit_pairs(const PairSet& train, const std::optional<PairSet>& val,
                    const FitConfig& config, const ProgressCallback& progress) {
  config.validate();
  train.validate("training pairs");
  FitResult r;
  r.config = config;
  if (r.config.core.is_null()) r.config.core = default_core_for(train.d());
  if (r.config.train.epochs <= 0) r.config.train.epochs = default_epochs_for(train.d());

  if (val) {
    r.train = train;
    r.val = *val;
  } else {
    Rng split_rng(config.seed, "validation-split");
    std::tie(r.train, r.val) = split_pairs(train, config.val_fraction, split_rng);
  }
  nlohmann::json spec = {{"type", config.model}, {"d", train.d()}, {"core", r.config.core}};
  if (config.model == "csympnet") spec["beta_init"] = config.beta_init;
  r.model = make_model(spec);
  r.theta.resize(r.model.n_params());
  Rng init_rng(config.seed, "init");
  r.model.init_params(init_rng, r.theta);
  r.training = train_model(r.model, r.theta, r.train, r.val, r.config.train, progress);
  return r;
}

}  // namespace csympnet
