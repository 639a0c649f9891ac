#include "csympnet/experiments/fit.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/diagnostics/diagnostics.hpp"
#include "csympnet/train/loss.hpp"
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
  RefineOptions r = refine;
  if (r.method == "auto") r.method = "lm";
  r.validate();
  BootstrapOptions b = bootstrap;
  if (b.replicates < 0) b.replicates = 0;
  if (b.refine.method == "auto") b.refine.method = "lm";
  b.validate();
  require(b.replicates == 0 || model == "csympnet",
          "--bootstrap needs --model csympnet (the only model here with a damping rate)");
}

void to_json(nlohmann::json& j, const FitConfig& c) {
  j = {{"model", c.model},
       {"core", c.core},
       {"seed", c.seed},
       {"val_fraction", c.val_fraction},
       {"train", c.train},
       {"beta_init", c.beta_init},
       {"warm_start", c.warm_start},
       {"refine", c.refine},
       {"bootstrap", c.bootstrap}};
}

void resolve_auto_refine(RefineOptions& refine, Index n_pairs, Index dim, Index n_params) {
  const double entries =
      static_cast<double>(n_pairs) * static_cast<double>(dim) * static_cast<double>(n_params);
  const Index residuals = n_pairs * dim;
  if (entries <= kMaxJacobianEntries && n_params <= kMaxLmParams &&
      ceres_iteration_flops("dense_qr", residuals, n_params) <= kMaxCeresIterationFlops) {
    refine.method = "lm";
  } else if (entries <= kMaxNormalLmJacobianEntries && n_params <= kMaxNormalLmParams) {
    refine.method = "lm";
    refine.linear_solver = "blas_normal_cholesky";
  } else {
    refine.method = "lbfgs";
  }
}

RefineOptions default_replicate_refine_for(const RefineOptions& refine) {
  RefineOptions r;
  // Replicates start at θ̂ and keep their last iterate: with the best-validation rule they
  // would mostly keep θ̂ itself, and the interval would collapse to a point (measured).
  r.keep_best_validation = false;
  if (refine.method == "lm") {
    r.method = "lm";
    r.linear_solver = refine.linear_solver;
    r.iterations = 10;
  } else {
    r.method = "lbfgs";
    r.iterations = 100;
  }
  return r;
}

void to_json(nlohmann::json& j, const FitQuality& q) {
  j = {{"train_loss", q.train_loss},
       {"val_loss", q.val_loss},
       {"val_relative_residual", q.val_relative_residual},
       {"structure_residual_mean", q.structure_residual_mean},
       {"structure_residual_max", q.structure_residual_max}};
}

FitQuality fit_quality(const Model& model, const Vector& theta, const PairSet& train,
                       const PairSet& val) {
  require(model.is_map(), "fit quality: needs a map model");
  const OneStepMap& map = *model.map;
  FitQuality q;
  q.train_loss = one_step_loss(map, theta, train);
  q.val_loss = one_step_loss(map, theta, val);
  const Matrix r = map.apply(theta, val.z0, val.h) - val.z1;
  q.val_relative_residual = r.norm() / (val.z1 - val.z0).norm();
  const auto gamma = map.damping_rate(theta);
  for (Index j = 0; j < val.size(); ++j) {
    const Matrix jac = map.jacobian(theta, val.z0.col(j), val.h(j));
    std::optional<double> own;
    if (gamma) own = std::exp(-*gamma * val.h(j));
    const double s = structure_at(jac, own.value_or(1.0), own).self_residual;
    q.structure_residual_mean += s / static_cast<double>(val.size());
    q.structure_residual_max = std::max(q.structure_residual_max, s);
  }
  return q;
}

nlohmann::json default_core_for(Index d) {
  if (d == 1) return {{"type", "la"}, {"layers", 5}, {"sublayers", 20}};
  if (d <= 20) return {{"type", "la"}, {"layers", 4}, {"sublayers", 10}};
  return {{"type", "la"}, {"layers", 4}, {"sublayers", 4}};
}

long default_epochs_for(Index d) {
  return d <= 20 ? 50000 : 3000;
}

namespace {
// (training indices, validation indices) of a deterministic split.
std::pair<std::vector<Index>, std::vector<Index>> split_indices(Index n, double val_fraction,
                                                                Rng& rng) {
  require(n >= 2, "need at least 2 pairs to hold out a validation set, got " + std::to_string(n) +
                      "; expected more pairs, or a separate validation file (--val FILE)");
  std::vector<Index> idx(static_cast<std::size_t>(n));
  std::iota(idx.begin(), idx.end(), Index{0});
  // Fisher–Yates with our own RNG, so the split is the same on every platform.
  for (Index i = n - 1; i > 0; --i) {
    const auto j = static_cast<Index>(rng.next_u64() % static_cast<std::uint64_t>(i + 1));
    std::swap(idx[static_cast<std::size_t>(i)], idx[static_cast<std::size_t>(j)]);
  }
  Index n_val = static_cast<Index>(std::llround(val_fraction * static_cast<double>(n)));
  n_val = std::clamp<Index>(n_val, 1, n - 1);
  return {std::vector<Index>(idx.begin() + n_val, idx.end()),
          std::vector<Index>(idx.begin(), idx.begin() + n_val)};
}
}  // namespace

std::pair<PairSet, PairSet> split_pairs(const PairSet& all, double val_fraction, Rng& rng) {
  const auto [train_idx, val_idx] = split_indices(all.size(), val_fraction, rng);
  return {select_pairs(all, train_idx), select_pairs(all, val_idx)};
}

