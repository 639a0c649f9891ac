// Dry friction and drag in `fit` (src/identify/identify_dissipation.cpp, the dissipation
// stage of identify_library.cpp; docs/identification.md, "Dry friction and drag"):
//   - a viscous + Coulomb oscillator: Coulomb friction is selected, γ and μ recovered in the
//     data's units, their intervals cover the truth, the report and sentence name both;
//   - a purely viscous oscillator: no friction term (no false friction), γ as before;
//   - a viscous + drag oscillator: drag is selected, c recovered;
//   - dissipation = "viscous" keeps γ alone; a forced term with an LA core is refused by name.
// The records are exact (tests/support/friction_oscillator.hpp: closed form between reversals
// for Coulomb, RK4 at 400 substeps for drag), independent of the map.
#include <cmath>
#include <iostream>
#include <numbers>

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "csympnet/core/options.hpp"
#include "csympnet/identify/identify.hpp"
#include "support/friction_oscillator.hpp"

namespace csympnet {
namespace {

using testing::friction_records;
using testing::FrictionOscillator;

const nlohmann::json* term_of(const nlohmann::json& report, const std::string& kind) {
  for (const auto& t : report["dissipation"]["terms"])
    if (t["kind"] == kind) return &t;
  return nullptr;
}

bool friction_covers(const nlohmann::json& t, double truth) {
  return !t["low"].is_null() && t["low"].get<double>() <= truth && truth <= t["high"].get<double>();
}

// Four decays from amplitudes 1 to 2, 30 s each at 10 samples per second (ω = 2: 31 samples
// a period), 0.2% noise.
std::vector<Trajectory> decays(const FrictionOscillator& o, std::uint64_t seed) {
  return friction_records(o, {{1.0, 0.0}, {-1.4, 0.5}, {2.0, 0.0}, {0.3, -2.4}}, 301, 0.1, 2e-3,
                          seed);
}

TEST(FrictionFit, ViscousAndCoulombAreBothIdentified) {
  FrictionOscillator o;
  o.omega = 2.0;
  o.gamma = 0.1;
  o.mu = 0.1;
  const IdentifyResult r = identify(decays(o, 1), false, IdentifyConfig{});
  const nlohmann::json rep = identify_report(r);
  std::cout << "  " << dissipation_sentence(r) << "\n";
  ASSERT_TRUE(r.identified) << nlohmann::json(r.reasons).dump();
  const nlohmann::json* mu = term_of(rep, "coulomb");
  ASSERT_NE(mu, nullptr) << rep["choices"]["library"]["dissipation"].dump();
  EXPECT_EQ(term_of(rep, "drag"), nullptr);
  EXPECT_LT(std::abs(r.gamma - o.gamma) / o.gamma, 0.05) << r.gamma;
  EXPECT_LT(std::abs((*mu)["value"].get<double>() - o.mu) / o.mu, 0.1) << mu->dump();
  EXPECT_TRUE(r.interval->low <= o.gamma && o.gamma <= r.interval->high)
      << r.interval->low << " " << r.interval->high;
  EXPECT_TRUE(friction_covers(*mu, o.mu)) << mu->dump();
  EXPECT_NE(dissipation_sentence(r).find("plus dry friction mu = "), std::string::npos);
  // The viscous term comes first, with γ̂'s own interval.
  const auto& first = rep["dissipation"]["terms"][0];
  EXPECT_EQ(first["kind"], "viscous");
  EXPECT_EQ(first["low"].get<double>(), r.interval->low);
  // The model file carries the term.
  EXPECT_EQ(r.model.hyperparams()["core"]["dissipation"], nlohmann::json({"coulomb(p1)"}));
}

TEST(FrictionFit, APurelyViscousRecordGetsNoFriction) {
  FrictionOscillator o;
  o.omega = 2.0;
  o.gamma = 0.1;
  const IdentifyResult r = identify(decays(o, 2), false, IdentifyConfig{});
  ASSERT_TRUE(r.identified) << nlohmann::json(r.reasons).dump();
  EXPECT_TRUE(r.dissipation.empty()) << r.dissipation.dump();
  EXPECT_LT(std::abs(r.gamma - o.gamma) / o.gamma, 0.02) << r.gamma;
  EXPECT_TRUE(r.interval->low <= o.gamma && o.gamma <= r.interval->high);
  EXPECT_NE(dissipation_sentence(r).find("no friction or drag term"), std::string::npos);
}

TEST(FrictionFit, DragIsIdentifiedAsDrag) {
  FrictionOscillator o;
  o.omega = 2.0;
  o.gamma = 0.05;
  o.drag = 0.15;
  const IdentifyResult r = identify(decays(o, 3), false, IdentifyConfig{});
  const nlohmann::json rep = identify_report(r);
  std::cout << "  " << dissipation_sentence(r) << "\n";
  ASSERT_TRUE(r.identified) << nlohmann::json(r.reasons).dump();
  const nlohmann::json* c = term_of(rep, "drag");
  ASSERT_NE(c, nullptr) << rep["choices"]["library"]["dissipation"].dump();
  EXPECT_EQ(term_of(rep, "coulomb"), nullptr);
  EXPECT_LT(std::abs((*c)["value"].get<double>() - o.drag) / o.drag, 0.1) << c->dump();
  EXPECT_TRUE(friction_covers(*c, o.drag)) << c->dump();
  EXPECT_LT(std::abs(r.gamma - o.gamma) / o.gamma, 0.1) << r.gamma;
}

TEST(FrictionFit, ViscousOnlyWhenAskedAndForcedTermsNeedTheLibraryCore) {
  FrictionOscillator o;
  o.omega = 2.0;
  o.gamma = 0.1;
  o.mu = 0.1;
  IdentifyConfig c;
  c.dissipation = "viscous";
  const IdentifyResult r = identify(decays(o, 4), false, c);
  EXPECT_TRUE(r.dissipation.empty());
  EXPECT_EQ(identify_report(r)["config"]["dissipation"], "viscous");
  // Without friction in the model, its amplitude dependence shows in the check.
  for (const ModelCheck& k : r.checks)
    if (k.name == "linear_damping" && k.applicable) {
      EXPECT_TRUE(!k.passed || k.warning) << k.sentence;
    }
  c.dissipation = "viscous+coulomb";
  c.core = {{"type", "la"}, {"layers", 2}, {"sublayers", 2}};
  try {
    identify(decays(o, 4), false, c);
    ADD_FAILURE() << "a forced Coulomb term with an LA core was accepted";
  } catch (const OptionError& e) {
    EXPECT_NE(std::string(e.what()).find("dissipation"), std::string::npos) << e.what();
  }
  EXPECT_THROW(make_identify_config({{"dissipation", "coulomb"}}), OptionError);
}

// A weakly damped oscillator read at 100 Hz, positions alone, with dry friction as strong as
// its viscous damping over the first decay. Over two decays of 20 s the amplitudes span too
// little for the amplitude check at the velocity start to see the friction: the fit used to
// fold it into γ̂ (2.4 times the truth, an interval that missed). Offered on the linked
// positions, the friction explains them and both rates are recovered; the viscous twin of the
// record gets none.
TEST(FrictionFit, DryFrictionTheVelocityStartMissesIsFoundOnThePositions) {
  for (const bool friction : {true, false}) {
    SCOPED_TRACE(friction ? "viscous + Coulomb" : "viscous only");
    FrictionOscillator o;
    o.omega = 4.0;
    o.gamma = 0.03;
    o.mu = friction ? std::numbers::pi * o.gamma * o.omega * 0.9 / 4.0 : 0.0;
    std::vector<Trajectory> positions =
        friction_records(o, {{0.9, 0.0}, {-0.7, 0.0}}, 2000, 0.01, 6e-3, 7);
    for (Trajectory& t : positions) t.z = Matrix(t.z.topRows(1));
    const IdentifyResult r = identify_positions(positions, IdentifyConfig{});
    const nlohmann::json rep = identify_report(r);
    std::cout << "  " << dissipation_sentence(r) << "\n";
    ASSERT_TRUE(r.identified) << nlohmann::json(r.reasons).dump();
    // Within two half-widths of the interval (about four standard errors) on this one record;
    // the coverage itself is measured over many records (docs/identification.md, "Dry
    // friction and drag": 12 of 12 such records covered γ, 11 of 12 μ).
    const double half = 0.5 * (r.interval->high - r.interval->low);
    EXPECT_LE(std::abs(r.gamma - o.gamma), 2.0 * half)
        << r.gamma << " [" << r.interval->low << ", " << r.interval->high << "]";
    const nlohmann::json& offered = rep["choices"]["positions"]["dissipation_added_on_positions"];
    ASSERT_TRUE(offered.is_object()) << rep["choices"]["positions"].dump();
    std::cout << "  score test: " << offered["score_test"].dump() << "\n";
    if (!friction) {
      EXPECT_TRUE(r.dissipation.empty()) << r.dissipation.dump();
      EXPECT_TRUE(offered["added"].is_null()) << offered.dump();
      continue;
    }
    EXPECT_FALSE(offered["added"].is_null()) << offered.dump();
    // The score test at zero rates let the trials run: its predicted gain reached a quarter of
    // what the group had to gain.
    EXPECT_GE(offered["score_test"]["predicted_gain"].get<double>(),
              0.25 * offered["score_test"]["needed_gain"].get<double>())
        << offered.dump();
    const nlohmann::json* mu = term_of(rep, "coulomb");
    ASSERT_NE(mu, nullptr) << offered.dump();
    const double mu_half = 0.5 * ((*mu)["high"].get<double>() - (*mu)["low"].get<double>());
    EXPECT_LE(std::abs((*mu)["value"].get<double>() - o.mu), 2.0 * mu_half) << mu->dump();
    EXPECT_LT(std::abs(r.gamma - o.gamma) / o.gamma, 0.25) << r.gamma;
    // Before, the friction was folded into γ̂: it is no longer.
    EXPECT_LT(r.gamma, 1.5 * o.gamma);
  }
}

}  // namespace
}  // namespace csympnet
