#include "csympnet/train/gamma_bootstrap.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"

namespace csympnet {

void BootstrapOptions::validate() const {
  kBootstrapRange.check(replicates);
  require(std::isfinite(level) && level > 0.0 && level < 1.0,
          [&] { return "bootstrap.level must be in (0, 1), got " + std::to_string(level); });
  refine.validate();
  require(refine.method != RefineMethod::kNone, "bootstrap.refine.method must be 'lm' or 'lbfgs'");
}

void to_json(nlohmann::json& j, const BootstrapOptions& o) {
  j = {{"replicates", o.replicates}, {"level", o.level}, {"seed", o.seed}, {"refine", o.refine}};
}

void to_json(nlohmann::json& j, const GammaInterval& g) {
  j = {{"low", g.low},
       {"high", g.high},
       {"std", g.std},
       {"level", g.level},
       {"replicates", g.replicates},
       {"resample", g.resample},
       {"gammas", g.gammas}};
}

double sample_quantile(std::vector<double> values, double q) {
  require(!values.empty(), "quantile of an empty set");
  std::sort(values.begin(), values.end());
  const double pos = q * static_cast<double>(values.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, values.size() - 1);
  const double f = pos - static_cast<double>(lo);
  return values[lo] + f * (values[hi] - values[lo]);
}

GammaInterval gamma_bootstrap(const OneStepMap& map, const Vector& theta, const PairSet& train,
                              const PairSet& val, const BootstrapOptions& options,
                              const std::vector<Index>& groups,
                              const IterationCallbacks& callbacks) {
  const std::function<bool()>& should_stop = callbacks.should_stop;
  options.validate();
  require(map.damping_rate(theta).has_value(), [&] {
    return "bootstrap interval for gamma_hat: the model '" + map.type() +
           "' has no damping rate (use --model csympnet)";
  });
  require(groups.empty() || static_cast<Index>(groups.size()) == train.size(),
          "bootstrap: need one trajectory index per training pair");
  const auto start = std::chrono::steady_clock::now();

  // Units to resample: single pairs, or the pairs of each trajectory.
  std::vector<std::vector<Index>> units;
  if (groups.empty()) {
    for (Index i = 0; i < train.size(); ++i) units.push_back({i});
  } else {
    std::map<Index, std::size_t> slot;
    for (Index i = 0; i < train.size(); ++i) {
      const auto [it, inserted] = slot.emplace(groups[static_cast<std::size_t>(i)], units.size());
      if (inserted) units.emplace_back();
      units[it->second].push_back(i);
    }
  }
  GammaInterval g;
  g.level = options.level;
  g.replicates = options.replicates;
  g.resample = groups.empty() ? "pairs" : "trajectories";
  Rng rng(options.seed, "bootstrap");
  const auto n_units = static_cast<double>(units.size());
  for (long b = 0; b < options.replicates; ++b) {
    if (should_stop && should_stop()) {
      g.stopped = true;
      break;
    }
    std::vector<Index> idx;
    for (std::size_t u = 0; u < units.size(); ++u) {
      const auto pick = static_cast<std::size_t>(std::floor(rng.uniform() * n_units));
      idx.insert(idx.end(), units[pick].begin(), units[pick].end());
    }
    const PairSet resample = select_pairs(train, idx);
    Vector th = theta;
    if (refine_one_step_map(map, th, resample, val, options.refine, {{}, should_stop}).stopped) {
      g.stopped = true;
      break;
    }
    g.gammas.push_back(*map.damping_rate(th));
    if (callbacks.progress) {
      TrainProgress p;
      p.stage = "bootstrap";
      p.epoch = b + 1;
      p.epochs = options.replicates;
      p.train_loss = p.val_loss = p.best_val_loss = std::numeric_limits<double>::quiet_NaN();
      p.gamma_hat = g.gammas.back();
      p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (!callbacks.progress(p)) {
        g.stopped = true;
        break;
      }
    }
  }
  if (g.stopped) {
    g.replicates = static_cast<long>(g.gammas.size());
    g.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return g;
  }
  const double alpha = 1.0 - options.level;
  g.low = sample_quantile(g.gammas, alpha / 2);
  g.high = sample_quantile(g.gammas, 1.0 - alpha / 2);
  double mean = 0.0;
  for (double x : g.gammas) mean += x;
  mean /= static_cast<double>(g.gammas.size());
  double var = 0.0;
  for (double x : g.gammas) var += (x - mean) * (x - mean);
  g.std = std::sqrt(var / static_cast<double>(g.gammas.size() - 1));
  g.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return g;
}

}  // namespace csympnet
