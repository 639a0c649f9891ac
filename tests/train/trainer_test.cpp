#include "csympnet/train/trainer.hpp"
#include "csympnet/train/objective.hpp"

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "csympnet/train/loss.hpp"
#include "support/model_fixtures.hpp"

namespace csympnet {
namespace {

// A tiny damped-rotation data set: z1 = e^{-γh/2} R(h) e^{-γh/2}-ish, enough to train on.
PairSet toy_pairs(Index n, std::uint64_t seed) {
  return testing::damped_rotation_pairs(n, seed, "toy");
}

std::unique_ptr<OneStepMap> tiny_model() {
  return make_one_step_map({{"type", "csympnet"},
                            {"d", 1},
                            {"core", {{"type", "la"}, {"layers", 2}, {"sublayers", 2}}},
                            {"beta_init", 0.1}});
}

TEST(Trainer, KeepsTheBestValidationCheckpoint) {
  auto map = tiny_model();
  Vector theta(map->n_params());
  Rng rng(1, "init");
  map->init_params(rng, theta);
  TrainOptions o;
  o.epochs = 300;
  o.val_every = 7;
  o.adamw.lr = 1e-2;
  const PairSet train = toy_pairs(40, 1), val = toy_pairs(10, 2);
  const double initial_val = one_step_loss(*map, theta, val);
  std::vector<double> seen;
  const TrainSummary s = train_parameters(make_one_step_objective(*map, train, val), theta, o,
                                          [&](const TrainProgress& p) {
                                            seen.push_back(p.val_loss);
                                            return true;
                                          });
  EXPECT_EQ(s.epochs_run, 300);
  EXPECT_EQ(s.stop_reason, StopReason::kBudget);
  // Validations at 7, 14, ..., 294 and at the final epoch 300.
  EXPECT_EQ(seen.size(), 300u / 7 + 1);
  const double best_seen = *std::min_element(seen.begin(), seen.end());
  EXPECT_EQ(s.best_val_loss, std::min(best_seen, initial_val));
  // The returned parameters are the checkpoint: their validation loss is the best one.
  EXPECT_EQ(one_step_loss(*map, theta, val), s.best_val_loss);
  EXPECT_LT(s.best_val_loss, initial_val);
}

TEST(Trainer, SameInputsGiveBitIdenticalParameters) {
  auto map = tiny_model();
  TrainOptions o;
  o.epochs = 100;
  const PairSet train = toy_pairs(30, 3), val = toy_pairs(8, 4);
  Vector a(map->n_params()), b(map->n_params());
  Rng r1(5, "init"), r2(5, "init");
  map->init_params(r1, a);
  map->init_params(r2, b);
  train_parameters(make_one_step_objective(*map, train, val), a, o);
  train_parameters(make_one_step_objective(*map, train, val), b, o);
  EXPECT_EQ(a, b);
}

TEST(Trainer, CallbackCanStopAndDivergenceIsCaught) {
  auto map = tiny_model();
  Vector theta(map->n_params());
  Rng rng(1, "init");
  map->init_params(rng, theta);
  TrainOptions o;
  o.epochs = 1000;
  o.val_every = 10;
  const PairSet train = toy_pairs(20, 1), val = toy_pairs(5, 2);
  const TrainSummary s = train_parameters(make_one_step_objective(*map, train, val), theta, o,
                                          [](const TrainProgress& p) { return p.epoch < 50; });
  EXPECT_EQ(s.stop_reason, StopReason::kCallback);
  EXPECT_EQ(s.epochs_run, 50);

  PairSet bad = train;
  bad.z1(0, 0) = 1e300;  // the squared residual overflows to inf
  Vector t2(map->n_params());
  Rng rng2(1, "init");
  map->init_params(rng2, t2);
  const Vector before = t2;
  const TrainSummary s2 = train_parameters(make_one_step_objective(*map, bad, val), t2, o);
  EXPECT_EQ(s2.stop_reason, StopReason::kDiverged);
  EXPECT_EQ(t2, before);  // the best checkpoint (the initial one) is kept
}

TEST(Trainer, RejectsMismatchedData) {
  auto map = tiny_model();
  Vector theta = Vector::Zero(map->n_params());
  theta(theta.size() - 1) = 0.1;
  PairSet p;
  p.z0 = Matrix::Zero(4, 3);
  p.z1 = Matrix::Zero(4, 3);
  p.h = Vector::Constant(3, 0.1);
  EXPECT_THROW(train_parameters(make_one_step_objective(*map, p, p), theta, {}), Error);
}

}  // namespace
}  // namespace csympnet

