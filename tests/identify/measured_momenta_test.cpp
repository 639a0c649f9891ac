// The check that the momenta were measured (identify/model_checks.hpp,
// measured_momenta_check), on records of damped chains of pendulums:
//  - momenta computed from noisy positions by the filters users apply (numpy.gradient's
//    central differences at even and uneven steps, a five-point stencil, a Savitzky–Golay
//    derivative over 11 samples, any of them times a mass) are recognised in every record;
//  - measured momenta, with noise of their own, are not, over the same records;
//  - noise-free linear or finely sampled motion cannot tell them apart (untestable), nor can
//    pairs; computed momenta of noise-free positions at 20 samples per period fail.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "csympnet/core/rng.hpp"
#include "csympnet/identify/model_checks.hpp"
#include "csympnet/integrators/dopri5.hpp"

namespace csympnet {
namespace {

struct ChainCase {
  Index d = 1;
  double gamma = 0.1;
  bool linear = false;  // a harmonic chain instead of pendulums
};

// dq/dt = p, dp_i/dt = −ω_i² sin q_i − κ (2 q_i − q_{i−1} − q_{i+1}) − γ p_i.
Trajectory simulate(const ChainCase& c, Index points, bool uneven, Rng& rng,
                    double per_period = 20) {
  const Index d = c.d;
  Vector w2(d);
  for (Index i = 0; i < d; ++i) w2(i) = std::pow(1.0 + 0.3 * static_cast<double>(i), 2);
  const VectorField f = [&](const Vector& z, Vector& dz) {
    dz.resize(2 * d);
    dz.head(d) = z.tail(d);
    for (Index i = 0; i < d; ++i) {
      const double q = z(i);
      double force = -w2(i) * (c.linear ? q : std::sin(q)) - 0.2 * 2.0 * q;
      if (i > 0) force += 0.2 * z(i - 1);
      if (i + 1 < d) force += 0.2 * z(i + 1);
      dz(d + i) = force - c.gamma * z(d + i);
    }
  };
  const double h = 2.0 * M_PI / std::sqrt(w2(d - 1)) / per_period;  // of the fastest mode
  Trajectory t;
  t.t.resize(points);
  t.z.resize(2 * d, points);
  Vector z(2 * d);
  for (Index i = 0; i < 2 * d; ++i) z(i) = rng.uniform(-1.0, 1.0);
  OdeOptions opt;
  opt.rtol = 1e-11;
  opt.atol = 1e-13;
  t.t(0) = 0.0;
  t.z.col(0) = z;
  for (Index n = 1; n < points; ++n) {
    const double step = uneven ? h * rng.uniform(0.5, 1.5) : h;
    z = dopri5_flow(f, z, step, opt);
    t.t(n) = t.t(n - 1) + step;
    t.z.col(n) = z;
  }
  return t;
}

void add_noise(Trajectory& t, Index rows_from, Index rows, double sigma, Rng& rng) {
  for (Index i = rows_from; i < rows_from + rows; ++i) {
    const double sd = std::sqrt((t.z.row(i).array() - t.z.row(i).mean()).square().mean());
    for (Index j = 0; j < t.z.cols(); ++j) t.z(i, j) += sigma * sd * rng.normal();
  }
}

enum class Filter { kGradient, kFivePoint, kSavitzkyGolay11 };

// numpy.gradient(q, t): second-order central differences inside (any steps), first-order ones
// at the ends.
double gradient_at(const Vector& q, const Vector& t, Index n) {
  const Index last = q.size() - 1;
  if (n == 0) return (q(1) - q(0)) / (t(1) - t(0));
  if (n == last) return (q(last) - q(last - 1)) / (t(last) - t(last - 1));
  const double h0 = t(n) - t(n - 1), h1 = t(n + 1) - t(n);
  return (h0 * h0 * q(n + 1) - h1 * h1 * q(n - 1) + (h1 * h1 - h0 * h0) * q(n)) /
         (h0 * h1 * (h0 + h1));
}

// The momenta a user would compute: mass × filter(q) (even steps for the stencils).
void compute_momenta(Trajectory& t, Filter f, double mass) {
  const Index d = t.z.rows() / 2, n = t.t.size();
  const double h = t.t(1) - t.t(0);
  for (Index i = 0; i < d; ++i) {
    const Vector q = t.z.row(i).transpose();
    for (Index k = 0; k < n; ++k) {
      double v = gradient_at(q, t.t, k);
      if (f == Filter::kFivePoint && k >= 2 && k + 2 < n)
        v = (q(k - 2) - 8.0 * q(k - 1) + 8.0 * q(k + 1) - q(k + 2)) / (12.0 * h);
      if (f == Filter::kSavitzkyGolay11 && k >= 5 && k + 5 < n) {
        double s = 0.0;  // the derivative of a cubic (or quadratic) least-squares fit
        for (Index j = -5; j <= 5; ++j) s += static_cast<double>(j) * q(k + j);
        v = s / (110.0 * h);  // Σ j² over −5…5 = 110
      }
      t.z(d + i, k) = mass * v;
    }
  }
}

TEST(MeasuredMomenta, ComputedMomentaAreRecognisedAndMeasuredOnesAreNot) {
  const int records = 40;
  int measured_flagged = 0, computed_missed = 0, computed_cases = 0;
  for (int r = 0; r < records; ++r) {
    Rng rng(static_cast<std::uint64_t>(r), "measured-momenta");
    const ChainCase c{1 + r % 3, std::exp(rng.uniform(std::log(0.01), std::log(0.5))), false};
    const bool uneven = r % 4 == 3;
    const double sigma = std::vector<double>{1e-3, 1e-2, 5e-2}[static_cast<std::size_t>(r % 3)];
    const Trajectory clean = simulate(c, 400, uneven, rng);

    Trajectory measured = clean;
    add_noise(measured, 0, 2 * c.d, sigma, rng);
    const ModelCheck m = measured_momenta_check({measured}, false);
    EXPECT_TRUE(m.applicable) << "record " << r << ": " << m.sentence;
    if (!m.passed) ++measured_flagged;

    Trajectory noisy_q = clean;
    add_noise(noisy_q, 0, c.d, sigma, rng);
    for (Filter f : {Filter::kGradient, Filter::kFivePoint, Filter::kSavitzkyGolay11}) {
      if (uneven && f != Filter::kGradient) continue;  // the stencils assume even steps
      Trajectory computed = noisy_q;
      compute_momenta(computed, f, r % 2 == 0 ? 1.0 : 2.5);
      const ModelCheck k = measured_momenta_check({computed}, false);
      ++computed_cases;
      if (k.passed) {
        ++computed_missed;
        ADD_FAILURE() << "record " << r << " filter " << static_cast<int>(f) << ": " << k.sentence;
      } else {
        EXPECT_NE(k.sentence.find("computed from the positions"), std::string::npos);
      }
    }
  }
  EXPECT_EQ(measured_flagged, 0) << "of " << records;
  std::printf("measured momenta flagged: %d of %d; computed momenta missed: %d of %d\n",
              measured_flagged, records, computed_missed, computed_cases);
}

// Several trajectories of different steps pool into one regression (a filter's coefficients
// scale as 1/h).
TEST(MeasuredMomenta, TrajectoriesOfDifferentStepsArePooled) {
  Rng rng(5, "measured-momenta-pooled");
  std::vector<Trajectory> computed, measured;
  for (int k = 0; k < 5; ++k) {
    Trajectory t = simulate({2, 0.1, false}, 60, false, rng);
    t.t *= 1.0 + 0.4 * static_cast<double>(k);  // a different step per trajectory
    t.z.bottomRows(2) /= 1.0 + 0.4 * static_cast<double>(k);
    Trajectory m = t;
    add_noise(m, 0, 4, 1e-2, rng);
    measured.push_back(m);
    add_noise(t, 0, 2, 1e-2, rng);
    compute_momenta(t, Filter::kGradient, 1.0);
    computed.push_back(t);
  }
  EXPECT_FALSE(measured_momenta_check(computed, false).passed);
  const ModelCheck m = measured_momenta_check(measured, false);
  EXPECT_TRUE(m.applicable && m.passed) << m.sentence;
}

TEST(MeasuredMomenta, NoiseFreeLinearOrFineMotionAndPairsAreUntestable) {
  Rng rng(9, "measured-momenta-clean");
  const Trajectory linear = simulate({2, 0.1, true}, 300, false, rng);
  const ModelCheck l = measured_momenta_check({linear}, false);
  EXPECT_FALSE(l.applicable) << l.sentence;
  EXPECT_TRUE(l.passed);

  // Noise-free positions sampled finely (400 per period): a filter of 16 neighbours predicts
  // them to rounding, so measured and computed momenta cannot be told apart and no noise is
  // amplified: untestable. Sampled at 20 per period, what the neighbours miss is not told from
  // noise, and computed momenta fail (their difference's bias is real there); with positions
  // declared smooth (a threshold of 1), they pass with a note.
  Trajectory fine = simulate({1, 0.1, false}, 600, false, rng, 400);
  compute_momenta(fine, Filter::kGradient, 1.0);
  const ModelCheck f = measured_momenta_check({fine}, false);
  EXPECT_FALSE(f.applicable) << f.sentence;
  EXPECT_TRUE(f.passed);
  Trajectory coarse = simulate({1, 0.1, false}, 300, false, rng, 20);
  compute_momenta(coarse, Filter::kGradient, 1.0);
  EXPECT_FALSE(measured_momenta_check({coarse}, false).passed);
  CheckThresholds lenient;
  lenient.smooth_positions = 1.0;
  const ModelCheck s = measured_momenta_check({coarse}, false, lenient);
  EXPECT_TRUE(s.applicable && s.passed) << s.sentence;
  EXPECT_NE(s.sentence.find("look computed"), std::string::npos) << s.sentence;

  const ModelCheck p = measured_momenta_check({linear}, true);
  EXPECT_FALSE(p.applicable);
  const ModelCheck short_record =
      measured_momenta_check({simulate({1, 0.1, false}, 30, false, rng)}, false);
  EXPECT_FALSE(short_record.applicable);
  EXPECT_TRUE(short_record.passed);
}

}  // namespace
}  // namespace csympnet
