// one_step_loss (src/train/loss.cpp) forms the residual and dL/dΦ̂ = (2/N) r in place. Its loss
// and gradient must be, bit for bit, those of the previous expressions
//   r = Φ̂(z0) − z1,   grad = backward((2/N) r),   L = ‖r‖² / N,
// on CSympNet-ID (LA and G cores, d = 1 and d > 1) and on a bare SympNet core, with a cache
// reused across calls and batches. AdamW::step, which now tests sizes before building its
// message, must still reject wrong sizes.
#include "csympnet/train/loss.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <memory>
#include <random>

#include "../src/models/csympnet_id.hpp"
#include "../src/models/g_sympnet.hpp"
#include "../src/models/la_sympnet.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/train/adamw.hpp"
#include "support/random_data.hpp"
#include "support/same_bits.hpp"

namespace csympnet {
namespace {

using testing::random_pairs;
using testing::same_bits;

// The previous one_step_loss.
double reference_loss(const OneStepMap& map, ConstParams theta, const PairSet& pairs,
                      Vector* grad) {
  ForwardCache cache;
  const Matrix residual =
      map.forward(theta, pairs.z0, pairs.h, grad != nullptr ? &cache : nullptr) - pairs.z1;
  const double n = static_cast<double>(pairs.size());
  if (grad != nullptr) {
    grad->setZero(map.n_params());
    map.backward(theta, cache, (2.0 / n) * residual, *grad, nullptr);
  }
  return residual.squaredNorm() / n;
}

void expect_same_as_reference(const OneStepMap& map, std::mt19937_64& gen) {
  SCOPED_TRACE(map.hyperparams().dump());
  std::normal_distribution<double> normal;
  ForwardCache cache;  // reused across the batches, as in training
  for (const Index n : {1, 7, 80, 81, 3}) {
    SCOPED_TRACE("N = " + std::to_string(n));
    const PairSet pairs = random_pairs(map.dim(), n, gen);
    Vector theta(map.n_params());
    for (Index i = 0; i < theta.size(); ++i) theta(i) = 0.4 * normal(gen);
    Vector ref_grad, grad, grad_local;
    const double ref = reference_loss(map, theta, pairs, &ref_grad);
    EXPECT_TRUE(same_bits(one_step_loss(map, theta, pairs, &grad, &cache), ref));
    EXPECT_TRUE(same_bits(grad, ref_grad));
    EXPECT_TRUE(same_bits(one_step_loss(map, theta, pairs, &grad_local), ref));
    EXPECT_TRUE(same_bits(grad_local, ref_grad));
    EXPECT_TRUE(
        same_bits(one_step_loss(map, theta, pairs), reference_loss(map, theta, pairs, nullptr)));
  }
}

TEST(OneStepLoss, MatchesPreviousExpressionsBitForBit) {
  std::mt19937_64 gen(5);
  expect_same_as_reference(CSympNetId(std::make_unique<LaSympNet>(1, 5, 20)), gen);
  expect_same_as_reference(CSympNetId(std::make_unique<LaSympNet>(1, 3, 4, 2)), gen);
  expect_same_as_reference(CSympNetId(std::make_unique<LaSympNet>(3, 2, 3)), gen);
  expect_same_as_reference(CSympNetId(std::make_unique<GSympNet>(1, 3, 8)), gen);
  expect_same_as_reference(CSympNetId(std::make_unique<GSympNet>(2, 2, 5)), gen);
  expect_same_as_reference(LaSympNet(1, 2, 4), gen);
  expect_same_as_reference(GSympNet(2, 2, 3), gen);
}

TEST(AdamWSizes, WrongSizesThrowWithTheSizes) {
  AdamW opt(3, {});
  Vector theta = Vector::Zero(3);
  const Vector g = Vector::Ones(2);
  try {
    opt.step(theta, g);
    FAIL() << "expected an Error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("AdamW::step"), std::string::npos) << what;
    EXPECT_NE(what.find("(3), got 3 and 2"), std::string::npos) << what;
  }
  EXPECT_EQ(opt.steps_taken(), 0);
}

}  // namespace
}  // namespace csympnet
