// The checks around state_from_positions for the front ends: a window with a gap, and a fit
// that does not explain its window, are refused rather than forecast from.
#include "csympnet/train/positions_state.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "support/refusal.hpp"

namespace csympnet {
namespace {

using testing::refusal;

TEST(PositionsState, AWindowWithAGapIsRefused) {
  Matrix q(1, 6);
  q << 0, 1, 2, 3, 4, 5;
  Vector t(6);
  t << 0, 0.1, 0.2, 0.3, 0.4, 0.5;
  EXPECT_EQ(refusal([&] { check_positions_window(q, t, "w.csv"); }), "");
  t << 0, 0.1, 0.2, 5.0, 5.1, 5.2;
  const std::string why = refusal([&] { check_positions_window(q, t, "w.csv"); });
  EXPECT_NE(why.find("w.csv: a gap from t = 0.2 to t = 5"), std::string::npos) << why;
  // Irregular steps within a factor 5 of the median are no gap.
  t << 0, 0.1, 0.15, 0.3, 0.45, 0.5;
  EXPECT_EQ(refusal([&] { check_positions_window(q, t, "w.csv"); }), "");
  t << 0, 0.1, 0.1, 0.3, 0.4, 0.5;
  EXPECT_NE(refusal([&] { check_positions_window(q, t, "w.csv"); }).find("do not increase"),
            std::string::npos);
}

TEST(PositionsState, AFitThatMissesItsWindowIsRefused) {
  Matrix q(2, 4);
  q << 0, 1, 0, -1, 1, 0, -1, 0;  // spread sqrt(0.5)
  Vector z = Vector::Zero(4);
  EXPECT_EQ(refusal([&] { check_state_fit(q, z, 0.01, "w"); }), "");
  const std::string far = refusal([&] { check_state_fit(q, z, 20091.0, "w"); });
  EXPECT_NE(far.find("does not explain"), std::string::npos) << far;
  EXPECT_NE(far.find("20091 rms"), std::string::npos) << far;
  EXPECT_NE(refusal([&] { check_state_fit(q, z, 2.79e63, "w"); }), "");
  EXPECT_NE(refusal([&] { check_state_fit(q, z, std::nan(""), "w"); }).find("not finite"),
            std::string::npos);
  z(3) = std::numeric_limits<double>::infinity();
  EXPECT_NE(refusal([&] { check_state_fit(q, z, 0.0, "w"); }), "");
}

// A decayed window: a slow motion of amplitude 1 under noise of sd 0.3. A state that misses it
// by the noise is accepted although that is far more than 10% of the spread; one that misses
// it by twice the noise (and more than half the spread) is not.
TEST(PositionsState, AWindowNearTheNoiseIsExplainedByAFitAtTheNoise) {
  Rng rng(3, "state-noise");
  const Index n = 200;
  Matrix q(1, n);
  for (Index k = 0; k < n; ++k)
    q(0, k) = std::cos(0.25 * static_cast<double>(k)) + 0.3 * rng.normal();
  const Vector z = Vector::Zero(2);
  EXPECT_EQ(refusal([&] { check_state_fit(q, z, 0.3, "w"); }), "");
  const std::string why = refusal([&] { check_state_fit(q, z, 0.6, "w"); });
  EXPECT_NE(why.find("times their noise"), std::string::npos) << why;
  // Noise alone (a zigzag at the sampling rate): nothing is explained, whatever the noise.
  Matrix zigzag(1, 40);
  for (Index k = 0; k < 40; ++k) zigzag(0, k) = k % 2 == 0 ? 1.0 : -1.0;
  EXPECT_NE(refusal([&] { check_state_fit(zigzag, z, 0.9, "w"); }), "");
}

// A driven record's warm-up from rest: positions that are noise alone about a state at rest.
// Without inputs nothing in such a window is explained (refused, as above); with inputs the
// state is a start like any other when the residuals look like white noise, and a smooth misfit
// of a window whose fourth differences are inflated by fast motion is still refused.
TEST(PositionsState, ADrivenWarmUpAtRestIsAStartWhenItsResidualsAreNoise) {
  Rng rng(4, "state-rest");
  const Index n = 100;
  Matrix q(1, n);
  for (Index k = 0; k < n; ++k) q(0, k) = 0.01 * rng.normal();
  const Vector z = Vector::Zero(2);
  const Matrix at_rest = -q;  // the fitted motion is rest: the residuals are the noise
  const double rms = std::sqrt(at_rest.squaredNorm() / static_cast<double>(n));
  const std::string free_why = refusal([&] { check_state_fit(q, z, rms, "w"); });
  EXPECT_NE(free_why.find("does not explain"), std::string::npos) << free_why;
  EXPECT_EQ(refusal([&] { check_state_fit(q, z, rms, "w", &at_rest); }), "");
  // Twice the noise left unexplained is refused, white or not.
  const Matrix twice = 2.0 * at_rest;
  EXPECT_NE(refusal([&] { check_state_fit(q, z, 2.0 * rms, "w", &twice); }), "");
  // Fast motion (a zigzag at the sampling rate) makes the positions' fourth differences large;
  // a smooth misfit of it is not noise and is refused.
  Matrix zigzag(1, 40), smooth(1, 40);
  for (Index k = 0; k < 40; ++k) {
    zigzag(0, k) = k % 2 == 0 ? 1.0 : -1.0;
    smooth(0, k) = 0.9 * std::sin(0.05 * static_cast<double>(k));
  }
  const double smooth_rms = std::sqrt(smooth.squaredNorm() / 40.0);
  EXPECT_GT(smooth_rms, 0.5);  // beyond the cap, within 1.5 times the zigzag's "noise"
  EXPECT_NE(refusal([&] { check_state_fit(zigzag, z, smooth_rms, "w", &smooth); }), "");
}

}  // namespace
}  // namespace csympnet
