// Multiple shooting on positions (train/shooting.hpp): the segment Jacobians in θ and in the
// start state against central differences, the eliminated normal equations against the Schur
// complement of the explicit JᵀJ, and the fits: start states recovered from exact positions,
// held-out start states to kScoringTolerance against those to rounding, and a joint fit from
// perturbed parameters that returns to the positions' noise floor.
#include "csympnet/train/shooting.hpp"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>
#include <Eigen/Cholesky>

#include "csympnet/core/error.hpp"
#include "csympnet/models/dof_scaled_map.hpp"
#include "support/gradient_check.hpp"
#include "support/model_fixtures.hpp"

namespace csympnet {
namespace {

using testing::check_jacobian;
using testing::random_theta;

// Segments of random positions at random steps (the derivatives hold for any data), with
// random start states.
ShootingSegments random_segments(Index d, int count, Rng& rng, Matrix& z0) {
  ShootingSegments s;
  s.d = d;
  z0.resize(2 * d, count);
  for (int k = 0; k < count; ++k) {
    const Index len = 3 + k % 4;
    s.q.push_back(rng.normal_matrix(d, len, 1.0));
    Vector h(len - 1);
    for (Index j = 0; j < len - 1; ++j) h(j) = rng.uniform(0.05, 0.2);
    s.h.push_back(h);
    s.block.push_back(k / 2);
    z0.col(k) = rng.normal_matrix(2 * d, 1, 0.7);
  }
  return s;
}

// Segment i of segs alone.
ShootingSegments one_segment(const ShootingSegments& segs, std::size_t i) {
  ShootingSegments one;
  one.d = segs.d;
  one.q = {segs.q[i]};
  one.h = {segs.h[i]};
  one.block = {0};
  return one;
}

class ShootingTest : public ::testing::TestWithParam<const char*> {};

TEST_P(ShootingTest, SegmentJacobiansMatchFiniteDifferences) {
  const auto map = make_one_step_map(nlohmann::json::parse(GetParam()));
  const Index d = map->dim() / 2;
  Rng rng(31, GetParam());
  for (int rep = 0; rep < 2; ++rep) {
    const Vector theta = random_theta(*map, rng, 0.3, rep == 0 ? 0.6 : -0.4);
    Matrix z0;
    const ShootingSegments segs = random_segments(d, 3, rng, z0);
    for (Index s = 0; s < segs.size(); ++s) {
      const auto i = static_cast<std::size_t>(s);
      const Vector start = z0.col(s);
      const ShootingSegments one = one_segment(segs, i);
      const auto r_theta = [&](const Vector& th) {
        return shooting_residuals(*map, th, start, one);
      };
      const auto a_of = [&](const Vector& th) -> Matrix {
        RowMajorMatrix a;
        Matrix b;
        Vector r;
        shooting_segment_jacobian(*map, th, start, segs.q[i], segs.h[i], map->n_params(), a, b, r);
        return a;
      };
      const auto c1 = check_jacobian(r_theta, a_of, theta);
      EXPECT_TRUE(c1.ok()) << c1.report("shooting: dr/dtheta");
      const auto r_z = [&](const Vector& z) { return shooting_residuals(*map, theta, z, one); };
      const auto b_of = [&](const Vector& z) -> Matrix {
        RowMajorMatrix a;
        Matrix b;
        Vector r;
        shooting_segment_jacobian(*map, theta, z, segs.q[i], segs.h[i], 0, a, b, r);
        EXPECT_EQ(a.cols(), 0);
        return b;
      };
      const auto c2 = check_jacobian(r_z, b_of, start);
      EXPECT_TRUE(c2.ok()) << c2.report("shooting: dr/dz0");
    }
  }
}

// A driven map's segments (known inputs per step): the rows in θ and in the start state, which
// come from one reverse pass per state component and step (the step's DΦ̂ from the same passes),
// against central differences, for the two neural cores (G, LA).
TEST(ShootingDriven, SegmentJacobiansMatchFiniteDifferences) {
  const char* specs[] = {
      R"({"type":"csympnet","d":1,"inputs":{"m":1,"hold":"foh"},"core":{"type":"g","layers":3,"width":5}})",
      R"({"type":"csympnet","d":2,"inputs":{"m":2,"hold":"zoh"},"core":{"type":"la","layers":2,"sublayers":3}})"};
  for (const char* spec : specs) {
    SCOPED_TRACE(spec);
    const auto map = make_one_step_map(nlohmann::json::parse(spec));
    const Index d = map->dim() / 2, m = map->n_inputs();
    ASSERT_GT(m, 0);
    Rng rng(37, spec);
    const Vector theta = random_theta(*map, rng, 0.3, 0.5);
    Matrix z0;
    ShootingSegments segs = random_segments(d, 3, rng, z0);
    for (Index s = 0; s < segs.size(); ++s) {
      const auto i = static_cast<std::size_t>(s);
      const Matrix u = rng.normal_matrix(2 * m, segs.h[i].size(), 0.8);
      ShootingSegments one = one_segment(segs, i);
      one.u = {u};
      const Vector start = z0.col(s);
      const auto a_of = [&](const Vector& th) -> Matrix {
        RowMajorMatrix a;
        Matrix b;
        Vector r;
        shooting_segment_jacobian(*map, th, start, segs.q[i], segs.h[i], map->n_params(), a, b, r,
                                  Vector(), u);
        return a;
      };
      const auto c1 = check_jacobian(
          [&](const Vector& th) { return shooting_residuals(*map, th, start, one); }, a_of, theta);
      EXPECT_TRUE(c1.ok()) << c1.report("driven shooting: dr/dtheta");
      const auto b_of = [&](const Vector& z) -> Matrix {
        RowMajorMatrix a;
        Matrix b;
        Vector r;
        shooting_segment_jacobian(*map, theta, z, segs.q[i], segs.h[i], 0, a, b, r, Vector(), u);
        EXPECT_EQ(r, shooting_residuals(*map, theta, z, one));  // the same rollout, to the bit
        return b;
      };
      const auto c2 = check_jacobian(
          [&](const Vector& z) { return shooting_residuals(*map, theta, z, one); }, b_of, start);
      EXPECT_TRUE(c2.ok()) << c2.report("driven shooting: dr/dz0");
    }
  }
}

// The eliminated system is the Schur complement of the explicit joint JᵀJ over (θ, every z0),
// and its scores are the efficient scores of the blocks.
TEST_P(ShootingTest, EliminatedNormalEquationsAreTheSchurComplement) {
  const auto map = make_one_step_map(nlohmann::json::parse(GetParam()));
  const Index d = map->dim() / 2, dim = 2 * d, p = map->n_params();
  Rng rng(32, GetParam());
  const Vector theta = random_theta(*map, rng, 0.3, 0.5);
  Matrix z0;
  const ShootingSegments segs = random_segments(d, 5, rng, z0);
  const double scale = 0.41;
  const NormalEquations ne = shooting_normal_equations(*map, theta, z0, segs, p, scale, true);
  // The joint J, rows segment by segment, columns θ then each segment's z0.
  const Index n = segs.n_residuals(), cols = p + dim * segs.size();
  Matrix j = Matrix::Zero(n, cols);
  Vector r(n);
  Index row = 0;
  for (Index s = 0; s < segs.size(); ++s) {
    const auto i = static_cast<std::size_t>(s);
    RowMajorMatrix a;
    Matrix b;
    Vector rs;
    shooting_segment_jacobian(*map, theta, z0.col(s), segs.q[i], segs.h[i], p, a, b, rs);
    j.block(row, 0, a.rows(), p) = a;
    j.block(row, p + dim * s, b.rows(), dim) = b;
    r.segment(row, rs.size()) = rs;
    row += rs.size();
  }
  j *= scale;
  r *= scale;
  const Matrix full = j.transpose() * j;
  const Vector g = j.transpose() * r;
  const Matrix zz = full.bottomRightCorner(cols - p, cols - p);
  const Matrix tz = full.topRightCorner(p, cols - p);
  const Eigen::LDLT<Matrix> f(zz);
  const Matrix schur = full.topLeftCorner(p, p) - tz * f.solve(tz.transpose());
  const Vector g_red = g.head(p) - tz * f.solve(g.tail(cols - p));
  const Matrix lower_ne = ne.a.triangularView<Eigen::Lower>();
  const Matrix lower_schur = schur.triangularView<Eigen::Lower>();
  EXPECT_LE((lower_ne - lower_schur).norm(), 1e-9 * full.norm());
  EXPECT_LE((ne.g - g_red).norm(), 1e-9 * (1.0 + g.norm()));
  EXPECT_NEAR(ne.cost, 0.5 * r.squaredNorm(), 1e-12 * ne.cost);
  // The scores of the blocks add up to the reduced gradient.
  ASSERT_EQ(ne.scores.cols(), 3);
  EXPECT_LE((ne.scores.rowwise().sum() - ne.g).norm(), 1e-9 * (1.0 + ne.g.norm()));
}

// Segments spanning several blocks, with positions passed through unobserved (a linked chain
// through a held-out block): the weighted Jacobians against central differences, the eliminated
// system against the Schur complement of the explicit weighted JᵀJ, and each block's score
// against the efficient score of its own rows, at random parameters, weights and blocks.
TEST_P(ShootingTest, WeightedSegmentsAcrossBlocksGiveEachBlockItsEfficientScore) {
  const auto map = make_one_step_map(nlohmann::json::parse(GetParam()));
  const Index d = map->dim() / 2, dim = 2 * d, p = map->n_params();
  Rng rng(33, GetParam());
  const Vector theta = random_theta(*map, rng, 0.3, 0.5);
  Matrix z0;
  ShootingSegments segs = random_segments(d, 5, rng, z0);
  const Index blocks = 4;
  for (Index s = 0; s < segs.size(); ++s) {
    const Index len = segs.q[static_cast<std::size_t>(s)].cols();
    Vector w(len);
    std::vector<Index> cb(static_cast<std::size_t>(len));
    for (Index k = 0; k < len; ++k) {
      w(k) = k == 0 || rng.uniform(0.0, 1.0) < 0.6 ? 1.0 : 0.0;
      cb[static_cast<std::size_t>(k)] =
          static_cast<Index>(rng.uniform(0.0, 0.999) * static_cast<double>(blocks));
    }
    segs.observed.push_back(w);
    segs.column_block.push_back(cb);
  }
  segs.validate();
  double observed = 0.0;
  for (const Vector& w : segs.observed) observed += w.sum();
  ASSERT_EQ(segs.n_residuals(), static_cast<Index>(observed) * d);
  ASSERT_LT(segs.n_residuals(), segs.n_rows());
  // Derivatives of the weighted residuals, segment by segment.
  for (Index s = 0; s < segs.size(); ++s) {
    const auto i = static_cast<std::size_t>(s);
    ShootingSegments one = one_segment(segs, i);
    one.observed = {segs.observed[i]};
    const Vector start = z0.col(s);
    const auto a_of = [&](const Vector& th) -> Matrix {
      RowMajorMatrix a;
      Matrix b;
      Vector r;
      shooting_segment_jacobian(*map, th, start, segs.q[i], segs.h[i], p, a, b, r,
                                segs.observed[i]);
      return a;
    };
    const auto c1 = check_jacobian(
        [&](const Vector& th) { return shooting_residuals(*map, th, start, one); }, a_of, theta);
    EXPECT_TRUE(c1.ok()) << c1.report("weighted shooting: dr/dtheta");
    const auto b_of = [&](const Vector& z) -> Matrix {
      RowMajorMatrix a;
      Matrix b;
      Vector r;
      shooting_segment_jacobian(*map, theta, z, segs.q[i], segs.h[i], 0, a, b, r, segs.observed[i]);
      return b;
    };
    const auto c2 = check_jacobian(
        [&](const Vector& z) { return shooting_residuals(*map, theta, z, one); }, b_of, start);
    EXPECT_TRUE(c2.ok()) << c2.report("weighted shooting: dr/dz0");
  }
  // The explicit joint system, and its rows per block.
  const double scale = 0.37;
  const NormalEquations ne = shooting_normal_equations(*map, theta, z0, segs, p, scale, true);
  const Index n = segs.n_rows(), cols = p + dim * segs.size();
  Matrix j = Matrix::Zero(n, cols);
  Vector r(n);
  std::vector<Index> row_block(static_cast<std::size_t>(n));
  Index row = 0;
  for (Index s = 0; s < segs.size(); ++s) {
    const auto i = static_cast<std::size_t>(s);
    RowMajorMatrix a;
    Matrix b;
    Vector rs;
    shooting_segment_jacobian(*map, theta, z0.col(s), segs.q[i], segs.h[i], p, a, b, rs,
                              segs.observed[i]);
    j.block(row, 0, a.rows(), p) = a;
    j.block(row, p + dim * s, b.rows(), dim) = b;
    r.segment(row, rs.size()) = rs;
    for (Index k = 0; k < rs.size(); ++k)
      row_block[static_cast<std::size_t>(row + k)] = segs.block_of(s, k / d);
    row += rs.size();
  }
  j *= scale;
  r *= scale;
  const Matrix full = j.transpose() * j;
  const Matrix zz = full.bottomRightCorner(cols - p, cols - p);
  const Matrix tz = full.topRightCorner(p, cols - p);
  const Eigen::LDLT<Matrix> f(zz);
  const Matrix schur = full.topLeftCorner(p, p) - tz * f.solve(tz.transpose());
  const Matrix lower_ne = ne.a.triangularView<Eigen::Lower>();
  const Matrix lower_schur = schur.triangularView<Eigen::Lower>();
  EXPECT_LE((lower_ne - lower_schur).norm(), 1e-9 * full.norm());
  EXPECT_NEAR(ne.cost, 0.5 * r.squaredNorm(), 1e-12 * ne.cost);
  EXPECT_NEAR(shooting_loss(*map, theta, z0, segs),
              r.squaredNorm() / (scale * scale) / static_cast<double>(segs.n_residuals()),
              1e-12 * r.squaredNorm() / (scale * scale));
  ASSERT_EQ(ne.scores.cols(), blocks);
  for (Index b = 0; b < blocks; ++b) {
    Vector gb = Vector::Zero(cols);
    for (Index k = 0; k < n; ++k)
      if (row_block[static_cast<std::size_t>(k)] == b) gb += j.row(k).transpose() * r(k);
    const Vector efficient = gb.head(p) - tz * f.solve(gb.tail(cols - p));
    EXPECT_LE((ne.scores.col(b) - efficient).norm(), 1e-9 * (1.0 + efficient.norm()))
        << "block " << b;
  }
  // Each block's information is that of its rows of the efficient Jacobian (the start states
  // eliminated over every segment's rows), J̃ = J_θ − J_z (J_zᵀJ_z)⁻¹ J_zᵀJ_θ; they add up to the
  // reduced matrix, and the rest of the normal equations is shooting_normal_equations'.
  const NormalEquations nb = shooting_block_equations(*map, theta, z0, segs, p, scale);
  EXPECT_EQ((nb.a - ne.a).norm(), 0.0);
  EXPECT_EQ((nb.scores - ne.scores).norm(), 0.0);
  ASSERT_EQ(static_cast<Index>(nb.block_information.size()), blocks);
  const Matrix efficient_j = j.leftCols(p) - j.rightCols(cols - p) * f.solve(tz.transpose());
  Matrix sum = Matrix::Zero(p, p);
  for (Index b = 0; b < blocks; ++b) {
    Matrix expected = Matrix::Zero(p, p);
    for (Index k = 0; k < n; ++k)
      if (row_block[static_cast<std::size_t>(k)] == b)
        expected += efficient_j.row(k).transpose() * efficient_j.row(k);
    const Matrix& got = nb.block_information[static_cast<std::size_t>(b)];
    EXPECT_LE((got - expected).norm(), 1e-8 * (1.0 + full.norm())) << "block " << b;
    sum += got;
  }
  EXPECT_LE((sum - schur).norm(), 1e-8 * full.norm());
}

// Runs inside blocks: every run lies in one block, runs follow the record's order, each has
// `run` positions but a block's last, and the segments' positions and steps are untouched.
TEST(ShootingRuns, SplitBlocksIntoRunsCutsEachBlockInOrder) {
  ShootingSegments segs;
  segs.d = 1;
  // Block 0: segments 0 and 1 (5 + 4 positions); segment 2 spans blocks 0 (2) and 1 (6).
  for (Index len : {5, 4, 8}) {
    segs.q.push_back(Matrix::Zero(1, len));
    segs.h.push_back(Vector::Constant(len - 1, 0.1));
  }
  segs.block = {0, 0, 0};
  segs.column_block = {{0, 0, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, 1, 1, 1, 1, 1, 1}};
  const ShootingSegments runs = split_blocks_into_runs(segs, 4);
  runs.validate();
  // Block 0 has 11 positions: runs 4, 4, 3; block 1 has 6: runs 4, 2.
  const std::vector<std::vector<Index>> expected = {
      {0, 0, 0, 0, 1}, {1, 1, 1, 2}, {2, 2, 3, 3, 3, 3, 4, 4}};
  EXPECT_EQ(runs.column_block, expected);
  EXPECT_EQ(runs.block, (std::vector<Index>{0, 1, 2}));
  for (std::size_t s = 0; s < segs.q.size(); ++s) {
    EXPECT_EQ(runs.q[s], segs.q[s]);
    EXPECT_EQ(runs.h[s], segs.h[s]);
  }
  EXPECT_THROW(split_blocks_into_runs(segs, 0), Error);
}

// Positions made by the map itself: the start states are recovered from positions alone, and
// a joint fit from perturbed parameters returns to zero loss.
TEST_P(ShootingTest, FitsRecoverExactPositions) {
  const auto map = make_one_step_map(nlohmann::json::parse(GetParam()));
  const Index d = map->dim() / 2;
  Rng rng(33, GetParam());
  const Vector truth = random_theta(*map, rng, 0.3, 0.3);
  ShootingSegments segs;
  segs.d = d;
  const int count = 12;
  Matrix z_true(2 * d, count);
  for (int k = 0; k < count; ++k) {
    z_true.col(k) = rng.normal_matrix(2 * d, 1, 0.6);
    const Vector h = Vector::Constant(11, 0.1);
    segs.q.push_back(shooting_states(*map, truth, z_true.col(k), h).topRows(d));
    segs.h.push_back(h);
    segs.block.push_back(k % 4);
  }
  // Start states from a disturbed guess, θ known.
  Matrix z0 = z_true + 0.05 * rng.normal_matrix(2 * d, count, 1.0);
  EXPECT_LT(fit_start_states(*map, truth, segs, z0), 1e-20);
  EXPECT_LE((z0 - z_true).norm(), 1e-7 * z_true.norm());
  // Jointly from perturbed parameters; three segments held out.
  ShootingSegments train = segs, val;
  val.d = d;
  for (int k = 0; k < 3; ++k) {
    val.q.push_back(train.q.back());
    val.h.push_back(train.h.back());
    val.block.push_back(0);
    train.q.pop_back();
    train.h.pop_back();
    train.block.pop_back();
  }
  Vector theta = truth + 0.01 * rng.normal_matrix(truth.size(), 1, 1.0);
  Matrix zt = z_true.leftCols(count - 3) + 0.01 * rng.normal_matrix(2 * d, count - 3, 1.0);
  Matrix zv = z_true.rightCols(3).rowwise().reverse();  // any start: refitted first
  const double before = shooting_loss(*map, theta, zt, train);
  ShootingOptions opt;
  opt.iterations = 60;
  const ShootingReport rep = fit_shooting(*map, theta, zt, train, zv, val, opt);
  EXPECT_LT(rep.final_loss, 1e-6 * before) << rep.message;
  EXPECT_LT(rep.val_loss, 1e-6 * before) << rep.message;
  EXPECT_LE(rep.best_iteration, rep.iterations);
}

// Exact positions, the fit started at the truth: its loss is rounding, a trial step there fails,
// and that ends the fit at once (not λ climbing through a dozen more rollouts), with θ where it
// was to rounding. Positions with noise of 1e-6 of their size never end that way.
TEST_P(ShootingTest, AFailedStepAtRoundingLevelEndsTheFit) {
  const auto map = make_one_step_map(nlohmann::json::parse(GetParam()));
  const Index d = map->dim() / 2;
  Rng rng(41, GetParam());
  const Vector truth = random_theta(*map, rng, 0.3, 0.3);
  for (const double noise : {0.0, 1e-6}) {
    SCOPED_TRACE(noise);
    ShootingSegments train, val;
    train.d = val.d = d;
    const int count = 10;
    Matrix z_true(2 * d, count);
    double square_sum = 0.0;
    for (int k = 0; k < count; ++k) {
      z_true.col(k) = rng.normal_matrix(2 * d, 1, 0.6);
      const Vector h = Vector::Constant(15, 0.1);
      Matrix q = shooting_states(*map, truth, z_true.col(k), h).topRows(d);
      q += noise * rng.normal_matrix(d, q.cols(), q.cwiseAbs().maxCoeff());
      ShootingSegments& to = k < 7 ? train : val;
      if (k < 7) square_sum += q.squaredNorm();
      to.q.push_back(q);
      to.h.push_back(h);
      to.block.push_back(k % 3);
    }
    Vector theta = truth;
    Matrix zt = z_true.leftCols(7), zv = z_true.rightCols(3);
    ShootingOptions opt;
    opt.iterations = 60;
    const ShootingReport rep = fit_shooting(*map, theta, zt, train, zv, val, opt);
    const bool at_rounding = rep.message.find("rounding level") != std::string::npos;
    if (noise == 0.0) {
      EXPECT_TRUE(at_rounding) << rep.message;
      EXPECT_LE(rep.iterations, 6) << rep.message;
      EXPECT_LE(rep.final_loss,
                kRoundingShare * square_sum / static_cast<double>(train.n_residuals()));
      EXPECT_LE((theta - truth).norm(), 1e-9 * truth.norm());
    } else {
      EXPECT_FALSE(at_rounding) << rep.message;
      EXPECT_GT(rep.final_loss,
                1e3 * kRoundingShare * square_sum / static_cast<double>(train.n_residuals()));
    }
  }
}

// Noisy positions: a fit of the start states to kScoringTolerance (held-out segments) ends at
// the loss of the fit to rounding within a millionth of it, and the loss either returns is the
// loss of the start states it leaves (each segment's cost summed, not rolled out again).
TEST_P(ShootingTest, ScoringToleranceReachesTheConvergedLoss) {
  const auto map = make_one_step_map(nlohmann::json::parse(GetParam()));
  const Index d = map->dim() / 2;
  Rng rng(37, GetParam());
  const Vector theta = random_theta(*map, rng, 0.3, 0.3);
  ShootingSegments segs;
  segs.d = d;
  const int count = 8;
  Matrix z_true(2 * d, count);
  for (int k = 0; k < count; ++k) {
    z_true.col(k) = rng.normal_matrix(2 * d, 1, 0.6);
    const Vector h = Vector::Constant(15, 0.1);
    segs.q.push_back(shooting_states(*map, theta, z_true.col(k), h).topRows(d) +
                     rng.normal_matrix(d, 16, 0.01));
    segs.h.push_back(h);
    segs.block.push_back(k % 4);
  }
  const Matrix guess = z_true + 0.3 * rng.normal_matrix(2 * d, count, 1.0);
  Matrix tight = guess, loose = guess;
  const double tight_loss = fit_start_states(*map, theta, segs, tight);
  const double loose_loss =
      fit_start_states(*map, theta, segs, loose, 30, false, std::numeric_limits<double>::infinity(),
                       kScoringTolerance);
  ASSERT_GT(tight_loss, 1e-6);  // the noise floor, not an exact fit
  EXPECT_NEAR(tight_loss, shooting_loss(*map, theta, tight, segs), 1e-13 * tight_loss);
  EXPECT_NEAR(loose_loss, shooting_loss(*map, theta, loose, segs), 1e-13 * loose_loss);
  EXPECT_GE(loose_loss, tight_loss * (1.0 - 1e-12));
  EXPECT_LE(loose_loss, tight_loss * (1.0 + 1e-6));
  // Already converged, a refit to either tolerance keeps the loss.
  Matrix again = tight;
  EXPECT_LE(fit_start_states(*map, theta, segs, again), tight_loss * (1.0 + 1e-14));
}

// A rollout from positions alone: the state at the window's end, from positions the map made,
// is the state the map reached (from far starts: p of the wrong size and sign).
TEST_P(ShootingTest, StateFromPositionsIsTheStateReached) {
  const auto map = make_one_step_map(nlohmann::json::parse(GetParam()));
  const Index d = map->dim() / 2;
  Rng rng(34, GetParam());
  const Vector theta = random_theta(*map, rng, 0.3, 0.3);
  for (int rep = 0; rep < 3; ++rep) {
    Vector z = rng.normal_matrix(2 * d, 1, 0.6);
    z.tail(d) *= 3.0 * (rep - 1);
    Vector t(8);
    t(0) = rng.uniform(-1.0, 1.0);
    for (Index k = 1; k < t.size(); ++k) t(k) = t(k - 1) + rng.uniform(0.05, 0.15);
    const Matrix states = shooting_states(*map, theta, z, t.tail(7) - t.head(7));
    double rms = 1.0;
    const Vector end = state_from_positions(*map, theta, states.topRows(d), t, &rms);
    EXPECT_LT(rms, 1e-10);
    EXPECT_LE((end - states.col(7)).norm(), 1e-7 * (1.0 + states.col(7).norm()))
        << end.transpose() << " vs " << states.col(7).transpose();
  }
  EXPECT_THROW(state_from_positions(*map, theta, Matrix::Zero(d, 1), Vector::Zero(1)), Error);
  EXPECT_THROW(
      state_from_positions(*map, theta, Matrix::Zero(d + 1, 3), Vector::LinSpaced(3, 0, 1)), Error);
}

// The whole state observed (an errors-in-variables fit of a record with momenta): segments of
// 2d rows, the momenta's rows weighted against the positions', at random parameters, weights and
// data. The Jacobians against central differences, the eliminated system against the Schur
// complement of the explicit JᵀJ, and from states the map made, the start states recovered.
TEST_P(ShootingTest, ObservedStatesWithRowWeights) {
  const auto map = make_one_step_map(nlohmann::json::parse(GetParam()));
  const Index d = map->dim() / 2, dim = 2 * d, p = map->n_params();
  Rng rng(35, GetParam());
  const Vector theta = random_theta(*map, rng, 0.3, 0.5);
  Matrix z0;
  ShootingSegments segs = random_segments(d, 4, rng, z0);
  for (Matrix& q : segs.q) q = rng.normal_matrix(dim, q.cols(), 1.0);
  segs.row_weight = Vector::Ones(dim);
  for (Index i = d; i < dim; ++i) segs.row_weight(i) = rng.uniform(0.2, 3.0);
  segs.validate();
  ASSERT_EQ(segs.observed_rows(), dim);
  ASSERT_EQ(segs.n_residuals(), segs.n_rows());
  for (Index s = 0; s < segs.size(); ++s) {
    const auto i = static_cast<std::size_t>(s);
    ShootingSegments one = one_segment(segs, i);
    one.row_weight = segs.row_weight;
    const Vector start = z0.col(s);
    const auto jac = [&](const Vector& th, const Vector& z, bool want_a) -> Matrix {
      RowMajorMatrix a;
      Matrix b;
      Vector r;
      shooting_segment_jacobian(*map, th, z, segs.q[i], segs.h[i], p, a, b, r, Vector(), Matrix(),
                                segs.row_weight);
      EXPECT_LE((r - shooting_residuals(*map, th, z, one)).norm(), 1e-12 * (1.0 + r.norm()));
      return want_a ? Matrix(a) : b;
    };
    const auto c1 =
        check_jacobian([&](const Vector& th) { return shooting_residuals(*map, th, start, one); },
                       [&](const Vector& th) { return jac(th, start, true); }, theta);
    EXPECT_TRUE(c1.ok()) << c1.report("observed states: dr/dtheta");
    const auto c2 =
        check_jacobian([&](const Vector& z) { return shooting_residuals(*map, theta, z, one); },
                       [&](const Vector& z) { return jac(theta, z, false); }, start);
    EXPECT_TRUE(c2.ok()) << c2.report("observed states: dr/dz0");
  }
  const double scale = 0.29;
  const NormalEquations ne = shooting_normal_equations(*map, theta, z0, segs, p, scale, false);
  const Index n = segs.n_rows(), cols = p + dim * segs.size();
  Matrix j = Matrix::Zero(n, cols);
  Index row = 0;
  for (Index s = 0; s < segs.size(); ++s) {
    const auto i = static_cast<std::size_t>(s);
    RowMajorMatrix a;
    Matrix b;
    Vector rs;
    shooting_segment_jacobian(*map, theta, z0.col(s), segs.q[i], segs.h[i], p, a, b, rs, Vector(),
                              Matrix(), segs.row_weight);
    j.block(row, 0, a.rows(), p) = a;
    j.block(row, p + dim * s, b.rows(), dim) = b;
    row += rs.size();
  }
  ASSERT_EQ(row, n);
  j *= scale;
  const Matrix full = j.transpose() * j;
  const Matrix tz = full.topRightCorner(p, cols - p);
  const Eigen::LDLT<Matrix> f(full.bottomRightCorner(cols - p, cols - p));
  const Matrix schur = full.topLeftCorner(p, p) - tz * f.solve(tz.transpose());
  const Matrix lower_ne = ne.a.triangularView<Eigen::Lower>();
  const Matrix lower_schur = schur.triangularView<Eigen::Lower>();
  EXPECT_LE((lower_ne - lower_schur).norm(), 1e-9 * full.norm());
  // States the map made: every start state recovered from a far guess (θ known).
  Matrix z_true = z0;
  for (Index s = 0; s < segs.size(); ++s) {
    const auto i = static_cast<std::size_t>(s);
    segs.q[i] = shooting_states(*map, theta, z_true.col(s), segs.h[i]);
  }
  Matrix guess = z_true + 0.5 * rng.normal_matrix(dim, segs.size(), 1.0);
  EXPECT_LT(fit_start_states(*map, theta, segs, guess, 30, true), 1e-20);
  EXPECT_LE((guess - z_true).norm(), 1e-7 * z_true.norm());
}

// A start whose rollout is not finite (a trial core far from the data) ends the fit at once,
// with an infinite loss and θ unchanged, instead of failing on its Jacobian.
TEST_P(ShootingTest, ANonFiniteStartEndsTheFitWithAnInfiniteLoss) {
  const auto map = make_one_step_map(nlohmann::json::parse(GetParam()));
  const Index d = map->dim() / 2;
  Rng rng(36, GetParam());
  Vector theta = random_theta(*map, rng, 0.3, 0.5);
  Matrix z0;
  const ShootingSegments segs = random_segments(d, 3, rng, z0);
  z0(0, 1) = std::numeric_limits<double>::infinity();
  const Vector before = theta;
  Matrix val_z0;
  const ShootingReport rep =
      fit_shooting(*map, theta, z0, segs, val_z0, ShootingSegments(), ShootingOptions());
  EXPECT_FALSE(std::isfinite(rep.final_loss));
  EXPECT_EQ(rep.iterations, 0);
  EXPECT_EQ(theta, before);
}

INSTANTIATE_TEST_SUITE_P(
    Maps, ShootingTest,
    ::testing::Values(
        R"({"type":"csympnet","d":1,"core":{"type":"la","layers":3,"sublayers":4}})",
        R"({"type":"csympnet","d":2,"core":{"type":"g","layers":3,"width":5}})",
        R"({"type":"csympnet","d":2,"dof_scales":"learned","core":{"type":"la","layers":2,"sublayers":3}})"));

// The damping parameter's convergence rule (ShootingOptions::watch_index): on noisy positions
// the watched fit ends earlier than one run to the loss's own convergence, at a damping
// parameter within a tenth of its standard error of that one; and the standard error it uses
// matches the spread of the estimate over noise draws (within the sampling error of 24 draws).
TEST(Shooting, DampingWatchEndsOnceTheDampingStopsMoving) {
  const auto map = make_one_step_map(nlohmann::json::parse(
      R"({"type":"csympnet","d":1,"core":{"type":"library","terms":["q1^2","q1^4"]}})"));
  const Index b = *map->damping_param_index();
  Rng rng(41, "damping-watch");
  // θ = (W, c of q1^2, c of q1^4, β): W = 1, c = ½ and 0.05 (a hardening spring), γ = 0.1.
  Vector truth(map->n_params());
  map->init_params(rng, truth);
  ASSERT_EQ(truth.size(), 4);
  truth(2) = 0.05;
  truth(b) = 0.1;
  const int count = 10;
  Matrix z_true(2, count);
  std::vector<Matrix> clean;
  for (int k = 0; k < count; ++k) {
    z_true.col(k) = rng.normal_matrix(2, 1, 0.6);
    clean.push_back(
        shooting_states(*map, truth, z_true.col(k), Vector::Constant(21, 0.1)).topRows(1));
  }
  const double sigma = 0.01;
  std::vector<double> estimates, ses;
  long watched_iterations = 0, full_iterations = 0;
  int ended_by_watch = 0;
  for (int draw = 0; draw < 24; ++draw) {
    ShootingSegments train, val;
    train.d = val.d = 1;
    for (int k = 0; k < count; ++k) {
      ShootingSegments& s = k < count - 2 ? train : val;
      s.q.push_back(clean[static_cast<std::size_t>(k)] + rng.normal_matrix(1, 22, sigma));
      s.h.push_back(Vector::Constant(21, 0.1));
      s.block.push_back(k % 4);
    }
    ShootingOptions opt;
    opt.iterations = 300;
    opt.patience = 300;
    opt.converged_se = 0.01;
    opt.watch_index = b;
    Vector theta_w = truth;
    Matrix zt = z_true.leftCols(count - 2), zv = z_true.rightCols(2);
    const ShootingReport watched = fit_shooting(*map, theta_w, zt, train, zv, val, opt);
    opt.watch_index = -1;
    Vector theta_f = truth;
    zt = z_true.leftCols(count - 2);
    zv = z_true.rightCols(2);
    const ShootingReport full = fit_shooting(*map, theta_f, zt, train, zv, val, opt);
    ASSERT_GT(watched.watch_se, 0.0);
    if (watched.watch_converged) {
      ++ended_by_watch;
      EXPECT_LE(std::abs(theta_w(b) - theta_f(b)), 0.1 * watched.watch_se)
          << watched.message << " / " << full.message;
    }
    watched_iterations += watched.iterations;
    full_iterations += full.iterations;
    estimates.push_back(theta_f(b));
    ses.push_back(watched.watch_se);
  }
  EXPECT_GE(ended_by_watch, 12);
  EXPECT_LT(watched_iterations, full_iterations);
  std::printf("watched fits: %d of 24 ended by the rule, %ld iterations against %ld\n",
              ended_by_watch, watched_iterations, full_iterations);
  double mean = 0.0, var = 0.0, se = 0.0;
  for (double e : estimates) mean += e / 24.0;
  for (double e : estimates) var += (e - mean) * (e - mean) / 23.0;
  for (double s : ses) se += s / 24.0;
  // The sample sd of 24 draws is within a factor 1.5 of the true sd with probability > 0.99.
  EXPECT_GT(std::sqrt(var), se / 1.5);
  EXPECT_LT(std::sqrt(var), se * 1.5);
}

// The rule decided from one prediction: where the Gauss–Newton step's predicted fall of χ² is
// at most converged_se², the fit ends before the trial. That step then moves the damping
// parameter by at most converged_se of its standard error (the Cauchy–Schwarz bound): one more
// step, taken with every rule off, stays within it. A fit restarted where the rule ended it
// ends again at once, θ untouched (no held-out segments: the fit returns its last iterate).
TEST(Shooting, APredictedFallBelowTheBoundEndsTheFitBeforeTheTrial) {
  const auto map = make_one_step_map(nlohmann::json::parse(
      R"({"type":"csympnet","d":1,"core":{"type":"library","terms":["q1^2","q1^4"]}})"));
  const Index b = *map->damping_param_index();
  Rng rng(43, "damping-predicted");
  Vector truth(map->n_params());
  map->init_params(rng, truth);
  truth(2) = 0.05;
  truth(b) = 0.1;
  int ended_by_prediction = 0;
  for (int draw = 0; draw < 12; ++draw) {
    SCOPED_TRACE(draw);
    ShootingSegments train, val;
    train.d = val.d = 1;
    const int count = 10;
    Matrix z_true(2, count);
    for (int k = 0; k < count; ++k) {
      z_true.col(k) = rng.normal_matrix(2, 1, 0.6);
      train.q.push_back(
          shooting_states(*map, truth, z_true.col(k), Vector::Constant(21, 0.1)).topRows(1) +
          rng.normal_matrix(1, 22, 0.01));
      train.h.push_back(Vector::Constant(21, 0.1));
      train.block.push_back(k % 4);
    }
    ShootingOptions opt;
    opt.iterations = 300;
    opt.patience = 300;
    opt.converged_se = 0.01;
    opt.watch_index = b;
    Vector theta = truth;
    Matrix zt = z_true, zv(2, 0);
    const ShootingReport rep = fit_shooting(*map, theta, zt, train, zv, val, opt);
    if (rep.message.find("predicted") == std::string::npos) continue;
    ++ended_by_prediction;
    EXPECT_TRUE(rep.watch_converged);
    // Restarted there: ends before any trial, θ and the start states as they were.
    Vector again = theta;
    Matrix zt2 = zt, zv2 = zv;
    const ShootingReport rep2 = fit_shooting(*map, again, zt2, train, zv2, val, opt);
    EXPECT_EQ(rep2.iterations, 1) << rep2.message;
    EXPECT_EQ(rep2.accepted, 0) << rep2.message;
    EXPECT_EQ(again, theta);
    EXPECT_EQ(zt2, zt);
    // One more step with every rule off moves the damping parameter within the bound.
    ShootingOptions one = opt;
    one.iterations = 1;
    one.watch_index = -1;
    one.converged_se = 0.0;
    Vector next = theta;
    Matrix zt3 = zt, zv3 = zv;
    fit_shooting(*map, next, zt3, train, zv3, val, one);
    EXPECT_LE(std::abs(next(b) - theta(b)), 0.01 * rep.watch_se * (1.0 + 1e-6));
  }
  EXPECT_GE(ended_by_prediction, 6);
}

TEST(Shooting, RefusesMalformedSegments) {
  ShootingSegments s;
  s.d = 1;
  s.q = {Matrix::Zero(1, 1)};  // one position: no step
  s.h = {Vector(0)};
  s.block = {0};
  EXPECT_THROW(s.validate(), Error);
  s.q = {Matrix::Zero(1, 3)};
  s.h = {Vector::Constant(2, -0.1)};
  EXPECT_THROW(s.validate(), Error);
  s.h = {Vector::Constant(2, 0.1)};
  s.validate();
  s.observed = {Vector::Constant(3, 0.5)};  // a weight is 0 or 1
  EXPECT_THROW(s.validate(), Error);
  s.observed = {Vector::Ones(2)};  // one per position
  EXPECT_THROW(s.validate(), Error);
  s.observed.clear();
  s.column_block = {{0, -1, 0}};  // a block index is >= 0
  EXPECT_THROW(s.validate(), Error);
}

}  // namespace
}  // namespace csympnet
