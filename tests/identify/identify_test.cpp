// identify() (`csympnet fit`'s recipe) on data no preset resembles: unit and offset
// invariance as a property over scalings from 1e-6 to 1e6, "not identified" where the data
// cannot tell, and the coverage of its 95% interval over many noisy data sets. Small budgets;
// experiments/identification_benchmark.py measures the defaults.
#include "csympnet/identify/identify.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

#include "csympnet/core/rng.hpp"
#include "csympnet/integrators/reference.hpp"
#include "csympnet/systems/system.hpp"

namespace csympnet {
namespace {

// Damped linear chain (exact flow: expm), `trajs` trajectories of `points` samples at
// irregular steps h ~ U[0.06, 0.14], relative noise sigma of each coordinate's spread.
std::vector<Trajectory> chain_data(int d, double gamma, int trajs, int points, double sigma,
                                   std::uint64_t seed) {
  SystemSpec spec;
  spec.kind = d == 1 ? "oscillator" : "chain";
  spec.d = d;
  spec.gamma = gamma;
  const System sys(spec);
  Rng rng(seed, "identify-test");
  std::vector<Trajectory> out;
  for (int m = 0; m < trajs; ++m) {
    Trajectory t;
    t.t.resize(points);
    t.z.resize(2 * d, points);
    t.t(0) = 0.0;
    t.z.col(0) = rng.uniform_vector(2 * d, -1.0, 1.0);
    for (int k = 1; k < points; ++k) {
      const double h = rng.uniform(0.06, 0.14);
      t.t(k) = t.t(k - 1) + h;
      t.z.col(k) = expm_propagator(sys, h) * t.z.col(k - 1);
    }
    out.push_back(t);
  }
  if (sigma > 0.0) {
    for (Trajectory& t : out) {
      for (Index i = 0; i < t.z.rows(); ++i) {
        const double sd = std::sqrt((t.z.row(i).array() - t.z.row(i).mean()).square().mean());
        for (Index k = 0; k < t.z.cols(); ++k) t.z(i, k) += sigma * sd * rng.normal();
      }
    }
  }
  return out;
}

IdentifyConfig small_budget() {
  IdentifyConfig c;
  c.epochs = 1500;
  c.lm_iterations = 40;
  c.core = {{"type", "la"}, {"layers", 3}, {"sublayers", 6}};
  return c;
}

TEST(Identify, UnitsOffsetsAndTimeScaleDoNotChangeTheAnswer) {
  const auto base = chain_data(2, 0.08, 1, 240, 1e-3, 1);
  const IdentifyConfig c = small_budget();
  const IdentifyResult ref = identify(base, false, c);
  ASSERT_TRUE(ref.interval.has_value());
  const double width = ref.interval->high - ref.interval->low;
  for (double kq : {1e-6, 1e-2, 57.29577951308232, 1e6})
    for (double kp : {1e-6, 1e3, 1e6})
      for (double tc : {1e-3, 1.0, 1e2}) {
        if (kq != kp && tc == 1.0 && kq > 1e3) continue;  // keep the grid at 30 fits
        auto scaled = base;
        for (Trajectory& t : scaled) {
          t.z.topRows(2) = (t.z.topRows(2) * kq).array() + 250.0 * kq;
          t.z.bottomRows(2) *= kp;
          t.t = t.t * tc;
        }
        const IdentifyResult r = identify(scaled, false, c);
        ASSERT_TRUE(r.interval.has_value());
        // γ in the file's time units is γ/tc; rounding of the rescaled data is amplified by
        // training, so "the same" means far below the interval's own width.
        const double g = r.gamma * tc;
        EXPECT_LE(std::abs(g - ref.gamma), 1e-5 * width) << kq << " " << kp << " " << tc;
        EXPECT_LE(std::abs(r.interval->low * tc - ref.interval->low), 1e-4 * width);
        EXPECT_LE(std::abs(r.interval->high * tc - ref.interval->high), 1e-4 * width);
        EXPECT_EQ(r.identified, ref.identified);
      }
}

// Positions alone at regular steps (a camera's frames), the same record with its clock in s
// and in ms: one answer. The local velocities' window reaches a whole number of steps, and a
// sample exactly that far away was inside in ms (200) and outside in s (0.2 became
// 0.19999999999999907): the two took different paths, and the ms fit gave a wrong mode.
TEST(Identify, PositionsInSecondsAndMillisecondsGiveOneAnswer) {
  SystemSpec spec;
  spec.kind = "chain";
  spec.d = 2;
  spec.gamma = 0.12;
  const System sys(spec);
  Rng rng(5, "positions-clock");
  Trajectory t;
  const int n = 800;
  const double h = 0.04;
  t.t.resize(n);
  Matrix z(4, n);
  z.col(0) << 1.0, -0.4, 0.0, 0.3;
  const Matrix step = expm_propagator(sys, h);
  for (int k = 0; k < n; ++k) {
    t.t(k) = h * k;
    if (k > 0) z.col(k) = step * z.col(k - 1);
  }
  t.z = z.topRows(2) + 2e-3 * rng.normal_matrix(2, n, 1.0);
  Trajectory ms = t;
  ms.t = t.t * 1000.0;
  const IdentifyConfig c;
  const IdentifyResult a = identify_positions({t}, c);
  const IdentifyResult b = identify_positions({ms}, c);
  ASSERT_TRUE(a.interval.has_value() && b.interval.has_value());
  EXPECT_EQ(a.choices["core"].value("terms", nlohmann::json()),
            b.choices["core"].value("terms", nlohmann::json()));
  const double width = a.interval->high - a.interval->low;
  EXPECT_LE(std::abs(b.gamma * 1000.0 - a.gamma), 1e-6 * width);
  ASSERT_EQ(a.modes.size(), b.modes.size());
  for (std::size_t k = 0; k < a.modes.size(); ++k)
    EXPECT_NEAR(b.modes[k].frequency * 1000.0, a.modes[k].frequency, 1e-6 * a.modes[k].frequency);
  EXPECT_LE(a.interval->low, 0.12);
  EXPECT_GE(a.interval->high, 0.12);
}

// Positions alone: the neural cores are trained only where the library core, fitted to the
// positions, leaves smooth structure in them (positions_floor). A linear chain at 0.2% noise
// leaves white residuals; V = ½‖q‖² + α(q1 + q2)³ (α = 0.2, below its barrier) has products
// q1²q2 the library lacks, and at
// 0.2% noise its misfit shows.
TEST(Identify, PositionsTrainNeuralCoresOnlyWhereTheLibraryLeavesStructure) {
  const auto record = [](const std::string& kind, std::uint64_t seed) {
    SystemSpec spec;
    spec.kind = kind;
    spec.d = 2;
    spec.gamma = 0.05;
    spec.alpha = 0.2;
    const System sys(spec);
    Rng rng(seed, "positions-floor");
    const int n = 1000;
    const double h = 0.1;
    Trajectory t;
    t.t = Vector::LinSpaced(n, 0.0, h * (n - 1));
    Matrix z(4, n);
    z.col(0) << 0.2, -0.1, 0.05, 0.15;
    for (int k = 1; k < n; ++k) z.col(k) = conformal_sv_flow(sys, z.col(k - 1), h, 1e-3);
    t.z = z.topRows(2);
    for (Index i = 0; i < 2; ++i) {
      const double sd = std::sqrt((t.z.row(i).array() - t.z.row(i).mean()).square().mean());
      t.z.row(i) += 2e-3 * sd * rng.normal_matrix(1, n, 1.0);
    }
    return std::vector<Trajectory>{t};
  };
  const IdentifyConfig c;
  const IdentifyResult lin = identify_positions(record("chain", 1), c);
  const std::string lin_floor = lin.choices["library"]["floor"];
  EXPECT_NE(lin_floor.find("not trained"), std::string::npos) << lin_floor;
  EXPECT_EQ(lin.choices["core"].value("type", ""), "library");
  // The velocity start's drag on this viscous record is judged on the positions and dropped.
  EXPECT_FALSE(lin.choices["core"].contains("dissipation")) << lin.choices["core"].dump();
  // The decision comes before any neural training: small budgets for what follows it.
  IdentifyConfig quick;
  quick.epochs = 200;
  quick.lm_iterations = 10;
  const IdentifyResult cubic = identify_positions(record("cubic", 2), quick);
  const std::string cubic_floor = cubic.choices["library"]["floor"];
  EXPECT_NE(cubic_floor.find("trained too"), std::string::npos) << cubic_floor;
  std::cout << "  " << lin_floor << "\n  " << cubic_floor << "\n";
}

TEST(Identify, SaysNotIdentifiedWithoutDampingOrDynamics) {
  const IdentifyConfig c = small_budget();
  // No damping, noisy: the interval must reach 0.
  const IdentifyResult undamped = identify(chain_data(1, 0.0, 1, 200, 1e-2, 2), false, c);
  EXPECT_FALSE(undamped.identified);
  ASSERT_FALSE(undamped.reasons.empty());
  // Pure noise: nothing to explain.
  Rng rng(3, "noise");
  std::vector<Trajectory> noise(1);
  noise[0].z = rng.normal_matrix(2, 200, 1.0);
  noise[0].t = Vector::LinSpaced(200, 0.0, 19.9);
  const IdentifyResult r = identify(noise, false, c);
  EXPECT_FALSE(r.identified);
  const nlohmann::json rep = identify_report(r);
  EXPECT_EQ(rep["identified"], false);
  EXPECT_TRUE(rep["not_identified_reason"].is_string());
}

TEST(Identify, IntervalNeverHasZeroWidthAndContainsTheEstimate) {
  // Clean data of a linear system: an almost exact fit.
  const IdentifyResult r = identify(chain_data(1, 0.05, 12, 30, 0.0, 4), false, small_budget());
  ASSERT_TRUE(r.interval.has_value());
  EXPECT_LT(r.interval->low, r.gamma);
  EXPECT_GT(r.interval->high, r.gamma);
  EXPECT_TRUE(r.identified) << (r.reasons.empty() ? "" : r.reasons.front());
  EXPECT_LT(std::abs(r.gamma - 0.05), 1e-3);
}

// A free chain of two masses (springs k = 1 between them only): one oscillating mode at
// ω = √(2k), and the translation, which does not oscillate and whose equilibria form a line:
// the mode is found with its frequency and ζ = γ̂/(2ω), and the note says one mode is missing.
TEST(Identify, ModesOfAFreeChainSkipTheTranslation) {
  const IdentifyResult r = identify(chain_data(2, 0.08, 1, 240, 1e-3, 1), false, small_budget());
  ASSERT_EQ(r.modes.size(), 1u) << r.modes_note;
  EXPECT_NEAR(r.modes[0].frequency, std::sqrt(2.0), 0.02);
  EXPECT_NEAR(r.modes[0].damping_ratio, r.gamma / (2.0 * r.modes[0].frequency),
              1e-9 * r.modes[0].damping_ratio);
  EXPECT_NE(r.modes_note.find("1 of the 2 modes do not oscillate"), std::string::npos)
      << r.modes_note;
  if (r.identified) {
    ASSERT_TRUE(r.modes[0].frequency_interval.has_value());
    EXPECT_LT(r.modes[0].frequency_interval->low, r.modes[0].frequency);
    EXPECT_GT(r.modes[0].frequency_interval->high, r.modes[0].frequency);
  }
}

TEST(Identify, IntervalCoversAtAboutItsLevel) {
  // 60 independent noisy data sets (σ = 1e-2, one trajectory of 150 samples each): a 95%
  // interval misses about 3 of them; 60 draws give 0.95 ± 0.028 (one sd).
  // The same fits' mode (ω = 1, ζ = γ / 2 = 0.05): its frequency and damping ratio intervals,
  // from the same sandwich, must cover as often.
  const IdentifyConfig c = small_budget();
  int covered = 0, identified = 0, freq_covered = 0, ratio_covered = 0, with_mode = 0;
  const int n = 60;
  double worst = 0.0;
  std::vector<double> z;  // (γ̂ − γ) / standard error: about N(0, 1) for a calibrated interval
  for (int s = 0; s < n; ++s) {
    const double gamma = 0.1;
    const IdentifyResult r = identify(chain_data(1, gamma, 1, 150, 1e-2, 100 + s), false, c);
    ASSERT_TRUE(r.interval.has_value());
    if (r.modes.size() == 1 && r.modes[0].frequency_interval && r.modes[0].damping_ratio_interval) {
      ++with_mode;
      const Mode& m = r.modes[0];
      freq_covered += m.frequency_interval->low <= 1.0 && 1.0 <= m.frequency_interval->high;
      ratio_covered +=
          m.damping_ratio_interval->low <= 0.05 && 0.05 <= m.damping_ratio_interval->high;
      EXPECT_NEAR(m.damping_ratio, r.gamma / (2.0 * m.frequency), 1e-9 * m.damping_ratio);
    }
    covered += r.interval->low <= gamma && gamma <= r.interval->high;
    identified += r.identified;
    worst = std::max(worst, std::abs(r.gamma - gamma) / gamma);
    z.push_back((r.gamma - gamma) / r.interval->std_error);
  }
  double mean = 0.0, sq = 0.0;
  for (double v : z) mean += v / n;
  for (double v : z) sq += (v - mean) * (v - mean) / (n - 1);
  std::cout << "  standardised errors: mean " << mean << ", sd " << std::sqrt(sq) << "\n";
  std::cout << "  coverage " << covered << " / " << n << ", identified " << identified
            << ", worst relative error " << worst << "\n";
  EXPECT_GE(covered, 52);  // ≥ 0.867: more than 2.9 sd below 0.95 fails
  EXPECT_LE(covered, 60);
  EXPECT_GE(identified, 55);
  std::cout << "  mode: " << with_mode << " with intervals; frequency covered " << freq_covered
            << ", damping ratio covered " << ratio_covered << "\n";
  EXPECT_EQ(with_mode, n);
  EXPECT_GE(freq_covered, 52);
  EXPECT_GE(ratio_covered, 52);
}

// Positions alone (identify_positions: the momenta hidden states): 30 independent records of
// 300 positions (σ = 1e-2, about 31 samples per period), the momenta rows dropped. A 95%
// interval misses about 1.5 of them; 30 draws give 0.95 ± 0.040 (one sd).
TEST(Identify, PositionsAloneIntervalCoversAtAboutItsLevel) {
  IdentifyConfig c = small_budget();
  int covered = 0, identified = 0;
  const int n = 30;
  const double gamma = 0.1;
  std::vector<double> z;
  for (int s = 0; s < n; ++s) {
    std::vector<Trajectory> data = chain_data(1, gamma, 1, 300, 1e-2, 700 + s);
    for (Trajectory& t : data) t.z = Matrix(t.z.topRows(1));
    const IdentifyResult r = identify_positions(data, c);
    EXPECT_EQ(r.observed, "positions");
    if (!r.interval) continue;
    covered += r.interval->low <= gamma && gamma <= r.interval->high;
    identified += r.identified;
    z.push_back((r.gamma - gamma) / r.interval->std_error);
  }
  double mean = 0.0, sq = 0.0;
  for (double v : z) mean += v / static_cast<double>(z.size());
  for (double v : z) sq += (v - mean) * (v - mean) / static_cast<double>(z.size() - 1);
  std::cout << "  positions alone: coverage " << covered << " / " << n << ", identified "
            << identified << ", standardised errors mean " << mean << ", sd " << std::sqrt(sq)
            << "\n";
  EXPECT_EQ(z.size(), static_cast<std::size_t>(n));
  EXPECT_GE(covered, 25);  // ≥ 0.833: more than 2.9 sd below 0.95 fails
  EXPECT_GE(identified, 25);
}

}  // namespace
}  // namespace csympnet

