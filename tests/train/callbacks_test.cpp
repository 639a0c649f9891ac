// IterationMonitor (train/callbacks.hpp): the checkpoint, progress, interrupt and patience
// rules, and that AdamW, both LMs and L-BFGS apply them alike.
#include "csympnet/train/callbacks.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "csympnet/train/levenberg_marquardt.hpp"
#include "support/train_fixtures.hpp"

namespace csympnet {
namespace {

Vector scalar(double x) {
  Vector v(1);
  v << x;
  return v;
}

// Validation loss = the single parameter itself, so a test chooses each iterate's loss.
double identity_loss(const Vector& theta) {
  return theta(0);
}

TEST(IterationMonitor, KeepsTheStrictlyLowestAndTheEarliestOfEqualLosses) {
  const IterationCallbacks none;
  IterationMonitor m("test", 10, identity_loss, scalar(5.0), none);
  EXPECT_EQ(m.start_loss(), 5.0);
  EXPECT_EQ(m.best_iteration(), 0);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<double> losses = {4.0, 6.0, 3.0, 3.0, nan, inf, 3.5};
  for (std::size_t k = 0; k < losses.size(); ++k)
    EXPECT_TRUE(m.accept(static_cast<long>(k) + 1, scalar(losses[k])));
  EXPECT_EQ(m.best_loss(), 3.0);
  EXPECT_EQ(m.best_iteration(), 3);  // the first of the two 3.0s
  EXPECT_EQ(m.best()(0), 3.0);
  EXPECT_EQ(m.cause(), StopCause::kNone);
}

TEST(IterationMonitor, ANonFiniteStartIsReplacedByTheFirstFiniteIterate) {
  const IterationCallbacks none;
  IterationMonitor m("test", 10, identity_loss, scalar(std::numeric_limits<double>::infinity()),
                     none);
  m.accept(1, scalar(7.0));
  EXPECT_EQ(m.best_iteration(), 1);
}

TEST(IterationMonitor, ReportsProgressAndStopsWhenTheCallbackSaysSo) {
  std::vector<TrainProgress> seen;
  IterationCallbacks cb;
  cb.progress = [&seen](const TrainProgress& p) {
    seen.push_back(p);
    return p.epoch < 3;
  };
  IterationMonitor m("lm", 40, identity_loss, scalar(9.0), cb,
                     [](const Vector& t) { return std::optional<double>(2.0 * t(0)); });
  EXPECT_TRUE(m.accept(1, scalar(8.0), 0.5));
  EXPECT_TRUE(m.accept(2, scalar(8.5)));
  EXPECT_FALSE(m.stop_before(3));
  EXPECT_FALSE(m.accept(3, scalar(1.0)));
  EXPECT_EQ(m.cause(), StopCause::kCallback);
  EXPECT_TRUE(m.stop_before(4));
  ASSERT_EQ(seen.size(), 3u);
  EXPECT_STREQ(seen[0].stage, "lm");
  EXPECT_EQ(seen[0].epochs, 40);
  EXPECT_EQ(seen[0].train_loss, 0.5);
  EXPECT_TRUE(std::isnan(seen[1].train_loss));  // not given
  EXPECT_EQ(seen[1].val_loss, 8.5);
  EXPECT_EQ(seen[1].best_val_loss, 8.0);
  EXPECT_EQ(seen[2].best_val_loss, 1.0);  // the stopping iterate is still validated and kept
  EXPECT_EQ(seen[2].gamma_hat, 2.0);
  EXPECT_EQ(m.best_iteration(), 3);
}

TEST(IterationMonitor, PatienceCountsIterationsAfterTheBest) {
  IterationCallbacks cb;
  cb.patience = 3;
  IterationMonitor m("test", 100, identity_loss, scalar(1.0), cb);
  m.accept(2, scalar(0.5));  // best at 2
  EXPECT_FALSE(m.stop_before(5));
  m.accept(5, scalar(0.7));  // no better
  EXPECT_FALSE(m.stop_before(5));
  EXPECT_TRUE(m.stop_before(6));
  EXPECT_EQ(m.cause(), StopCause::kPatience);
}

TEST(IterationMonitor, RemembersAnInterruptAndNamesIt) {
  int polls = 0;
  IterationCallbacks cb;
  cb.should_stop = [&polls] { return ++polls == 2; };  // true once only
  cb.progress = [](const TrainProgress&) { return false; };
  IterationMonitor m("test", 10, identity_loss, scalar(1.0), cb);
  EXPECT_FALSE(m.interrupted());
  EXPECT_TRUE(m.interrupted());
  EXPECT_TRUE(m.interrupted());  // sticky, although should_stop now says false
  EXPECT_TRUE(m.stop_before(1));
  // A callback that says no because of the interrupt does not hide it.
  EXPECT_FALSE(m.accept(1, scalar(0.5)));
  EXPECT_EQ(m.cause(), StopCause::kInterrupt);
}

// LM through lm_hooks, on Rosenbrock's problem (many iterations from the classic start) with a
// validation loss that improves only at the first accepted step: with patience P the solve ends
// exactly P iterations after that step, however often the solver polls should_stop within an
// iteration (here: before each iteration and after each Jacobian).
TEST(IterationMonitor, LmPatienceIsInIterationsNotPolls) {
  LeastSquaresProblem p = testing::rosenbrock_problem();
  for (long patience : {5L, 8L}) {
    long validations = 0;
    // Call 0 validates the start; call 1 (the first accepted step) is the best; then worse.
    auto validation = [&validations](const Vector&) {
      const long k = validations++;
      return k == 1 ? 0.0 : 1.0 + static_cast<double>(k);
    };
    long polls = 0;
    IterationCallbacks cb;
    cb.patience = patience;
    IterationMonitor monitor("lm", 200, validation, Vector::Zero(2), cb);
    p.should_stop = [&] {
      ++polls;
      return monitor.interrupted();
    };
    Vector x(2);
    x << -1.2, 1.0;
    LmSettings s;
    s.max_iterations = 200;
    const LmReport r = levenberg_marquardt(p, x, s, lm_hooks(monitor));
    ASSERT_GE(monitor.best_iteration(), 1);
    EXPECT_EQ(r.iterations, monitor.best_iteration() + patience) << r.message;
    EXPECT_EQ(r.message, "stopped by the caller");
    EXPECT_EQ(monitor.cause(), StopCause::kPatience);
    EXPECT_GT(polls, r.iterations);  // several polls per iteration did not shorten the patience
  }
}

}  // namespace
}  // namespace csympnet
