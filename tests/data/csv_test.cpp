// Valid CSV input: round trips, tolerated variations, and how trajectories become pairs.
#include "csympnet/data/csv.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/io/files.hpp"
#include "temp_dir.hpp"

namespace csympnet {
namespace {

using testing::TempDir;

// Bit-level equality, so -0.0 vs 0.0 and last-digit differences are caught.
bool same_matrix_bits(const Matrix& a, const Matrix& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<std::size_t>(a.size())) == 0;
}

// Random values plus ones that break naive formatting (fewer than 17 digits, %f, locale).
Matrix tricky_matrix(Index rows, Index cols, Rng& rng) {
  Matrix m = rng.normal_matrix(rows, cols, 1.0);
  const double special[] = {0.1,
                            -0.0,
                            1.0 / 3.0,
                            1e-300,
                            std::numeric_limits<double>::denorm_min(),
                            std::numeric_limits<double>::max(),
                            -std::numeric_limits<double>::lowest() / 3,
                            123456789012345680.0,
                            std::numbers::pi};
  Index k = 0;
  for (double v : special) m(k % rows, (k / rows) % cols) = v, ++k;
  return m;
}

PairSet tricky_pairs(Index d, Index n, std::uint64_t seed) {
  Rng rng(seed, "csv-test");
  PairSet p;
  p.z0 = tricky_matrix(2 * d, n, rng);
  p.z1 = rng.normal_matrix(2 * d, n, 1e3);
  p.h = rng.uniform_vector(n, 1e-6, 2.0);
  p.h(0) = 0.1;
  // The smallest step a file may hold (a subnormal step is refused: it has lost its digits).
  p.h(n - 1) = std::numeric_limits<double>::min();
  return p;
}

std::vector<Trajectory> tricky_trajectories(Index d, std::uint64_t seed) {
  Rng rng(seed, "csv-test-traj");
  std::vector<Trajectory> trajs;
  for (Index len : {5, 1, 3}) {
    Trajectory tr;
    tr.t = Vector(len);
    double t = -1.0 / 3.0;
    for (Index n = 0; n < len; ++n) tr.t(n) = t += rng.uniform(1e-3, 1.0);
    tr.z = tricky_matrix(2 * d, len, rng);
    trajs.push_back(tr);
  }
  return trajs;
}

class CsvRoundTrip : public ::testing::TestWithParam<Index> {};

TEST_P(CsvRoundTrip, PairsAreBitIdentical) {
  TempDir dir;
  const PairSet p = tricky_pairs(GetParam(), 7, 1);
  write_pairs_csv(dir.file("pairs.csv"), p);
  EXPECT_EQ(detect_csv_kind(dir.file("pairs.csv")), CsvKind::kPairs);
  const PairSet r = read_pairs_csv(dir.file("pairs.csv"));
  EXPECT_TRUE(same_matrix_bits(p.z0, r.z0));
  EXPECT_TRUE(same_matrix_bits(p.z1, r.z1));
  EXPECT_TRUE(same_matrix_bits(p.h, r.h));
  // read_any_as_pairs reads for training: the same bits when every value is within 1e150 in
  // magnitude, else (tricky_pairs includes +-DBL_MAX) a refusal at the value's line.
  const bool trainable = p.z0.cwiseAbs().maxCoeff() <= 1e150 &&
                         p.z1.cwiseAbs().maxCoeff() <= 1e150 && p.h.maxCoeff() <= 1e150;
  if (trainable) {
    EXPECT_TRUE(same_matrix_bits(p.z0, read_any_as_pairs(dir.file("pairs.csv")).z0));
  } else {
    try {
      read_any_as_pairs(dir.file("pairs.csv"));
      ADD_FAILURE() << "read_any_as_pairs accepted a value beyond 1e150";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("too large to train on"), std::string::npos) << e.what();
    }
  }
  PairSet small = p;
  small.z0 = small.z0.cwiseMax(-1e150).cwiseMin(1e150);
  small.z1 = small.z1.cwiseMax(-1e150).cwiseMin(1e150);
  write_pairs_csv(dir.file("small.csv"), small);
  EXPECT_TRUE(same_matrix_bits(small.z0, read_any_as_pairs(dir.file("small.csv")).z0));
  EXPECT_TRUE(same_matrix_bits(small.z1, read_any_as_pairs(dir.file("small.csv")).z1));
}

