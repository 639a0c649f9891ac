#include "csympnet/train/adamw.hpp"

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"

namespace csympnet {
namespace {

// One step worked by hand from PyTorch's AdamW update (see adamw.hpp):
//   θ = (1, −2), g = (0.5, −0.1), lr = 0.1, wd = 0.01
//   decay:   θ ← θ(1 − 0.001)                = (0.999, −1.998)
//   moments: m = 0.1 g = (0.05, −0.01),  v = 0.001 g² = (2.5e-4, 1e-5)
//   bias corrections 1 − 0.9 = 0.1 and 1 − 0.999 = 0.001, so step_size = lr / 0.1 = 1 and
//   √v / √0.001 = |g| = (0.5, 0.1)
//   θ ← θ − m / (|g| + 1e-8) = (0.999 − 0.05/0.50000001, −1.998 + 0.01/0.10000001)
TEST(AdamW, OneStepMatchesHandComputation) {
  AdamWOptions o;
  o.lr = 0.1;
  o.weight_decay = 0.01;
  AdamW opt(2, o);
  Vector theta(2), g(2);
  theta << 1.0, -2.0;
  g << 0.5, -0.1;
  opt.step(theta, g);
  EXPECT_NEAR(theta(0), 0.899000002, 1e-15);
  EXPECT_NEAR(theta(1), -1.8980000099999999, 1e-15);
  EXPECT_EQ(opt.steps_taken(), 1);
}

// Second step with a different gradient, also by hand:
//   θ1 = (0.899000002, −1.89800001), g2 = (0.2, 0.3)
//   m2 = 0.9·0.05 + 0.1·0.2 = 0.065,        0.9·(−0.01) + 0.1·0.3 = 0.021
//   v2 = 0.999·2.5e-4 + 0.001·0.04 = 2.8975e-4,  0.999·1e-5 + 0.001·0.09 = 9.999e-5
//   bias1 = 1 − 0.81 = 0.19, bias2 = 1 − 0.998001 = 0.001999
TEST(AdamW, SecondStepMatchesHandComputation) {
  AdamWOptions o;
  o.lr = 0.1;
  o.weight_decay = 0.01;
  AdamW opt(2, o);
  Vector theta(2), g(2);
  theta << 1.0, -2.0;
  g << 0.5, -0.1;
  opt.step(theta, g);
  const Vector theta1 = theta;
  g << 0.2, 0.3;
  opt.step(theta, g);
  const double m[2] = {0.065, 0.021};
  const double v[2] = {2.8975e-4, 9.999e-5};
  for (int i = 0; i < 2; ++i) {
    const double expected = theta1(i) * (1 - 0.001) -
                            (0.1 / 0.19) * m[i] / (std::sqrt(v[i]) / std::sqrt(0.001999) + 1e-8);
    EXPECT_NEAR(theta(i), expected, 1e-14) << i;
  }
}

TEST(AdamW, ExcludingDampingFromDecayLeavesOnlyTheAdamStep) {
  AdamWOptions o;
  o.lr = 0.1;
  o.weight_decay = 0.5;
  o.decay_damping = false;
  AdamW opt(2, o, Index{1});
  Vector theta(2), g = Vector::Zero(2);
  theta << 1.0, 0.05;
  opt.step(theta, g);  // zero gradient: only decay acts
  EXPECT_DOUBLE_EQ(theta(0), 1.0 * (1 - 0.05));
  EXPECT_DOUBLE_EQ(theta(1), 0.05);
}

TEST(AdamW, RejectsBadOptions) {
  AdamWOptions o;
  o.lr = -1;
  EXPECT_THROW(o.validate(), Error);
  o = {};
  o.beta1 = 1.0;
  EXPECT_THROW(o.validate(), Error);
  o = {};
  o.weight_decay = std::nan("");
  EXPECT_THROW(o.validate(), Error);
}

}  // namespace
}  // namespace csympnet