namespace csympnet {
namespace {

TEST(Identify, WindowsGrowOnlyWhenNoiseDominatesMisfit) {
  IdentifyConfig c;
  c.epochs = 800;
  c.lm_iterations = 20;
  c.core = {{"type", "la"}, {"layers", 3}, {"sublayers", 6}};
  const IdentifyResult noisy = identify(chain_data(1, 0.1, 1, 200, 5e-2, 7), false, c);
  EXPECT_EQ(noisy.config.window, 4);
  EXPECT_LT(noisy.choices["one_step_residual_lag1_correlation"].get<double>(), -0.2);
  // A pendulum-like misfit on clean data: the smooth residuals keep one-step windows.
  std::vector<Trajectory> clean(1);
  clean[0].t = Vector::LinSpaced(200, 0.0, 19.9);
  clean[0].z.resize(2, 200);
  Vector z(2);
  z << 2.5, 0.0;
  for (Index k = 0; k < 200; ++k) {
    clean[0].z.col(k) = z;
    for (int s = 0; s < 100; ++s) {  // symplectic Euler with friction, fine steps
      z(1) += 1e-3 * (-std::sin(z(0)) - 0.1 * z(1));
      z(0) += 1e-3 * z(1);
    }
  }
  const IdentifyResult smooth = identify(clean, false, c);
  EXPECT_EQ(smooth.config.window, 1);
  EXPECT_GT(smooth.choices["one_step_residual_lag1_correlation"].get<double>(), 0.0);
  // A given window is used as given.
  c.window = 2;
  EXPECT_EQ(identify(clean, false, c).config.window, 2);
}

// The core is chosen by validation loss between the library, an LA and a G candidate; the
// winner is the one reported and saved. The library core is fitted first, and where it
// explains the held-out data to the noise floor (a clean linear oscillator: its q^2 term is
// the exact force) the neural cores are not trained. On a pendulum integrated by a
// first-order scheme (symplectic Euler, steps of 1e-3: a map the library's composed Strang
// steps do not reproduce to the data's precision) all three are trained.
TEST(Identify, ChoosesTheCoreByValidationLoss) {
  IdentifyConfig c;
  c.epochs = 600;
  c.lm_iterations = 40;
  auto check = [](const IdentifyResult& r) {
    const auto& cands = r.choices["core_candidates"];
    std::size_t win = 0;
    for (std::size_t k = 1; k < cands.size(); ++k)
      if (cands[k]["val_loss"].get<double>() < cands[win]["val_loss"].get<double>()) win = k;
    EXPECT_EQ(r.choices["core"], cands[win]["core"]);
    EXPECT_EQ(r.config.core, cands[win]["core"]);
    EXPECT_EQ(r.model.hyperparams()["core"], cands[win]["core"]);
    return cands;
  };
  const IdentifyResult lin = identify(chain_data(1, 0.1, 4, 60, 0.0, 3), false, c);
  const auto lc = check(lin);
  ASSERT_EQ(lc.size(), 1u);
  EXPECT_EQ(lin.config.core["type"], "library");
  EXPECT_NE(lin.choices["core_reason"].get<std::string>().find("clean data explained"),
            std::string::npos)
      << lin.choices["core_reason"];
  EXPECT_LT(std::abs(lin.gamma - 0.1), 1e-9);

  std::vector<Trajectory> pend(4);
  for (int m = 0; m < 4; ++m) {
    Trajectory& t = pend[static_cast<std::size_t>(m)];
    t.t = Vector::LinSpaced(60, 0.0, 0.3 * 59);
    t.z.resize(2, 60);
    Vector z(2);
    z << 1.0 + 0.5 * m, 0.0;
    for (Index k = 0; k < 60; ++k) {
      t.z.col(k) = z;
      for (int s = 0; s < 300; ++s) {  // symplectic Euler with friction, fine steps
        z(1) += 1e-3 * (-std::sin(z(0)) - 0.05 * z(1));
        z(0) += 1e-3 * z(1);
      }
    }
  }
  const IdentifyResult pr = identify(pend, false, c);
  const auto pc = check(pr);
  EXPECT_EQ(pc.size(), 3u);
  EXPECT_EQ(pc[0]["core"]["type"], "library");
  EXPECT_NE(pr.choices["core_reason"].get<std::string>().find("lowest validation loss"),
            std::string::npos)
      << pr.choices["core_reason"];
  // A given core is used as given: no candidates.
  c.core = {{"type", "la"}, {"layers", 3}, {"sublayers", 6}};
  const IdentifyResult given = identify(pend, false, c);
  EXPECT_FALSE(given.choices.contains("core_candidates"));
  EXPECT_EQ(given.choices["core_reason"], "given");
  EXPECT_EQ(given.config.core, c.core);
}

}  // namespace
}  // namespace csympnet
