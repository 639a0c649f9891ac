#include "csympnet/train/levenberg_marquardt.hpp"

#include <gtest/gtest.h>

#include <Eigen/QR>
#include <Eigen/SVD>
#include <cmath>
#include <iostream>
#include <vector>

#include "../../src/train/lapack.hpp"
#include "csympnet/core/rng.hpp"
#include "support/train_fixtures.hpp"

namespace csympnet {
namespace {

RowMajorMatrix random_rows(Index m, Index n, Rng& rng) {
  RowMajorMatrix a(m, n);
  const Matrix x = rng.normal_matrix(m, n, 1.0);
  a = x;
  return a;
}

TEST(Lapack, WrappersAgreeWithEigen) {
  Rng rng(41, "lapack");
  for (const auto& [m, n] : {std::pair<Index, Index>{7, 3}, {40, 17}, {130, 64}}) {
    const RowMajorMatrix j = random_rows(m, n, rng);
    const Vector r = rng.normal_matrix(m, 1, 1.0);
    const Matrix want = j.transpose() * j;
    Matrix a(n, n);
    lapack::gram_from_transpose(j.data(), n, m, a.data());
    const Matrix lower = a.triangularView<Eigen::Lower>();
    const Matrix want_lower = want.triangularView<Eigen::Lower>();
    EXPECT_LE((lower - want_lower).norm(), 1e-13 * want.norm()) << m << "x" << n;

    Vector g(n);
    lapack::transpose_times(j.data(), n, m, r.data(), g.data());
    EXPECT_LE((g - j.transpose() * r).norm(), 1e-13 * (j.norm() * r.norm()));

    const Vector x = rng.normal_matrix(n, 1, 1.0);
    Vector ax(n);
    lapack::symmetric_times(a.data(), n, x.data(), ax.data());
    EXPECT_LE((ax - want * x).norm(), 1e-13 * want.norm() * x.norm());

    Matrix l = a;
    l.diagonal().array() += 1.0;  // JᵀJ + I: positive definite
    ASSERT_TRUE(lapack::cholesky(l.data(), n));
    Vector b = x;
    lapack::cholesky_solve(l.data(), n, b.data());
    const Matrix spd = want + Matrix::Identity(n, n);
    EXPECT_LE((spd * b - x).norm(), 1e-10 * x.norm());
  }
}

TEST(Lapack, CholeskyReportsAnIndefiniteMatrix) {
  Matrix c(2, 2);
  c << 1.0, 0.0, 2.0, 1.0;  // lower triangle of [[1, 2], [2, 1]]: eigenvalues 3 and −1
  EXPECT_FALSE(lapack::cholesky(c.data(), 2));
}

// The block-column factor (polled for interrupts) is the same factor as dpotrf's at random
// SPD matrices of sizes around and across its block width, reports an indefinite matrix, and
// stops when asked.
TEST(Lapack, BlockedCholeskyAgreesWithDpotrfAndStops) {
  Rng rng(43, "blocked");
  for (const Index n : {1, 5, 31, 32, 33, 100, 257, 700}) {
    const RowMajorMatrix j = random_rows(n + 3, n, rng);
    Matrix a(n, n);
    lapack::gram_from_transpose(j.data(), n, n + 3, a.data());
    a.diagonal().array() += 0.5;
    Matrix whole = a, blocked = a;
    ASSERT_TRUE(lapack::cholesky(whole.data(), n));
    long polls = 0;
    ASSERT_EQ(lapack::cholesky_blocked(blocked.data(), n,
                                       [&polls] {
                                         ++polls;
                                         return false;
                                       }),
              lapack::Factor::kDone);
    const Matrix lw = whole.triangularView<Eigen::Lower>();
    const Matrix lb = blocked.triangularView<Eigen::Lower>();
    EXPECT_LE((lw - lb).norm(), 1e-12 * lw.norm()) << "n = " << n;
    EXPECT_EQ(polls, (n + 255) / 256) << "n = " << n;  // one poll per block of <= 256 columns
    // The factor reproduces the matrix.
    const Matrix want = a.selfadjointView<Eigen::Lower>();
    EXPECT_LE((lb * lb.transpose() - want).norm(), 1e-12 * want.norm()) << "n = " << n;
  }
  Matrix c(2, 2);
  c << 1.0, 0.0, 2.0, 1.0;
  EXPECT_EQ(lapack::cholesky_blocked(c.data(), 2, {}), lapack::Factor::kNotPositiveDefinite);
  Matrix big = Matrix::Identity(600, 600);
  EXPECT_EQ(lapack::cholesky_blocked(big.data(), 600, [] { return true; }),
            lapack::Factor::kStopped);
}

// A problem too large to linearise in one BLAS call between polls is formed in row blocks: the
// same solution as unpolled, and a stop request ends it before the first iteration.
TEST(LevenbergMarquardt, LargeProblemsPollBetweenBlocksAndStop) {
  Rng rng(44, "large");
  const Index m = 9000, n = 400;  // m n² = 1.44e9 > kMaxUninterruptedFlops: two row blocks
  ASSERT_GT(static_cast<double>(m) * n * n, lapack::kMaxUninterruptedFlops);
  const RowMajorMatrix a = random_rows(m, n, rng);
  const Vector b = rng.normal_matrix(m, 1, 1.0);
  LeastSquaresProblem p;
  p.n_residuals = m;
  p.n_params = n;
  p.residuals = [&](ConstParams x, Eigen::Ref<Vector> r) {
    r = a * x - b;
    return true;
  };
  p.jacobian = [&](ConstParams, Eigen::Ref<RowMajorMatrix> j) { j = a; };
  LmSettings settings;
  settings.max_iterations = 20;
  Vector plain = Vector::Zero(n);
  levenberg_marquardt(p, plain, settings);
  long polls = 0;
  p.should_stop = [&polls] {
    ++polls;
    return false;
  };
  Vector polled = Vector::Zero(n);
  levenberg_marquardt(p, polled, settings);
  EXPECT_GT(polls, 0);
  // The row blocks are the same with and without a poll, so the bits are too, on every CPU.
  EXPECT_EQ(polled, plain) << "max difference " << (polled - plain).cwiseAbs().maxCoeff();
  p.should_stop = [] { return true; };
  Vector stopped = Vector::Zero(n);
  const LmReport r = levenberg_marquardt(p, stopped, settings);
  EXPECT_EQ(r.message, "stopped by the caller");
  EXPECT_EQ(r.iterations, 0);
  EXPECT_EQ(stopped, Vector::Zero(n));
}

LeastSquaresProblem rosenbrock() {
  return testing::rosenbrock_problem();
}

TEST(LevenbergMarquardt, SolvesRosenbrockFromTheClassicStart) {
  Vector x(2);
  x << -1.2, 1.0;
  LmSettings s;
  s.max_iterations = 200;
  const LmReport r = levenberg_marquardt(rosenbrock(), x, s);
  EXPECT_NEAR(x(0), 1.0, 1e-10) << r.message;
  EXPECT_NEAR(x(1), 1.0, 1e-10) << r.message;
  EXPECT_LT(r.final_cost, 1e-20);
  EXPECT_NEAR(r.initial_cost, 12.1, 1e-12);  // ½ (4.4² + 2.2²)
  EXPECT_LE(r.iterations, 200);
}

// One residual r(x) of one parameter, with its derivative.
LeastSquaresProblem scalar_problem(double (*r)(double), double (*dr)(double)) {
  LeastSquaresProblem p;
  p.n_residuals = 1;
  p.n_params = 1;
  p.residuals = [r](ConstParams x, Eigen::Ref<Vector> out) {
    out(0) = r(x(0));
    return true;
  };
  p.jacobian = [dr](ConstParams x, Eigen::Ref<RowMajorMatrix> j) { j(0, 0) = dr(x(0)); };
  return p;
}

TEST(LevenbergMarquardt, RejectsAnOvershootAndStillConverges) {
  // r = atan(x) from x = 3: the Gauss–Newton step −atan(3)(1 + 9) lands at x ≈ −9.5, where
  // |r| is larger, so the first trial must be rejected and μ raised.
  const LeastSquaresProblem p = scalar_problem([](double x) { return std::atan(x); },
                                               [](double x) { return 1.0 / (1.0 + x * x); });
  Vector x(1);
  x << 3.0;
  std::vector<long> accepted_at;
  const LmReport r = levenberg_marquardt(
      p, x, LmSettings{}, {[&](long it, const Vector&, double) { accepted_at.push_back(it); }, {}});
  EXPECT_LT(std::abs(x(0)), 1e-12) << r.message;
  ASSERT_FALSE(accepted_at.empty());
  EXPECT_GT(accepted_at.front(), 1);  // iteration 1 was the rejected overshoot
  EXPECT_EQ(static_cast<long>(accepted_at.size()), r.accepted);
  EXPECT_LT(r.accepted, r.iterations);
}

TEST(LevenbergMarquardt, FindsTheLinearLeastSquaresSolution) {
  Rng rng(42, "linear");
  const RowMajorMatrix a = random_rows(60, 12, rng);
  const Vector b = rng.normal_matrix(60, 1, 1.0);
  LeastSquaresProblem p;
  p.n_residuals = 60;
  p.n_params = 12;
  p.residuals = [&](ConstParams x, Eigen::Ref<Vector> r) {
    r = a * x - b;
    return true;
  };
  p.jacobian = [&](ConstParams, Eigen::Ref<RowMajorMatrix> j) { j = a; };
  Vector x = Vector::Zero(12);
  const LmReport r = levenberg_marquardt(p, x, LmSettings{});
  EXPECT_LT(r.iterations, 100) << r.message;
  const Vector want = Matrix(a).colPivHouseholderQr().solve(b);
  // A cost-based method resolves the cost to its rounding, ε F: steps whose gain is below
  // that are noise. So x is exact up to ‖e‖ with ½ σ_min² ‖e‖² = ε F, F = ½‖A x* − b‖².
  const double cost = 0.5 * (a * want - b).squaredNorm();
  const double sigma_min = Eigen::JacobiSVD<Matrix>(a).singularValues().minCoeff();
  const double floor = std::sqrt(2.0 * 2.2e-16 * cost) / sigma_min;
  EXPECT_LE((x - want).norm(), floor) << r.message << " after " << r.iterations;
  EXPECT_LT(floor, 1e-6 * want.norm());  // and that bound says something
}

TEST(LevenbergMarquardt, StopsAtAZeroGradientAndAtTheBudget) {
  Vector x(2);
  x << 1.0, 1.0;  // Rosenbrock's minimum: Jᵀr = 0
  LmReport r = levenberg_marquardt(rosenbrock(), x, LmSettings{});
  EXPECT_EQ(r.iterations, 0);
  EXPECT_EQ(r.message, "gradient tolerance reached");
  x << -1.2, 1.0;
  LmSettings s;
  s.max_iterations = 3;
  r = levenberg_marquardt(rosenbrock(), x, s);
  EXPECT_EQ(r.iterations, 3);
  EXPECT_EQ(r.message, "maximum number of iterations reached");
}

// A damped cosine y = a e^(−b t) cos(ω t + φ) sampled with noise: a nonlinear regression with
// an ill-conditioned corner (a and b trade off), at random parameters and noise.
struct DampedCosine {
  Vector t, y;
  LeastSquaresProblem problem() const {
    LeastSquaresProblem p;
    p.n_residuals = t.size();
    p.n_params = 4;
    p.residuals = [this](ConstParams x, Eigen::Ref<Vector> r) {
      for (Index i = 0; i < t.size(); ++i)
        r(i) = x(0) * std::exp(-x(1) * t(i)) * std::cos(x(2) * t(i) + x(3)) - y(i);
      return true;
    };
    p.jacobian = [this](ConstParams x, Eigen::Ref<RowMajorMatrix> j) {
      for (Index i = 0; i < t.size(); ++i) {
        const double e = std::exp(-x(1) * t(i)), c = std::cos(x(2) * t(i) + x(3)),
                     s = std::sin(x(2) * t(i) + x(3));
        j(i, 0) = e * c;
        j(i, 1) = -t(i) * x(0) * e * c;
        j(i, 2) = -t(i) * x(0) * e * s;
        j(i, 3) = -x(0) * e * s;
      }
    };
    return p;
  }
};

// n samples over [0, 20] of a damped cosine at random parameters (returned in `truth`: a in
// [1, 2], b in [0.05, 0.25], ω in [1, 3], φ in [−0.5, 0.5]) with Gaussian noise of 0.1–0.32.
DampedCosine random_damped_cosine(Index n, Rng& rng, Vector& truth) {
  DampedCosine data;
  truth = (Vector(4) << 1.0 + rng.uniform(), 0.05 + 0.2 * rng.uniform(), 1.0 + 2.0 * rng.uniform(),
           rng.uniform() - 0.5)
              .finished();
  const double noise = std::pow(10.0, -1.0 + 0.5 * rng.uniform());
  data.t = Vector::LinSpaced(n, 0.0, 20.0);
  data.y.resize(n);
  for (Index i = 0; i < n; ++i)
    data.y(i) =
        truth(0) * std::exp(-truth(1) * data.t(i)) * std::cos(truth(2) * data.t(i) + truth(3)) +
        noise * rng.normal();
  return data;
}

// LmSettings::chi2_tolerance ends the solve once the Gauss–Newton steps left are worth less
// than 1e-3 of χ²; the parameters are then within 0.05 of their standard errors of the fully
// converged fit (0.032 is the local model's bound), at 20 random problems, in no more
// iterations; off (0, the default), the solve is unchanged. The noise (10–30% of the amplitude)
// makes Gauss–Newton converge slowly enough for the tolerance to matter: at 3 instead of 1e-3,
// 17 of the 80 parameter checks fail.
TEST(LevenbergMarquardt, TheChiSquareRuleStopsWithinAFewHundredthsOfAStandardError) {
  Rng rng(43, "chi2");
  long saved = 0;
  for (int draw = 0; draw < 20; ++draw) {
    const Index n = 200;
    Vector truth;
    const DampedCosine data = random_damped_cosine(n, rng, truth);
    const LeastSquaresProblem p = data.problem();
    Vector start = truth;
    start(0) *= 1.3;
    start(1) *= 0.6;
    start(2) *= 1.02;
    start(3) += 0.2;
    LmSettings full;
    full.max_iterations = 500;
    Vector best = start;
    const LmReport ref = levenberg_marquardt(p, best, full);
    LmSettings quick = full;
    quick.chi2_tolerance = 1e-3;
    Vector x = start;
    const LmReport r = levenberg_marquardt(p, x, quick);
    EXPECT_EQ(r.message.rfind("converged", 0), 0u) << r.message;
    EXPECT_LE(r.iterations, ref.iterations) << ref.message;
    saved += ref.iterations - r.iterations;
    // Where it stopped, the full Gauss–Newton step predicts a fall of χ² below the tolerance.
    RowMajorMatrix jx(n, 4);
    Vector rx(n);
    p.jacobian(x, jx);
    p.residuals(x, rx);
    const Vector gx = Matrix(jx).transpose() * rx;
    const Vector dx = (Matrix(jx).transpose() * Matrix(jx)).ldlt().solve(gx);
    EXPECT_LT(static_cast<double>(n) * 0.5 * gx.dot(dx) / (0.5 * rx.squaredNorm()), 1e-3)
        << "draw " << draw;
    // Standard errors at the converged fit: σ̂² (JᵀJ)⁻¹, σ̂² = ‖r‖² / (n − 4).
    RowMajorMatrix j(n, 4);
    p.jacobian(best, j);
    const Matrix cov = (Matrix(j).transpose() * Matrix(j)).inverse() * 2.0 * ref.final_cost /
                       static_cast<double>(n - 4);
    for (Index k = 0; k < 4; ++k)
      EXPECT_LE(std::abs(x(k) - best(k)), 0.05 * std::sqrt(cov(k, k)))
          << "draw " << draw << " parameter " << k << ": " << r.message;
  }
  std::cout << "  iterations saved over 20 problems: " << saved << "\n";
  // Off: the same iterates as before the rule existed (no "converged" message).
  DampedCosine data;
  data.t = Vector::LinSpaced(50, 0.0, 10.0);
  data.y = (data.t.array() * -0.1).exp() * (2.0 * data.t.array()).cos();
  Vector x = (Vector(4) << 1.2, 0.2, 2.1, 0.1).finished();
  const LmReport r = levenberg_marquardt(data.problem(), x, LmSettings{});
  EXPECT_NE(r.message.rfind("converged", 0), 0u) << r.message;
}

// LmSettings::watch_index ends the solve once the watched parameter has stopped moving while
// the others still crawl: the damped cosine's decay rate b (θ₁) beside a decoupled Rosenbrock
// valley in θ₄, θ₅ (steep, 100 (θ₅ − θ₄²), and scaled by 0.01 so that it hardly weighs in χ²)
// from the classic start. At 20 random problems the solve ends no later than the full solve,
// at least 15 of them on the rule, with b within 0.05 of its standard error of the fully
// converged fit (each of the last three steps moved it by at most 0.01). Off (no index, or
// converged_se 0), the iterates are the default's bit for bit.
TEST(LevenbergMarquardt, TheWatchedParameterRuleStopsOnceItStopsMoving) {
  Rng rng(47, "watch");
  constexpr double kValley = 0.01;
  long saved = 0;
  int ended_on_rule = 0;
  for (int draw = 0; draw < 20; ++draw) {
    const Index n = 200;
    Vector truth;
    const DampedCosine data = random_damped_cosine(n, rng, truth);
    const LeastSquaresProblem cosine = data.problem();
    LeastSquaresProblem p;
    p.n_residuals = n + 2;
    p.n_params = 6;
    p.residuals = [&cosine, n](ConstParams x, Eigen::Ref<Vector> r) {
      cosine.residuals(x.head(4), r.head(n));
      r(n) = kValley * 100.0 * (x(5) - x(4) * x(4));
      r(n + 1) = kValley * (1.0 - x(4));
      return true;
    };
    p.jacobian = [&cosine, n](ConstParams x, Eigen::Ref<RowMajorMatrix> j) {
      j.setZero();
      RowMajorMatrix head(n, 4);
      cosine.jacobian(x.head(4), head);
      j.topLeftCorner(n, 4) = head;
      j(n, 4) = -kValley * 200.0 * x(4);
      j(n, 5) = kValley * 100.0;
      j(n + 1, 4) = -kValley;
    };
    Vector start(6);
    start << truth(0) * 1.3, truth(1) * 0.6, truth(2) * 1.02, truth(3) + 0.2, -1.2, 1.0;
    LmSettings full;
    full.max_iterations = 500;
    Vector best = start;
    const LmReport ref = levenberg_marquardt(p, best, full);
    LmSettings watched = full;
    watched.watch_index = 1;
    watched.converged_se = 0.01;
    Vector x = start;
    const LmReport r = levenberg_marquardt(p, x, watched);
    const bool on_rule = r.message.rfind("converged: three steps in a row", 0) == 0;
    if (!on_rule) {
      EXPECT_EQ(r.message, ref.message) << "draw " << draw;
    }
    EXPECT_LE(r.iterations, ref.iterations) << "draw " << draw << ": " << ref.message;
    ended_on_rule += on_rule ? 1 : 0;
    saved += ref.iterations - r.iterations;
    RowMajorMatrix j(n + 2, 6);
    p.jacobian(best, j);
    const Matrix cov = (Matrix(j).transpose() * Matrix(j)).inverse() * 2.0 * ref.final_cost /
                       static_cast<double>(n - 4);
    EXPECT_LE(std::abs(x(1) - best(1)), 0.05 * std::sqrt(cov(1, 1)))
        << "draw " << draw << ": " << r.message;
    // Off: the default's iterates.
    LmSettings no_share = full, no_index = full;
    no_share.watch_index = 1;
    no_index.converged_se = 0.01;
    for (const LmSettings& off : {no_share, no_index}) {
      Vector y = start;
      const LmReport o = levenberg_marquardt(p, y, off);
      EXPECT_EQ(o.iterations, ref.iterations);
      EXPECT_EQ(y, best);
    }
  }
  EXPECT_GE(ended_on_rule, 15);
  EXPECT_GE(saved, 100);
  std::cout << "  " << ended_on_rule << " of 20 ended on the rule, iterations saved: " << saved
            << "\n";
}

TEST(LevenbergMarquardt, LeavesThetaAloneWhenTheStartIsNotFinite) {
  LeastSquaresProblem p = rosenbrock();
  p.residuals = [](ConstParams, Eigen::Ref<Vector> r) {
    r.setConstant(std::nan(""));
    return true;
  };
  Vector x(2);
  x << -1.2, 1.0;
  const Vector before = x;
  const LmReport r = levenberg_marquardt(p, x, LmSettings{});
  EXPECT_EQ(x, before);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_NE(r.message.find("not finite"), std::string::npos) << r.message;
}

TEST(LevenbergMarquardt, TreatsANonFiniteTrialAsARejection) {
  // r = log x from x = 5: the Gauss–Newton step −x log x ≈ −8.05 lands at x < 0, where r is
  // NaN. That trial must count as a rejection (not poison θ), and the damped steps that
  // follow must reach the root x = 1.
  const LeastSquaresProblem p =
      scalar_problem([](double x) { return std::log(x); }, [](double x) { return 1.0 / x; });
  Vector x(1);
  x << 5.0;
  std::vector<long> accepted_at;
  const LmReport r = levenberg_marquardt(
      p, x, LmSettings{}, {[&](long it, const Vector&, double) { accepted_at.push_back(it); }, {}});
  EXPECT_NEAR(x(0), 1.0, 1e-12) << r.message;
  ASSERT_FALSE(accepted_at.empty());
  EXPECT_GT(accepted_at.front(), 1);
}

}  // namespace
}  // namespace csympnet
