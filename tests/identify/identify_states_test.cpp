// The whole-record fit of records with momenta (identify_states.cpp, --record-fit whole): the
// noise weights it estimates per row against the noise the record was given, its interval
// against the windows' on the same record, its coverage over independent records, and the
// linking's skips of lengths the model already follows.
#include <cmath>
#include <iostream>
#include <vector>

#include <gtest/gtest.h>

#include "csympnet/core/rng.hpp"
#include "csympnet/identify/identify.hpp"

namespace csympnet {
namespace {

// A damped linear oscillator, q'' = −q − γ q' (H = p²/2 + q²/2, p = q'), from q = 1, p = 0:
// `n` samples at step h, Gaussian noise σ_q on q and σ_p on p.
std::vector<Trajectory> decay_record(double gamma, Index n, double h, double sigma_q,
                                     double sigma_p, std::uint64_t seed) {
  Rng rng(seed, "identify-states-test");
  const double w = std::sqrt(1.0 - 0.25 * gamma * gamma);
  Trajectory t;
  t.t.resize(n);
  t.z.resize(2, n);
  for (Index k = 0; k < n; ++k) {
    const double s = h * static_cast<double>(k), e = std::exp(-0.5 * gamma * s);
    const double q = e * (std::cos(w * s) + 0.5 * gamma / w * std::sin(w * s));
    const double p = -e * std::sin(w * s) / w;
    t.t(k) = s;
    t.z(0, k) = q + sigma_q * rng.normal();
    t.z(1, k) = p + sigma_p * rng.normal();
  }
  return {t};
}

IdentifyConfig harmonic(const std::string& record_fit) {
  IdentifyConfig c;
  c.core = {{"type", "library"}, {"terms", {"q1^2"}}};
  c.record_fit = record_fit;
  return c;
}

// The momenta are four times as noisy as the positions: the weights follow (within 15%), the
// interval covers, and over the whole record it is at least ten times as narrow as the
// windows' (65 times when written).
TEST(IdentifyStates, WeightsFollowEachRowsNoiseAndTheWholeRecordNarrowsTheInterval) {
  const double gamma = 0.05;
  const auto data = decay_record(gamma, 1200, 0.1, 2e-3, 8e-3, 1);
  const IdentifyResult whole = identify(data, false, harmonic("whole"));
  const IdentifyResult windows = identify(data, false, harmonic("windows"));
  ASSERT_TRUE(whole.interval && windows.interval);
  ASSERT_TRUE(whole.choices.contains("whole_record"));
  EXPECT_FALSE(windows.choices.contains("whole_record"));
  const nlohmann::json& rec = whole.choices["whole_record"];
  const std::vector<double> noise = rec.at("row_noise").get<std::vector<double>>();
  ASSERT_EQ(noise.size(), 2u);
  // In the fit's units each row's noise is divided by its scale.
  const Vector unit = whole.normalization.unit();
  const double expected = (8e-3 / unit(1)) / (2e-3 / unit(0));
  EXPECT_NEAR(noise[1] / noise[0], expected, 0.15 * expected);
  EXPECT_TRUE(rec.at("linking").at("linked_fully").get<bool>());
  EXPECT_LE(whole.interval->low, gamma);
  EXPECT_GE(whole.interval->high, gamma);
  const double w_whole = whole.interval->high - whole.interval->low;
  const double w_windows = windows.interval->high - windows.interval->low;
  std::cout << "  widths: whole record " << w_whole << ", windows " << w_windows << "\n";
  EXPECT_LE(10.0 * w_whole, w_windows);
  EXPECT_TRUE(whole.identified);
}

// 30 independent records (600 samples, 10 periods, noise 1% on q and 2% on p): a 95% interval
// misses about 1.5 of them; 30 draws give 0.95 ± 0.040 (one sd).
TEST(IdentifyStates, WholeRecordIntervalCoversAtAboutItsLevel) {
  const double gamma = 0.08;
  int covered = 0, identified = 0;
  const int n = 30;
  for (int s = 0; s < n; ++s) {
    const IdentifyResult r =
        identify(decay_record(gamma, 600, 0.1, 1e-2, 2e-2, 100 + s), false, harmonic("whole"));
    ASSERT_TRUE(r.interval.has_value());
    covered += r.interval->low <= gamma && gamma <= r.interval->high;
    identified += r.identified;
  }
  std::cout << "  whole record: coverage " << covered << " / " << n << ", identified " << identified
            << "\n";
  EXPECT_GE(covered, 25);  // ≥ 0.833: more than 2.9 sd below 0.95 fails
  EXPECT_GE(identified, 28);
}

// 6,000 samples of the oscillator (60 periods, noise 0.1%): the model that the windows fitted
// already follows the positions over segments many times longer than the first ones, so the
// linking skips lengths (a stage records the length it skipped from), links the record fully,
// and its interval covers. With the wrong force law (a harmonic core on a stiff Duffing record)
// the rollouts drift off at once and nothing is skipped.
TEST(IdentifyStates, TheLinkingSkipsOnlyLengthsTheModelAlreadyFollows) {
  const double gamma = 0.01;
  const IdentifyResult r =
      identify(decay_record(gamma, 6000, 0.1, 1e-3, 1e-3, 3), false, harmonic("whole"));
  ASSERT_TRUE(r.interval.has_value());
  const nlohmann::json& link = r.choices.at("whole_record").at("linking");
  EXPECT_TRUE(link.at("linked_fully").get<bool>()) << link.dump(1);
  int skips = 0;
  for (const auto& stage : link.at("stages"))
    if (stage.contains("skipped_to_from")) {
      ++skips;
      EXPECT_GT(stage["positions_per_segment"].get<long>(), stage["skipped_to_from"].get<long>());
    }
  EXPECT_GE(skips, 1) << link.dump(1);
  EXPECT_LE(r.interval->low, gamma);
  EXPECT_GE(r.interval->high, gamma);

  // q'' = −q − 2q³ − γq', from q = 1.5: a harmonic core cannot follow it far.
  Trajectory t;
  const Index n = 3000;
  const double h = 0.1, dt = h / 100.0;
  t.t = Vector::LinSpaced(n, 0.0, h * static_cast<double>(n - 1));
  t.z.resize(2, n);
  double q = 1.5, p = 0.0;
  Rng rng(4, "identify-states-duffing");
  const auto acc = [gamma](double x, double v) { return -x - 2.0 * x * x * x - gamma * v; };
  for (Index k = 0; k < n; ++k) {
    t.z(0, k) = q + 1e-3 * rng.normal();
    t.z(1, k) = p + 1e-3 * rng.normal();
    for (int s = 0; s < 100; ++s) {
      const double a1 = p, b1 = acc(q, p);
      const double a2 = p + 0.5 * dt * b1, b2 = acc(q + 0.5 * dt * a1, a2);
      const double a3 = p + 0.5 * dt * b2, b3 = acc(q + 0.5 * dt * a2, a3);
      const double a4 = p + dt * b3, b4 = acc(q + dt * a3, a4);
      q += dt / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
      p += dt / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4);
    }
  }
  const IdentifyResult wrong = identify({t}, false, harmonic("whole"));
  ASSERT_TRUE(wrong.choices.contains("whole_record")) << wrong.choices.dump();
  for (const auto& stage : wrong.choices["whole_record"]["linking"]["stages"])
    EXPECT_FALSE(stage.contains("skipped_to_from")) << stage.dump();
}

}  // namespace
}  // namespace csympnet
