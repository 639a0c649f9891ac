// A richer force law where the linked chain breaks (src/identify/identify_force_law.cpp): a
// pendulum's positions at 85 samples per period, where the velocity start's one-step residuals
// hardly see the force's anharmonic part, end with an anharmonic force law and a covering
// interval; the linking then spans the record. (With every core a candidate, the positions
// floor test sees the harmonic library's misfit and trains the neural cores too.)
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "csympnet/core/rng.hpp"
#include "csympnet/identify/identify.hpp"
#include "csympnet/models/model.hpp"
#include "oversampled_pendulum.hpp"

namespace csympnet {
namespace {

TEST(IdentifyForceLaw, AnOversampledPendulumGetsItsAnharmonicForceFromTheChain) {
  // V = -cos q, unit mass, γ = 0.02, amplitude 0.6 rad, by the library map at 8 substeps of
  // order 6 (far below the noise).
  const double gamma = 0.02;
  const Trajectory t = oversampled_pendulum(gamma);
  // The library core alone (`--core library`): its terms selected, no neural candidates.
  IdentifyConfig c;
  c.core = {{"type", "library"}};
  const IdentifyResult r = identify_positions({t}, c);
  ASSERT_TRUE(r.identified) << r.verdict;
  EXPECT_LE(r.interval->low, gamma);
  EXPECT_GE(r.interval->high, gamma);
  const std::vector<std::string> terms = r.choices["core"].at("terms");
  const auto has = [&terms](const char* x) {
    return std::find(terms.begin(), terms.end(), x) != terms.end();
  };
  EXPECT_TRUE(has("q1^4") || has("cos(q1)")) << r.choices["core"].dump();
  const nlohmann::json& p = r.choices["positions"];
  EXPECT_TRUE(p.at("linking").at("linked_fully").get<bool>()) << p.at("linking").dump(1);
  // The velocity start left the force harmonic, and the chain added to it.
  const nlohmann::json& rounds = p.at("force_law_on_chain");
  ASSERT_FALSE(rounds.empty()) << p.dump(1);
  bool added = false;
  for (const auto& x : rounds.at(0).at("trials")) added = added || x.contains("dropped");
  EXPECT_TRUE(added) << rounds.dump(1);
}

}  // namespace
}  // namespace csympnet
