#include "csympnet/data/dataset.hpp"

#include <gtest/gtest.h>

#include <limits>

#include "csympnet/core/error.hpp"

namespace csympnet {
namespace {

PairSet make_pairs(Index d, Index n, double offset = 0.0) {
  PairSet p;
  p.z0 = Matrix::Zero(2 * d, n);
  p.z1 = Matrix::Zero(2 * d, n);
  p.h = Vector::Constant(n, 0.1);
  for (Index j = 0; j < n; ++j) {
    p.z0.col(j).setConstant(offset + static_cast<double>(j));
    p.z1.col(j).setConstant(-offset - static_cast<double>(j));
    p.h(j) = 0.1 * static_cast<double>(j + 1);
  }
  return p;
}

std::string message_of(const PairSet& p, const std::string& where = "pairs") {
  try {
    p.validate(where);
  } catch (const Error& e) {
    return e.what();
  }
  return "<no error>";
}

TEST(PairSetValidate, AcceptsGoodData) {
  EXPECT_NO_THROW(make_pairs(2, 4).validate());
}

TEST(PairSetValidate, NamesWhatIsWrong) {
  PairSet p = make_pairs(1, 4);
  p.h(3) = -0.1;
  EXPECT_EQ(message_of(p), "pairs: h[3] = -0.1 must be > 0");

  p = make_pairs(1, 4);
  p.h(0) = 0.0;
  EXPECT_NE(message_of(p, "train").find("train: h[0] = 0 must be > 0"), std::string::npos);

  p = make_pairs(1, 4);
  p.z1(1, 2) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(message_of(p).find("z1(1, 2) = nan; expected a finite value"), std::string::npos);

  p = make_pairs(1, 4);
  p.h(1) = std::numeric_limits<double>::infinity();
  EXPECT_NE(message_of(p).find("h[1] = inf; expected a finite"), std::string::npos);

  p = make_pairs(1, 4);
  p.z1 = Matrix::Zero(2, 3);
  EXPECT_NE(message_of(p).find("z0 is 2x4 but z1 is 2x3"), std::string::npos);

  p = make_pairs(1, 4);
  p.z0 = Matrix::Zero(3, 4);
  p.z1 = Matrix::Zero(3, 4);
  EXPECT_NE(message_of(p).find("z0 has 3 rows; expected an even number"), std::string::npos);

  p = make_pairs(1, 4);
  p.h = Vector::Constant(5, 0.1);
  EXPECT_NE(message_of(p).find("h has length 5; expected N = 4"), std::string::npos);

  EXPECT_NE(message_of(make_pairs(1, 0)).find("no pairs"), std::string::npos);
  EXPECT_NE(message_of(PairSet{}).find("rows"), std::string::npos);
}

TEST(SelectPairs, KeepsColumnsInGivenOrder) {
  const PairSet p = make_pairs(2, 5);
  const PairSet s = select_pairs(p, {4, 0, 4});
  ASSERT_EQ(s.size(), 3);
  EXPECT_EQ(s.z0(0, 0), 4.0);
  EXPECT_EQ(s.z1(3, 1), 0.0);
  EXPECT_EQ(s.h(2), p.h(4));
  EXPECT_THROW(select_pairs(p, {5}), Error);
  EXPECT_THROW(select_pairs(p, {-1}), Error);
}

TEST(ConcatPairs, JoinsInOrderAndRejectsDimensionMismatch) {
  const PairSet c = concat_pairs({make_pairs(1, 2), make_pairs(1, 3, 10.0)});
  ASSERT_EQ(c.size(), 5);
  EXPECT_EQ(c.z0(0, 1), 1.0);
  EXPECT_EQ(c.z0(0, 2), 10.0);
  EXPECT_EQ(c.z1(1, 4), -12.0);
  EXPECT_DOUBLE_EQ(c.h(4), 0.3);
  EXPECT_THROW(concat_pairs({make_pairs(1, 2), make_pairs(2, 2)}), Error);
  EXPECT_THROW(concat_pairs({}), Error);
}

Trajectory traj(std::vector<double> t, double q0) {
  Trajectory tr;
  tr.t = Eigen::Map<Vector>(t.data(), static_cast<Index>(t.size()));
  tr.z = Matrix::Zero(2, tr.t.size());
  for (Index n = 0; n < tr.t.size(); ++n) tr.z.col(n) << q0 + static_cast<double>(n), -q0;
  return tr;
}

TEST(PairsFromTrajectories, IrregularStepsAndNoPairAcrossBoundaries) {
  const PairSet p = pairs_from_trajectories(
      {traj({0.0, 0.5, 0.75, 2.0}, 0.0), traj({3.0}, 100.0), traj({-1.0, -0.875}, 50.0)});
  ASSERT_EQ(p.size(), 4);
  const double h[] = {0.5, 0.25, 1.25, 0.125};
  for (Index j = 0; j < 4; ++j) EXPECT_EQ(p.h(j), h[j]);
  EXPECT_EQ(p.z0(0, 2), 2.0);
  EXPECT_EQ(p.z1(0, 2), 3.0);
  EXPECT_EQ(p.z0(0, 3), 50.0);  // starts the third trajectory, not the end of the first
  EXPECT_EQ(p.z1(1, 3), -50.0);
}

TEST(PairsFromTrajectories, RejectsBadInput) {
  EXPECT_THROW(pairs_from_trajectories({}), Error);
  EXPECT_THROW(pairs_from_trajectories({traj({1.0}, 0.0), traj({2.0}, 0.0)}), Error);
  EXPECT_THROW(pairs_from_trajectories({traj({0.0, 1.0, 1.0}, 0.0)}), Error);
  Trajectory wide = traj({0.0, 1.0}, 0.0);
  wide.z = Matrix::Zero(4, 2);
  EXPECT_THROW(pairs_from_trajectories({traj({0.0, 1.0}, 0.0), wide}), Error);
  Trajectory ragged = traj({0.0, 1.0}, 0.0);
  ragged.z = Matrix::Zero(2, 3);
  EXPECT_THROW(pairs_from_trajectories({ragged}), Error);
  try {
    pairs_from_trajectories({traj({0.0, 1.0, 0.5}, 0.0)});
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("trajectory 0: t[2] = 0.5 is not greater than t[1]"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace csympnet
