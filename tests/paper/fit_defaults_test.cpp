#include <gtest/gtest.h>

#include "csympnet/paper/fit.hpp"

#include <cmath>

#include "csympnet/core/error.hpp"
#include "csympnet/core/options.hpp"

namespace csympnet {
namespace {

RefineOptions resolved(Index n_pairs, Index dim, Index n_params) {
  RefineOptions r;
  resolve_auto_refine(r, n_pairs, dim, n_params);
  return r;
}

TEST(FitDefaults, AutoRefineScalesTheSecondStageWithTheProblem) {
  // s1-sized: Ceres' dense QR, as before the normal-equations LM existed.
  RefineOptions r = resolved(80, 2, 115);
  EXPECT_EQ(r.method, RefineMethod::kLm);
  EXPECT_EQ(r.linear_solver, LinearSolver::kDenseQr);
  // s3-sized (400 pairs, 2d = 20, 4201 parameters): LM on the normal equations.
  r = resolved(400, 20, 4201);
  EXPECT_EQ(r.method, RefineMethod::kLm);
  EXPECT_EQ(r.linear_solver, LinearSolver::kBlasNormalCholesky);
  // Just past each limit of the middle tier, and s2-100: L-BFGS.
  EXPECT_EQ(resolved(400, 20, kMaxNormalLmParams + 1).method, RefineMethod::kLbfgs);
  EXPECT_EQ(resolved(5000, 20, 1001).method, RefineMethod::kLbfgs);  // 1.0e8 Jacobian entries
  EXPECT_EQ(resolved(400, 200, 161101).method, RefineMethod::kLbfgs);
  // The limits themselves are inside.
  EXPECT_EQ(resolved(1, 1, kMaxLmParams).linear_solver, LinearSolver::kDenseQr);
  EXPECT_EQ(resolved(1, 1, kMaxNormalLmParams).linear_solver, LinearSolver::kBlasNormalCholesky);
}

TEST(FitDefaults, BootstrapReplicatesInheritTheFitsSolver) {
  const RefineOptions fit = resolved(400, 20, 4201);
  const RefineOptions rep = default_replicate_refine_for(fit);
  EXPECT_EQ(rep.method, RefineMethod::kLm);
  EXPECT_EQ(rep.linear_solver, LinearSolver::kBlasNormalCholesky);
  EXPECT_EQ(rep.iterations, 10);
  EXPECT_FALSE(rep.keep_best_validation);
  RefineOptions lbfgs;
  lbfgs.method = RefineMethod::kLbfgs;
  EXPECT_EQ(default_replicate_refine_for(lbfgs).method, RefineMethod::kLbfgs);
}

// The recipes the front ends start from: `csympnet fit --recipe classic` and Python's fit
// take identification(), `csympnet train` adamw_only(); both anneal the rate (cosine) and take
// the epoch budget by dimension.
TEST(FitRecipes, IdentificationLeavesTheSizeDependentChoicesToTheFit) {
  const FitConfig c = FitConfig::identification();
  EXPECT_TRUE(c.warm_start);
  EXPECT_FALSE(c.refine_method.has_value());
  EXPECT_FALSE(c.bootstrap_replicates.has_value());
  EXPECT_FALSE(c.replicate_refine.has_value());
  EXPECT_EQ(c.train.lr_schedule, LrSchedule::kCosine);
  EXPECT_EQ(c.train.epochs, 0);
  EXPECT_EQ(c.train.val_every, 10);
  EXPECT_EQ(c.train.adamw.lr, 1e-3);
  EXPECT_EQ(c.seed, 42u);
  EXPECT_EQ(c.val_fraction, 0.2);
  EXPECT_EQ(c.beta_init, 0.1);
  EXPECT_EQ(nlohmann::json(c)["refine"]["method"], "auto");
  EXPECT_EQ(nlohmann::json(c)["bootstrap"]["replicates"], "auto");
  c.validate();
}

TEST(FitRecipes, AdamwOnlyHasNoSecondStageNoIntervalNoWarmStart) {
  const FitConfig c = FitConfig::adamw_only();
  EXPECT_FALSE(c.warm_start);
  EXPECT_EQ(c.refine_method, RefineMethod::kNone);
  EXPECT_EQ(c.bootstrap_replicates, 0);
  EXPECT_EQ(c.train.lr_schedule, LrSchedule::kCosine);
  EXPECT_EQ(nlohmann::json(c)["refine"]["method"], "none");
  c.validate();
}

TEST(FitRecipes, SettingsOverrideOnlyWhatWasGiven) {
  FitSettings s;
  EXPECT_EQ(nlohmann::json(make_fit_config(FitConfig::identification(), s)),
            nlohmann::json(FitConfig::identification()));
  s.refine = "lbfgs";
  s.refine_solver = "blas_normal_cholesky";
  s.bootstrap = 12;
  s.lr = 2e-3;
  s.epochs = 7;
  s.decay_damping = false;
  const FitConfig c = make_fit_config(FitConfig::adamw_only(), s);
  EXPECT_EQ(c.refine_method, RefineMethod::kLbfgs);
  EXPECT_EQ(c.refine.linear_solver, LinearSolver::kBlasNormalCholesky);
  EXPECT_EQ(c.bootstrap_replicates, 12);
  EXPECT_EQ(c.train.adamw.lr, 2e-3);
  EXPECT_EQ(c.train.epochs, 7);
  EXPECT_FALSE(c.train.adamw.decay_damping);
  EXPECT_FALSE(c.warm_start);  // the recipe's
  s = FitSettings{};
  s.refine = "auto";
  EXPECT_FALSE(make_fit_config(FitConfig::adamw_only(), s).refine_method.has_value());
}

// make_fit_config is the boundary: every misspelt value, value out of range and pair of
// options that do not go together is refused there, before any work, by the option's key.
TEST(FitRecipes, MisspeltValuesAndOutOfRangeOptionsAreRefusedByKey) {
  const auto key_of = [](const FitSettings& s) {
    try {
      make_fit_config(FitConfig::identification(), s);
    } catch (const OptionError& e) {
      return e.key();
    }
    return std::string();
  };
  const auto with = [](const auto& set) {
    FitSettings s;
    set(s);
    return s;
  };
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.refine = "newton"; })), "refine");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.refine_solver = "sparse"; })), "refine_solver");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.model = "ode"; })), "model");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.lr_schedule = "linear"; })), "lr_schedule");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.val_fraction = 1.0; })), "val_fraction");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.val_fraction = 0.005; })), "val_fraction");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.beta_init = 0.0; })), "beta_init");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.epochs = 0; })), "epochs");  // 0 is not a budget
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.epochs = 100000001; })), "epochs");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.val_every = 0; })), "val_every");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.lr = 0.0; })), "lr");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.lr = 11.0; })), "lr");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.lr_final_fraction = 2.0; })), "lr_final_fraction");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.weight_decay = -1.0; })), "weight_decay");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.threads = 0; })), "threads");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.threads = 257; })), "threads");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.refine_iterations = 0; })), "refine_iterations");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.bootstrap = -1; })), "bootstrap");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.bootstrap = 5; })), "bootstrap");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.bootstrap = 10; })), "");
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.bootstrap = 0; })), "");
  // The rules between options, with the other option named in the problem.
  try {
    make_fit_config(FitConfig::identification(), with([](FitSettings& s) {
                      s.model = "sympnet";
                      s.bootstrap = 10;
                    }));
    FAIL() << "a bootstrap of a model without a damping rate was accepted";
  } catch (const OptionError& e) {
    EXPECT_STREQ(e.what(),
                 "bootstrap: needs model = csympnet (the only model here with a damping rate)");
  }
  // refine_solver with refine auto (identification's default), which picks the solver itself.
  EXPECT_EQ(key_of(with([](FitSettings& s) { s.refine_solver = "dense_qr"; })), "refine_solver");
  EXPECT_EQ(key_of(with([](FitSettings& s) {
              s.refine = "lm";
              s.refine_solver = "dense_qr";
            })),
            "");
}

