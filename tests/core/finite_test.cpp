#include "csympnet/core/finite.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "csympnet/core/rng.hpp"
#include "csympnet/core/types.hpp"

namespace csympnet {
namespace {

// all_finite agrees with Eigen's allFinite() at random shapes and storage orders, with ±∞ or NaN
// at a random entry or none, among entries of every size up to the largest double (whose sum
// would overflow: the test must not be a sum of the entries).
TEST(Finite, AllFiniteAgreesWithEigensAllFinite) {
  Rng rng(11, "all-finite");
  const double specials[] = {std::numeric_limits<double>::infinity(),
                             -std::numeric_limits<double>::infinity(),
                             std::numeric_limits<double>::quiet_NaN()};
  int non_finite = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const Index rows = static_cast<Index>(rng.uniform() * 40.0);
    const Index cols = static_cast<Index>(rng.uniform() * 40.0);
    Matrix a = rng.normal_matrix(rows, cols, 1.0);
    const double magnitude = std::pow(10.0, -300.0 + 608.0 * rng.uniform());
    a *= magnitude;
    if (a.size() > 0 && rng.uniform() < 0.3)
      a(static_cast<Index>(rng.uniform() * static_cast<double>(rows)),
        static_cast<Index>(rng.uniform() * static_cast<double>(cols))) =
          std::numeric_limits<double>::max();
    if (a.size() > 0 && rng.uniform() < 0.5) {
      a(static_cast<Index>(rng.uniform() * static_cast<double>(rows)),
        static_cast<Index>(rng.uniform() * static_cast<double>(cols))) =
          specials[static_cast<int>(rng.uniform() * 3.0) % 3];
    }
    const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> row_major = a;
    non_finite += a.allFinite() ? 0 : 1;
    ASSERT_EQ(all_finite(a), a.allFinite()) << "trial " << trial << ": " << rows << " x " << cols;
    ASSERT_EQ(all_finite(row_major), a.allFinite()) << "trial " << trial;
    const Eigen::Map<const Vector> flat(a.data(), a.size());
    ASSERT_EQ(all_finite(flat), a.allFinite()) << "trial " << trial;
  }
  EXPECT_GT(non_finite, 100);  // both answers were exercised
  EXPECT_LT(non_finite, 300);
}

}  // namespace
}  // namespace csympnet