void check_beta_start(double beta, double h_max, bool from_warm_start) {
  require(
      std::abs(beta) * h_max <= kMaxBetaInitTimesStep,
      std::string(from_warm_start ? "the warm start's gamma " : "--beta-init ") +
          number_text(beta) + " with the data's largest step h = " + number_text(h_max) +
          " shrinks every state by exp(-|beta| h) = " +
          number_text(std::exp(-std::abs(beta) * h_max)) +
          " per step, so training could not move it; expected |beta_init| * h <= " +
          number_text(kMaxBetaInitTimesStep) +
          " (|beta_init| <= " + number_text(kMaxBetaInitTimesStep / h_max) + " here)" +
          (from_warm_start ? "; the data decay too fast for their steps to identify gamma" : ""));
}

FitResult fit_pairs(const PairSet& train, const std::optional<PairSet>& val,
                    const FitConfig& config, const ProgressCallback& progress,
                    const std::vector<Index>& groups, const std::function<bool()>& should_stop) {
  config.validate();
  train.validate("training pairs");
  require(groups.empty() || static_cast<Index>(groups.size()) == train.size(),
          "fit: need one trajectory index per pair");
  FitResult r;
  r.config = config;
  if (r.config.core.is_null()) r.config.core = default_core_for(train.d());
  if (r.config.train.epochs <= 0) r.config.train.epochs = default_epochs_for(train.d());

  if (val) {
    r.train = train;
    r.val = *val;
    r.train_groups = groups;
  } else {
    Rng split_rng(config.seed, "validation-split");
    const auto [train_idx, val_idx] = split_indices(train.size(), config.val_fraction, split_rng);
    r.train = select_pairs(train, train_idx);
    r.val = select_pairs(train, val_idx);
    if (!groups.empty())
      for (Index i : train_idx) r.train_groups.push_back(groups[static_cast<std::size_t>(i)]);
  }
  nlohmann::json spec = {{"type", config.model}, {"d", train.d()}, {"core", r.config.core}};
  if (config.model == "csympnet") {
    spec["beta_init"] = config.beta_init;
    if (config.warm_start) {
      // A convenience, not a requirement: on data it cannot use (too few pairs, states that
      // do not span phase space) the fit starts from beta_init instead and says why.
      try {
        r.warm_start = gamma_warm_start(r.train);
        // γ̂ = |β|; β must not be 0, where its gradient vanishes.
        spec["beta_init"] = std::max(std::abs(r.warm_start->gamma), 1e-8);
      } catch (const Error& e) {
        r.warm_start_note = e.what();
      }
    }
    check_beta_start(spec["beta_init"].get<double>(), r.train.h.maxCoeff(),
                     r.warm_start.has_value());
  }
  r.model = make_model(spec);
  r.theta.resize(r.model.n_params());
  Rng init_rng(config.seed, "init");
  r.model.init_params(init_rng, r.theta);
  r.config.bootstrap.seed = config.seed;
  if (r.config.refine.method == "auto")
    resolve_auto_refine(r.config.refine, r.train.size(), r.train.dim(), r.model.n_params());
  if (r.config.bootstrap.replicates < 0) {
    r.config.bootstrap.replicates = 0;
    if (config.model == "csympnet" && r.model.n_params() <= kMaxLmParams) {
      r.config.bootstrap.replicates = kAutoBootstrapReplicates;
    } else if (config.model == "csympnet") {
      r.interval_note = "no interval by default for " + std::to_string(r.model.n_params()) +
                        " parameters (more than " + std::to_string(kMaxLmParams) +
                        "): each bootstrap replicate refits them; ask for one with --bootstrap N "
                        "(Python: bootstrap=N)";
    }
  }
  if (r.config.bootstrap.refine.method == "auto")
    r.config.bootstrap.refine = default_replicate_refine_for(r.config.refine);
  // A second stage that could not be interrupted is refused before any training.
  check_refine_fits(r.config.refine, r.train.size() * r.train.dim(), r.model.n_params());
  if (r.config.bootstrap.replicates > 0)
    check_refine_fits(r.config.bootstrap.refine, r.train.size() * r.train.dim(),
                      r.model.n_params());
  r.training = train_model(r.model, r.theta, r.train, r.val, r.config.train, progress);
  if (r.training.stop_reason != "budget") {  // diverged or stopped: no second stage
    r.stopped = r.training.stop_reason == "callback";
    return r;
  }
  r.refine =
      refine_one_step_map(*r.model.map, r.theta, r.train, r.val, r.config.refine, should_stop);
  if (r.refine.stopped) {
    r.stopped = true;
    if (r.config.bootstrap.replicates > 0)
      r.interval_note = "no interval: the fit was interrupted during the second stage";
    return r;
  }
  if (r.config.bootstrap.replicates > 0) {
    GammaInterval g = gamma_bootstrap(*r.model.map, r.theta, r.train, r.val, r.config.bootstrap,
                                      r.train_groups, should_stop);
    if (g.stopped) {
      r.stopped = true;
      r.interval_note = "no interval: the bootstrap was interrupted after " +
                        std::to_string(g.gammas.size()) + " of " +
                        std::to_string(r.config.bootstrap.replicates) + " replicates";
    } else {
      r.interval = std::move(g);
    }
  }
  return r;
}

}  // namespace csympnet
