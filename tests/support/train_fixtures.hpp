// Fixtures the optimiser tests share: a small least-squares problem with a known answer, and a
// CSympNet-ID map that AdamW has trained on damped rotation data (the second stages' start).
#pragma once

#include <memory>

#include <nlohmann/json.hpp>

#include "csympnet/core/rng.hpp"
#include "csympnet/train/levenberg_marquardt.hpp"
#include "csympnet/train/objective.hpp"
#include "csympnet/train/trainer.hpp"
#include "support/model_fixtures.hpp"

namespace csympnet::testing {

// Rosenbrock's function as residuals r = (10 (x₁ − x₀²), 1 − x₀): minimum 0 at (1, 1); from
// the classic start (−1.2, 1) Levenberg–Marquardt takes a few dozen iterations.
inline LeastSquaresProblem rosenbrock_problem() {
  LeastSquaresProblem p;
  p.n_residuals = 2;
  p.n_params = 2;
  p.residuals = [](ConstParams x, Eigen::Ref<Vector> r) {
    r(0) = 10.0 * (x(1) - x(0) * x(0));
    r(1) = 1.0 - x(0);
    return true;
  };
  p.jacobian = [](ConstParams x, Eigen::Ref<RowMajorMatrix> j) {
    j << -20.0 * x(0), 10.0, -1.0, 0.0;
  };
  return p;
}

struct TrainedMap {
  std::unique_ptr<OneStepMap> map;
  Vector theta;
  PairSet train, val;
};

// CSympNet-ID (d = 1, an LA core of 2 × 3) after 500 AdamW epochs on 30 damped-rotation pairs,
// validated on 10 others: where a second stage starts.
inline TrainedMap adamw_trained_rotation_map() {
  TrainedMap t;
  t.map = make_one_step_map(nlohmann::json::parse(
      R"({"type":"csympnet","d":1,"core":{"type":"la","layers":2,"sublayers":3}})"));
  t.theta.resize(t.map->n_params());
  Rng rng(3, "init");
  t.map->init_params(rng, t.theta);
  t.train = damped_rotation_pairs(30, 1, "rotation");
  t.val = damped_rotation_pairs(10, 2, "rotation");
  TrainOptions o;
  o.epochs = 500;
  o.adamw.lr = 1e-2;
  o.lr_schedule = LrSchedule::kCosine;
  train_parameters(make_one_step_objective(*t.map, t.train, t.val), t.theta, o);
  return t;
}

}  // namespace csympnet::testing
