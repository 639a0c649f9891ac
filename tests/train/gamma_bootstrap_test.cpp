// gamma_bootstrap's callbacks (train/gamma_bootstrap.hpp): progress per replicate, a stop.
#include "csympnet/train/gamma_bootstrap.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "support/train_fixtures.hpp"

namespace csympnet {
namespace {

using Fitted = testing::TrainedMap;

Fitted fitted() {
  return testing::adamw_trained_rotation_map();
}

BootstrapOptions options() {
  BootstrapOptions b;
  b.replicates = 12;
  b.seed = 5;
  b.refine.method = RefineMethod::kLm;
  b.refine.iterations = 10;
  return b;
}

TEST(GammaBootstrap, ReportsEachReplicateAndTheSameIntervalAsWithoutCallbacks) {
  const Fitted f = fitted();
  const GammaInterval plain = gamma_bootstrap(*f.map, f.theta, f.train, f.val, options());
  std::vector<TrainProgress> seen;
  IterationCallbacks cb;
  cb.progress = [&seen](const TrainProgress& p) {
    seen.push_back(p);
    return true;
  };
  const GammaInterval watched = gamma_bootstrap(*f.map, f.theta, f.train, f.val, options(), {}, cb);
  EXPECT_EQ(watched.gammas, plain.gammas);  // watching changes nothing
  EXPECT_EQ(watched.low, plain.low);
  ASSERT_EQ(seen.size(), 12u);
  for (std::size_t k = 0; k < seen.size(); ++k) {
    EXPECT_STREQ(seen[k].stage, "bootstrap");
    EXPECT_EQ(seen[k].epoch, static_cast<long>(k) + 1);
    EXPECT_EQ(seen[k].epochs, 12);
    EXPECT_EQ(seen[k].gamma_hat, plain.gammas[k]);
    EXPECT_TRUE(std::isnan(seen[k].val_loss));
  }
}

TEST(GammaBootstrap, AProgressCallbackCanStopIt) {
  const Fitted f = fitted();
  IterationCallbacks cb;
  cb.progress = [](const TrainProgress& p) { return p.epoch < 4; };
  const GammaInterval g = gamma_bootstrap(*f.map, f.theta, f.train, f.val, options(), {}, cb);
  EXPECT_TRUE(g.stopped);
  EXPECT_EQ(g.gammas.size(), 4u);
}

}  // namespace
}  // namespace csympnet
