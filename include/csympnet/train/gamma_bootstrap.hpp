// A bootstrap interval for the identified damping rate γ̂ (docs/identification.md,
// "Uncertainty").
//
// Each replicate resamples the training pairs with replacement (or whole trajectories, when
// `groups` names the trajectory of each pair), starts from the fitted θ̂ and refines on the
// resample with a cheap second stage (LM, a few iterations, keeping the last iterate). The
// interval is the percentile interval of the replicates' γ̂. It measures the sampling variance of γ̂
// given the data; it does not see a bias (e.g. from noise in z0), so its coverage must be checked
// (experiments/coverage.py).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/data/dataset.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "csympnet/train/callbacks.hpp"
#include "csympnet/train/refine.hpp"

namespace csympnet {

// The range of the replicates as the front ends give them: 0 switches the interval off.
inline constexpr OptionRange kBootstrapRange{
    .key = "bootstrap",
    .lo = 10,
    .hi = 1e6,
    .whole = true,
    .zero_means = "off",
    .why = "a percentile interval needs at least 10 replicates"};

struct BootstrapOptions {
  long replicates = 0;         // number of resamples; 0 switches the interval off
  double level = 0.95;         // coverage level of the percentile interval, in (0, 1)
  std::uint64_t seed = 42;     // resampling stream Rng(seed, "bootstrap")
  RefineOptions refine = [] {  // second stage of each replicate (lm, 10 iterations, last)
    RefineOptions r;
    r.method = RefineMethod::kLm;
    r.iterations = 10;
    r.keep_best_validation = false;
    return r;
  }();
  void validate() const;
};
void to_json(nlohmann::json& j, const BootstrapOptions& o);

struct GammaInterval {
  double low = 0.0;   // (1 − level)/2 quantile of the replicates' γ̂
  double high = 0.0;  // (1 + level)/2 quantile
  double std = 0.0;   // standard deviation of the replicates' γ̂
  double level = 0.95;
  long replicates = 0;
  std::string resample;        // "pairs" or "trajectories"
  std::vector<double> gammas;  // every replicate's γ̂, in draw order
  double seconds = 0.0;
  // Ended early because the caller asked: `gammas` holds the replicates finished, and the
  // other fields are unset (an interval from part of the replicates is not the one asked for).
  bool stopped = false;
};
// Every field but the wall time.
void to_json(nlohmann::json& j, const GammaInterval& g);

// `groups`: empty (resample pairs) or one trajectory index per training pair (resample
// trajectories). Requires a map with a damping rate. `callbacks.should_stop`, when given, is
// polled between replicates and inside each replicate's refinement (refine_one_step_map);
// `callbacks.progress` sees each replicate as it ends (stage "bootstrap", epoch = replicates
// done of epochs, gamma_hat = that replicate's γ̂; the losses are NaN) and may stop the
// interval. A stopped bootstrap returns `stopped` and no interval.
GammaInterval gamma_bootstrap(const OneStepMap& map, const Vector& theta, const PairSet& train,
                              const PairSet& val, const BootstrapOptions& options,
                              const std::vector<Index>& groups = {},
                              const IterationCallbacks& callbacks = {});

// The q-quantile (q in [0, 1]) of values, linear interpolation between order statistics
// (NumPy's default "linear" method).
double sample_quantile(std::vector<double> values, double q);

}  // namespace csympnet