TEST_P(CsvRoundTrip, TrajectoriesAreBitIdenticalWithAndWithoutTrajColumn) {
  TempDir dir;
  const std::vector<Trajectory> trajs = tricky_trajectories(GetParam(), 2);
  write_trajectories_csv(dir.file("traj.csv"), trajs);
  EXPECT_EQ(detect_csv_kind(dir.file("traj.csv")), CsvKind::kTrajectories);
  const std::vector<Trajectory> r = read_trajectories_csv(dir.file("traj.csv"));
  ASSERT_EQ(r.size(), trajs.size());
  for (std::size_t k = 0; k < r.size(); ++k) {
    EXPECT_TRUE(same_matrix_bits(trajs[k].t, r[k].t)) << k;
    EXPECT_TRUE(same_matrix_bits(trajs[k].z, r[k].z)) << k;
  }

  // Dropping the traj column of the first trajectory's rows gives a one-trajectory file.
  const Trajectory& first = trajs[0];
  write_trajectories_csv(dir.file("one.csv"), {first});
  std::string text = read_text_file(dir.file("one.csv"));
  std::string stripped;
  for (std::size_t pos = 0; pos < text.size();) {
    const std::size_t nl = text.find('\n', pos);
    const std::string line = text.substr(pos, nl - pos);
    stripped += line.substr(line.find(',') + 1) + "\n";
    pos = nl + 1;
  }
  ASSERT_EQ(stripped.substr(0, 2), "t,");
  const std::vector<Trajectory> one = read_trajectories_csv(dir.write("no_traj.csv", stripped));
  ASSERT_EQ(one.size(), 1u);
  EXPECT_TRUE(same_matrix_bits(first.t, one[0].t));
  EXPECT_TRUE(same_matrix_bits(first.z, one[0].z));
}

INSTANTIATE_TEST_SUITE_P(Dims, CsvRoundTrip, ::testing::Values(Index{1}, Index{3}));

TEST(CsvWrite, HeaderAndShortestRoundTripText) {
  TempDir dir;
  PairSet p;
  p.z0 = Matrix::Constant(2, 1, 0.1);
  p.z0(1, 0) = 0.1 + 0.2;  // 0.30000000000000004: needs all 17 digits to read back
  p.z1 = Matrix::Constant(2, 1, -2.0);
  p.h = Vector::Constant(1, 0.5);
  write_pairs_csv(dir.file("p.csv"), p);
  EXPECT_EQ(read_text_file(dir.file("p.csv")),
            "h,q1,p1,next_q1,next_p1\n0.5,0.1,0.30000000000000004,-2,-2\n");
  const PairSet back = read_pairs_csv(dir.file("p.csv"));
  EXPECT_EQ(back.z0, p.z0);
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), {}), 1);
}

TEST(CsvWrite, RefusesInvalidData) {
  TempDir dir;
  PairSet p;
  p.z0 = Matrix::Zero(2, 2);
  p.z1 = Matrix::Zero(2, 2);
  p.h = Vector::Constant(2, 0.1);
  p.h(1) = -0.1;
  EXPECT_THROW(write_pairs_csv(dir.file("p.csv"), p), Error);
  EXPECT_FALSE(std::filesystem::exists(dir.file("p.csv")));
  EXPECT_THROW(write_trajectories_csv(dir.file("t.csv"), {}), Error);
  Trajectory bad;
  bad.t = Vector::LinSpaced(3, 0.0, 1.0);
  bad.t(2) = bad.t(1);
  bad.z = Matrix::Zero(2, 3);
  EXPECT_THROW(write_trajectories_csv(dir.file("t.csv"), {bad}), Error);
  try {
    write_pairs_csv(dir.file("missing_dir/p.csv"), tricky_pairs(1, 2, 3));
    FAIL() << "no Error for a missing directory";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("missing_dir/p.csv"), std::string::npos) << e.what();
  }
}

TEST(CsvRead, ToleratesWhitespaceCrlfBlankTrailingLinesBomAndPlus) {
  TempDir dir;
  const std::string path = dir.write(
      "ok.csv",
      "\xEF\xBB\xBF h , q1,p1 ,next_q1,\tnext_p1\r\n 0.25 ,1, -2e0,+3.5,.5\r\n0.5,1,2,3,4\r\n\r\n "
      " \n\n");
  const PairSet p = read_pairs_csv(path);
  ASSERT_EQ(p.size(), 2);
  EXPECT_EQ(p.h(0), 0.25);
  EXPECT_EQ(p.z0(1, 0), -2.0);
  EXPECT_EQ(p.z1(0, 0), 3.5);
  EXPECT_EQ(p.z1(1, 0), 0.5);
  EXPECT_EQ(p.z1(1, 1), 4.0);
  // No trailing newline at all is fine too.
  EXPECT_EQ(read_pairs_csv(dir.write("nonl.csv", "h,q1,p1,next_q1,next_p1\n1,2,3,4,5")).h(0), 1.0);
}

