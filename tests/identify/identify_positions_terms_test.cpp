// The library core's terms judged on segments of the positions (src/identify/
// identify_positions_terms.cpp, used by the positions floor test): on a Duffing record the
// harmonic core gets the quartic force, on a linear record nothing is added at any of several
// noise draws, and end to end an oversampled pendulum whose velocity stage kept a harmonic
// force is fitted by the library core alone, its interval covering.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "../../src/identify/identify_positions.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/identify/identify.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/models/model.hpp"
#include "oversampled_pendulum.hpp"

namespace csympnet::detail {
namespace {

Candidate library(const std::vector<std::string>& terms) {
  Candidate c;
  c.core = {{"type", "library"}, {"terms", terms}, {"substeps", 2}};
  c.inner = make_model({{"type", "csympnet"}, {"d", 1}, {"core", c.core}, {"beta_init", 0.1}});
  c.theta = Vector::Zero(c.inner.n_params());
  return c;
}

// A damped 1-dof record by the library map with `terms` (coefficients `coef`, W = 1) at 8
// substeps: blocks of 200 samples whose rows are the noisy positions and the true momenta
// with 5% noise (the velocity start's role).
std::vector<Trajectory> record(const std::vector<std::string>& terms,
                               const std::vector<double>& coef, double gamma, double noise,
                               std::uint64_t seed) {
  const nlohmann::json core = {
      {"type", "library"}, {"terms", terms}, {"order", 6}, {"substeps", 8}};
  const Model truth =
      make_model({{"type", "csympnet"}, {"d", 1}, {"core", core}, {"beta_init", 0.1}});
  Vector theta = Vector::Zero(truth.n_params());
  theta(0) = 1.0;
  for (std::size_t k = 0; k < coef.size(); ++k) theta(1 + static_cast<Index>(k)) = coef[k];
  theta(1 + static_cast<Index>(coef.size())) = gamma;
  const double h = 0.1;
  const int n = 1600;
  Matrix z(2, n);
  z.col(0) << 1.2, 0.0;
  const Vector step = Vector::Constant(1, h);
  for (int k = 1; k < n; ++k) z.col(k) = truth.map->forward(theta, z.col(k - 1), step, nullptr);
  Rng rng(seed, "positions-terms");
  std::vector<Trajectory> blocks;
  for (int b = 0; b + 200 <= n; b += 200) {
    Trajectory t;
    t.t = Vector::LinSpaced(200, h * b, h * (b + 199));
    t.z = z.middleCols(b, 200);
    t.z.row(0) += noise * rng.normal_matrix(1, 200, 1.0);
    t.z.row(1) += 0.05 * rng.normal_matrix(1, 200, 1.0);
    blocks.push_back(t);
  }
  return blocks;
}

ShootingOptions options() {
  ShootingOptions opt;
  opt.iterations = kPositionsLmIterations;
  opt.patience = 20;
  opt.max_abs_state = kMaxAbsState;
  opt.converged_chi2 = 1e-3;
  opt.converged_se = kDampingConvergedSe;
  return opt;
}

// The harmonic core fitted to 40-position segments of the training blocks (all but the last),
// then its terms judged there.
TermsOnSegments judged(const std::vector<Trajectory>& blocks) {
  Candidate c = library({"q1", "q1^2"});
  c.theta(0) = 1.0;
  c.theta(2) = 0.5;
  c.theta(3) = 0.05;
  const std::vector<Trajectory> train(blocks.begin(), blocks.end() - 1);
  const std::vector<Trajectory> val(blocks.end() - 1, blocks.end());
  ShootingOptions opt = options();
  opt.n_free = free_parameters(*c.inner.map, 1);
  const SegmentFit start = fit_segments(*c.inner.map, c.theta, cut_segments(train, 1, 40),
                                        cut_segments(val, 1, 40), opt);
  Matrix q(1, 0);
  for (const Trajectory& t : train) {
    q.conservativeResize(1, q.cols() + t.z.cols());
    q.rightCols(t.z.cols()) = t.z.topRows(1);
  }
  TermsOnSegments out = terms_on_segments(c, start, 1, q, opt);
  EXPECT_LE(out.fit.rep.final_loss, start.rep.final_loss);
  return out;
}

TEST(PositionsTerms, AHarmonicCoreOnADuffingRecordGetsItsQuartic) {
  // V = q²/2 + q⁴/4 at 1.2 of amplitude: the quartic force is 70% of the linear one there.
  const TermsOnSegments t = judged(record({"q1^2", "q1^4"}, {0.5, 0.25}, 0.03, 0.01, 7));
  ASSERT_TRUE(t.changed) << t.trials.dump(1);
  const std::vector<std::string> terms = t.lib.core.at("terms");
  EXPECT_TRUE(std::find(terms.begin(), terms.end(), "q1^4") != terms.end() ||
              std::find(terms.begin(), terms.end(), "cos(q1)") != terms.end())
      << t.lib.core.dump();
  const double gamma = t.lib.inner.map->damping_rate(t.lib.theta).value();
  EXPECT_NEAR(gamma, 0.03, 0.003);
}

TEST(PositionsTerms, NothingIsAddedToAHarmonicCoreOnALinearRecord) {
  // The criterion's penalty, log n per parameter, makes a false addition of two parameters a
  // chance of about 1e-3 per draw: none in 6.
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    const TermsOnSegments t = judged(record({"q1^2"}, {0.5}, 0.03, 0.01, seed));
    EXPECT_FALSE(t.changed) << "seed " << seed << ": " << t.trials.dump(1);
    EXPECT_EQ(t.lib.core.at("terms"), nlohmann::json({"q1", "q1^2"}));
  }
}

}  // namespace
}  // namespace csympnet::detail

namespace csympnet {
namespace {

TEST(PositionsTerms, AnOversampledPendulumIsFittedByTheLibraryAloneFromPositions) {
  // The record of IdentifyForceLaw (V = -cos q, γ = 0.02, 0.6 rad, 85 samples per period), fitted
  // with every core a candidate: the velocity stage keeps a harmonic force, the floor test's
  // segments see its misfit, and the terms judged there leave noise, so no neural core is trained.
  const double gamma = 0.02;
  const Trajectory t = oversampled_pendulum(gamma);
  const IdentifyResult r = identify_positions({t}, IdentifyConfig{});
  ASSERT_TRUE(r.identified) << r.verdict;
  EXPECT_LE(r.interval->low, gamma);
  EXPECT_GE(r.interval->high, gamma);
  EXPECT_EQ(r.choices["core"].value("type", ""), "library") << r.choices["core"].dump();
  const nlohmann::json& lib = r.choices.at("library");
  ASSERT_TRUE(lib.contains("terms_on_positions")) << lib.dump(1);
  EXPECT_TRUE(lib["terms_on_positions"].at("adopted").get<bool>()) << lib.dump(1);
  // The library alone was a candidate: no neural core was trained.
  ASSERT_TRUE(r.choices.contains("core_candidates")) << r.choices.dump(1);
  EXPECT_EQ(r.choices["core_candidates"].size(), 1u) << r.choices["core_candidates"].dump(1);
}

}  // namespace
}  // namespace csympnet