TEST(FitRecipes, ADefaultConstructedConfigIsTheDocumentedDefaultRecipe) {
  EXPECT_EQ(nlohmann::json(FitConfig{}), nlohmann::json(FitConfig::identification()));
  const FitConfig c;
  EXPECT_EQ(c.model, FitModel::kCSympNet);
  EXPECT_EQ(c.train.epochs, kAutoEpochs);  // by dimension, when fit_pairs sees the data
  EXPECT_EQ(c.train.lr_schedule, LrSchedule::kCosine);
  EXPECT_NO_THROW(c.validate());
}

TEST(FitRecipes, ModelAndRefineSpellingsRoundTrip) {
  for (const std::string& name : fit_model_names())
    EXPECT_EQ(to_string(parse_fit_model(name)), name);
  EXPECT_EQ(to_string(FitModel::kSympNet), "sympnet");
  EXPECT_THROW(parse_fit_model("CSympNet"), OptionError);
  const std::vector<std::string> choices = {"auto", "none", "lm", "lbfgs"};
  EXPECT_EQ(refine_choice_names(), choices);
}

// The report is the library's: every field but the file names, which the CLI adds.
TEST(FitReport, DescribesTheFitWithoutFileNames) {
  PairSet pairs;
  const Index n = 12;
  pairs.z0.resize(2, n);
  pairs.z1.resize(2, n);
  pairs.h.resize(n);
  for (Index j = 0; j < n; ++j) {
    const double t = 0.3 * static_cast<double>(j), h = 0.1 + 0.01 * static_cast<double>(j);
    pairs.z0.col(j) << std::cos(t), std::sin(t);
    pairs.z1.col(j) << std::exp(-0.05 * h) * std::cos(t + h), std::exp(-0.05 * h) * std::sin(t + h);
    pairs.h(j) = h;
  }
  FitConfig c = FitConfig::adamw_only();
  c.core = {{"type", "la"}, {"layers", 1}, {"sublayers", 2}};
  c.train.epochs = 20;
  const FitResult r = fit_pairs(pairs, std::nullopt, c);
  EXPECT_TRUE(r.val_split);
  const nlohmann::json rep = fit_report(r);
  EXPECT_TRUE(rep["data"].is_null());
  EXPECT_EQ(rep["validation"], "split");
  EXPECT_EQ(rep["h_min"], pairs.h.minCoeff());  // over the training and the held-out pairs
  EXPECT_EQ(rep["h_max"], pairs.h.maxCoeff());
  EXPECT_EQ(rep["pairs_train"].get<Index>() + rep["pairs_val"].get<Index>(), n);
  EXPECT_EQ(rep["epochs"], 20);
  EXPECT_EQ(rep["config"]["refine"]["method"], "none");
  EXPECT_EQ(rep["config"]["bootstrap"]["replicates"], 0);
  EXPECT_EQ(rep["training"]["stop_reason"], "budget");
  EXPECT_EQ(rep["warm_start"], "off");
  EXPECT_TRUE(rep["gamma_ci_low"].is_null());
  EXPECT_EQ(rep["gamma_hat"], *r.model.damping_rate(r.theta));
  EXPECT_EQ(rep["quality"]["val_loss"], rep["best_val_loss"]);
  EXPECT_FALSE(rep.contains("interrupted"));
  // With a validation set given, "validation" is left for the caller to name.
  const FitResult given = fit_pairs(r.train, r.val, c);
  EXPECT_FALSE(given.val_split);
  EXPECT_TRUE(fit_report(given)["validation"].is_null());
}

}  // namespace
}  // namespace csympnet