TEST(CsvRead, IrregularStepsBecomeExactPairsWithinEachTrajectory) {
  TempDir dir;
  // Times are dyadic, so every difference is exact in binary floating point.
  const std::string path = dir.write("irr.csv",
                                     "traj,t,q1,p1\n"
                                     "7,0,0,10\n7,0.5,1,11\n7,0.75,2,12\n7,2,3,13\n"
                                     "3,10,100,200\n"
                                     "4,-1,50,60\n4,-0.875,51,61\n");
  const std::vector<Trajectory> trajs = read_trajectories_csv(path);
  ASSERT_EQ(trajs.size(), 3u);  // in file order: ids 7, 3, 4
  EXPECT_EQ(trajs[0].t.size(), 4);
  EXPECT_EQ(trajs[1].t.size(), 1);
  EXPECT_EQ(trajs[2].t(0), -1.0);

  const PairSet p = read_any_as_pairs(path);
  ASSERT_EQ(p.size(), 4);  // 3 + 0 + 1: nothing across trajectory boundaries
  const double h[] = {0.5, 0.25, 1.25, 0.125};
  const double q0[] = {0, 1, 2, 50}, q1[] = {1, 2, 3, 51};
  for (Index j = 0; j < 4; ++j) {
    EXPECT_EQ(p.h(j), h[j]) << j;
    EXPECT_EQ(p.z0(0, j), q0[j]) << j;
    EXPECT_EQ(p.z1(0, j), q1[j]) << j;
    EXPECT_EQ(p.z1(1, j) - p.z0(1, j), 1.0) << j;
  }
}

TEST(CsvRead, DetectsKindFromHeader) {
  TempDir dir;
  EXPECT_EQ(detect_csv_kind(dir.write("a.csv", "h,q1,q2,p1,p2,next_q1,next_q2,next_p1,next_p2\n")),
            CsvKind::kPairs);
  EXPECT_EQ(detect_csv_kind(dir.write("b.csv", "t,q1,p1\n")), CsvKind::kTrajectories);
  EXPECT_EQ(detect_csv_kind(dir.write("c.csv", "traj,t,q1,q2,p1,p2\n1,2,3,4,5,6\n")),
            CsvKind::kTrajectories);
}

// Positions alone: a trajectories file without p columns is its own kind, read as d rows per
// sample by parse_positions_csv; the states reader refuses it and names the positions route;
// a pairs file cannot be positions alone (a pair needs a state).
TEST(CsvRead, PositionsAloneAreTheirOwnKind) {
  TempDir dir;
  EXPECT_EQ(detect_csv_kind(dir.write("q.csv", "traj,t,q1\n0,0,1\n0,1,2\n")), CsvKind::kPositions);
  EXPECT_EQ(detect_csv_kind(dir.write("q2.csv", "t,q1,q2\n0,1,2\n")), CsvKind::kPositions);
  const CsvInput in =
      read_csv_input(dir.write("q3.csv", "traj,t,q1,q2\n0,0,1,2\n0,1,3,4\n1,0,5,6\n"));
  ASSERT_EQ(in.kind, CsvKind::kPositions);
  const std::vector<Trajectory> trajs = parse_positions_csv(in.text, in.name);
  ASSERT_EQ(trajs.size(), 2U);
  ASSERT_EQ(trajs[0].z.rows(), 2);
  ASSERT_EQ(trajs[0].z.cols(), 2);
  EXPECT_EQ(trajs[0].z(0, 1), 3.0);
  EXPECT_EQ(trajs[0].z(1, 1), 4.0);
  EXPECT_EQ(trajs[1].t(0), 0.0);
  try {
    parse_trajectories_csv(in.text, in.name);
    ADD_FAILURE() << "the states reader accepted positions alone";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("has positions but no momenta"), std::string::npos) << m;
    EXPECT_NE(m.find("hidden states"), std::string::npos) << m;
    EXPECT_NE(m.find("q3.csv"), std::string::npos) << m;
  }
  // The positions reader refuses states, and a pairs file of positions is refused with the
  // reason and the trajectories form that works.
  const CsvInput states = read_csv_input(dir.write("s.csv", "t,q1,p1\n0,1,2\n"));
  EXPECT_THROW(parse_positions_csv(states.text, states.name), Error);
  try {
    read_csv_input(dir.write("pq.csv", "h,q1,next_q1\n0.1,1,2\n"));
    ADD_FAILURE() << "accepted a pairs file of positions";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("a pair needs a whole state"), std::string::npos) << m;
    EXPECT_NE(m.find("[traj,]t,q1..qd"), std::string::npos) << m;
    EXPECT_NE(m.find("pq.csv"), std::string::npos) << m;
  }
  // Positions keep the other rules: times strictly increase.
  const CsvInput back = read_csv_input(dir.write("b.csv", "t,q1\n0,1\n0,2\n"));
  EXPECT_THROW(parse_positions_csv(back.text, back.name), Error);
}

}  // namespace
}  // namespace csympnet
