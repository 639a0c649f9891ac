// Fitting a one-step map to a user's own snapshot pairs (any d, any steps).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "csympnet/data/dataset.hpp"
#include "csympnet/models/model.hpp"
#include "csympnet/train/trainer.hpp"

namespace csympnet {

struct FitConfig {
  std::string model = "csympnet";  // "csympnet" or "sympnet"
  nlohmann::json core;             // symplectic core; null → default_core_for(d)
  std::uint64_t seed = 42;         // validation split and initialisation
  double val_fraction = 0.2;       // share of pairs held out when no validation set is given
  TrainOptions train;              // epochs <= 0 → default_epochs_for(d)
  double beta_init = 0.1;          // CSympNet-ID: initial β, nonzero
  void validate() const;
};
void to_json(nlohmann::json& j, const FitConfig& c);

// The presets' cores, chosen by dimension: LA(5,20) for d = 1, LA(4,10) up to d = 20,
// LA(4,4) beyond.
nlohmann::json default_core_for(Index d);
// 50,000 epochs up to d = 20 (the s1/s2 budget, docs/training.md), 3,000 beyond.
long default_epochs_for(Index d);

// Deterministic split of `all` into (train, val) with round(val_fraction·N) ≥ 1 validation
// pairs (N ≥ 2 required).
std::pair<PairSet, PairSet> split_pairs(const PairSet& all, double val_fraction, Rng& rng);

struct FitResult {
  Model model;  // a map model (csympnet or sympnet)
  Vector theta;
  TrainSummary training;
  PairSet train;
  PairSet val;
  FitConfig config;  // with the defaults filled in
};

// Trains on `train`; validates on `val` if given, else on a split of `train`.
FitResult fit_pairs(const PairSet& train, const std::optional<PairSet>& val,
                    const FitConfig& config, const ProgressCallback& progress = {});

}  // namespace csympnet