namespace csympnet {
namespace {

TEST(TrainOptions, CosineScheduleRunsFromLrToTheFinalFraction) {
  TrainOptions o;
  o.epochs = 101;
  o.adamw.lr = 2e-3;
  EXPECT_EQ(o.lr_at(1), 2e-3);  // constant: the paper's recipe
  EXPECT_EQ(o.lr_at(101), 2e-3);
  o.lr_schedule = LrSchedule::kCosine;
  o.lr_final_fraction = 1e-3;
  EXPECT_DOUBLE_EQ(o.lr_at(1), 2e-3);
  EXPECT_DOUBLE_EQ(o.lr_at(101), 2e-6);
  EXPECT_DOUBLE_EQ(o.lr_at(51), 2e-3 * (1e-3 + (1 - 1e-3) * 0.5));  // halfway: cos = 0
  for (long e = 2; e <= 101; ++e) EXPECT_LT(o.lr_at(e), o.lr_at(e - 1));
  EXPECT_THROW(parse_lr_schedule("linear"), Error);
  EXPECT_THROW(nlohmann::json({{"lr_schedule", "linear"}}).get<TrainOptions>(), Error);
  for (LrSchedule s : {LrSchedule::kConstant, LrSchedule::kCosine})
    EXPECT_EQ(parse_lr_schedule(to_string(s)), s);
  const std::vector<std::string> names = {"constant", "cosine"};
  EXPECT_EQ(lr_schedule_names(), names);
  try {
    parse_lr_schedule("linear");
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "train.lr_schedule must be 'constant' or 'cosine', got 'linear'");
  }
}

}  // namespace
}  // namespace csympnet

namespace csympnet {
namespace {

// Every option that changes training is in the JSON (reports and reproduce's cache keys rely
// on it), and reading it back gives the same options.
TEST(TrainOptionsJson, RoundTripsEveryField) {
  TrainOptions o;
  o.epochs = 1234;
  o.val_every = 7;
  o.adamw.lr = 3e-3;
  o.adamw.weight_decay = 1e-5;
  o.adamw.decay_damping = false;
  o.lr_schedule = LrSchedule::kCosine;
  o.lr_final_fraction = 0.25;
  const nlohmann::json j = o;
  EXPECT_EQ(j["lr_schedule"], "cosine");
  EXPECT_EQ(j["lr_final_fraction"], 0.25);
  const TrainOptions back = j.get<TrainOptions>();
  EXPECT_EQ(nlohmann::json(back), j);
  TrainOptions other = o;
  other.lr_schedule = LrSchedule::kConstant;
  EXPECT_NE(nlohmann::json(other), j);
}

TEST(Trainer, StopReasonsRoundTripThroughTheirSpellings) {
  const std::vector<std::string> names = {"budget", "callback", "diverged"};
  EXPECT_EQ(stop_reason_names(), names);
  for (StopReason r : {StopReason::kBudget, StopReason::kCallback, StopReason::kDiverged})
    EXPECT_EQ(parse_stop_reason(to_string(r)), r);
  try {
    parse_stop_reason("interrupted", "training.stop_reason");
    FAIL() << "accepted 'interrupted'";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "training.stop_reason must be 'budget', 'callback' or 'diverged', got "
              "'interrupted'");
  }
}

}  // namespace
}  // namespace csympnet
