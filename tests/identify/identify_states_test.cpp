// The whole-record fit of records with momenta (identify_states.cpp, --record-fit whole): the
// noise weights it estimates per row against the noise the record was given, its interval
// against the windows' on the same record, and its coverage over independent records.
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

}  // namespace
}  // namespace csympnet
