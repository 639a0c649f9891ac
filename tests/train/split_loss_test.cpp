// one_step_loss on a team of threads (LossSplit, loss.hpp) must give the serial loss and
// gradient to the bit, and training with TrainOptions::threads > 1 the serial run's bits.
#include <gtest/gtest.h>

#include <memory>
#include <random>

#include "../src/kernels/product.hpp"
#include "../src/models/csympnet_id.hpp"
#include "../src/models/g_sympnet.hpp"
#include "../src/models/la_sympnet.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/paper/run.hpp"
#include "csympnet/train/loss.hpp"
#include "support/random_data.hpp"
#include "support/same_bits.hpp"

namespace csympnet::testing {
namespace {

bool kernels_run() {
  return std::string(kernels::product_kernel_isa()) != "portable";
}

TEST(SplitLoss, EqualsTheSerialLossAndGradientToTheBit) {
  std::mt19937_64 gen(77);
  std::normal_distribution<double> normal;
  std::vector<std::unique_ptr<CSympNetId>> models;
  models.push_back(std::make_unique<CSympNetId>(std::make_unique<LaSympNet>(10, 3, 4)));
  models.push_back(std::make_unique<CSympNetId>(std::make_unique<LaSympNet>(8, 2, 3, 2)));
  models.push_back(std::make_unique<CSympNetId>(std::make_unique<GSympNet>(10, 3, 50)));
  int split = 0;
  for (int threads : {2, 3}) {
    ThreadTeam team(threads);
    for (const auto& model : models) {
      for (Index n : {40, 81, 400}) {
        SCOPED_TRACE(model->hyperparams().dump() + " N=" + std::to_string(n) +
                     " threads=" + std::to_string(threads));
        const PairSet pairs = random_pairs(model->dim(), n, gen);
        Vector theta(model->n_params());
        for (Index i = 0; i < theta.size(); ++i) theta(i) = 0.3 * normal(gen);
        const LossSplit plan = plan_loss_split(*model, n, &team);
        split += plan.active() ? 1 : 0;
        ForwardCache serial_cache, split_cache;
        Vector g_serial, g_split;
        // Twice each: a reused cache must give the same again.
        for (int rep = 0; rep < 2; ++rep) {
          const double l_serial = one_step_loss(*model, theta, pairs, &g_serial, &serial_cache);
          const double l_split = one_step_loss(*model, theta, pairs, &g_split, &split_cache, plan);
          EXPECT_TRUE(same_bits(l_serial, l_split));
          EXPECT_TRUE(same_bits(g_serial, g_split));
        }
        // Without a gradient: the loss alone.
        EXPECT_TRUE(same_bits(one_step_loss(*model, theta, pairs),
                              one_step_loss(*model, theta, pairs, nullptr, &split_cache, plan)));
      }
    }
  }
  // Every one of these splits where the exact kernels run; else the test said nothing.
  if (kernels_run()) {
    EXPECT_EQ(split, 18);
  }
}

TEST(SplitLoss, PlansSeriallyWhenNothingSplits) {
  ThreadTeam team(2);
  const CSympNetId d1(std::make_unique<LaSympNet>(1, 2, 4));
  EXPECT_FALSE(plan_loss_split(d1, 80, &team).active());  // d = 1 sweeps are single-row kernels
  const CSympNetId d10(std::make_unique<LaSympNet>(10, 2, 4));
  EXPECT_FALSE(plan_loss_split(d10, 400, nullptr).active());
  ThreadTeam one(1);
  EXPECT_FALSE(plan_loss_split(d10, 400, &one).active());
  EXPECT_FALSE(plan_loss_split(d10, 8, &team).active());  // one aligned block: one range
}

TEST(SplitLoss, RefusesABatchOfAnotherSize) {
  if (!kernels_run()) GTEST_SKIP() << "no exact kernels: nothing splits";
  ThreadTeam team(2);
  const CSympNetId model(std::make_unique<LaSympNet>(10, 2, 4));
  const LossSplit plan = plan_loss_split(model, 400, &team);
  ASSERT_TRUE(plan.active());
  std::mt19937_64 gen(5);
  const PairSet pairs = random_pairs(model.dim(), 80, gen);
  Vector theta = Vector::Constant(model.n_params(), 0.01), grad;
  ForwardCache cache;
  EXPECT_THROW(one_step_loss(model, theta, pairs, &grad, &cache, plan), Error);
}

// A whole run (data, training with checkpoints, evaluation) with threads = 2 and 3 reports what
// the serial run reports, on the presets whose cores split.
TEST(SplitLoss, ThreadedRunsReportTheSerialBits) {
  for (const std::string preset : {"s2", "s3"}) {
    RunConfig c = default_run_config(preset, "csympnet");
    c.train.epochs = 40;
    const RunResult serial = run_experiment(c);
    for (int threads : {2, 3}) {
      c.train.threads = threads;
      const RunResult threaded = run_experiment(c);
      EXPECT_TRUE(same_bits(serial.theta, threaded.theta)) << preset << " threads " << threads;
      nlohmann::json a = serial.report, b = threaded.report;
      for (auto* r : {&a, &b}) {
        r->erase("train_seconds");
        r->erase("eval_seconds");
        r->erase("train_threads");
      }
      EXPECT_EQ(a, b) << preset << " threads " << threads;
      EXPECT_EQ(threaded.report.at("train_threads"), threads);
    }
  }
}

}  // namespace
}  // namespace csympnet::testing
