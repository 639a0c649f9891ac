#include "csympnet/core/dense.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "csympnet/core/rng.hpp"

namespace csympnet {
namespace {

// wᵀy is the least-squares solution's first entry for every y, at random full-rank matrices of
// random shapes (rows ≥ columns), against column-pivoting QR's solution.
TEST(Dense, FirstCoefficientWeightsGiveTheLeastSquaresFirstEntry) {
  Rng rng(7, "first-coefficient-weights");
  for (int trial = 0; trial < 200; ++trial) {
    const Index cols = 1 + static_cast<Index>(rng.uniform() * 5.0);
    const Index rows = cols + static_cast<Index>(rng.uniform() * 12.0);
    const Matrix a = rng.normal_matrix(rows, cols, 1.0);
    const Vector w = dense::first_coefficient_weights(a);
    ASSERT_EQ(w.size(), rows);
    for (int k = 0; k < 3; ++k) {
      const Vector y = rng.normal_matrix(rows, 1, 1.0).col(0);
      const double x0 = dense::least_squares(a, y)(0);
      EXPECT_NEAR(w.dot(y), x0, 1e-9 * std::max(1.0, std::abs(x0)))
          << "trial " << trial << ": " << rows << " x " << cols;
    }
  }
}

// On the rows of a local polynomial (powers of irregular times around 0), the weights
// reproduce any polynomial of that degree at 0 exactly (to rounding), and sum to 1.
TEST(Dense, FirstCoefficientWeightsInterpolatePolynomialsAtTheCentre) {
  Rng rng(8, "centre-polynomials");
  for (int trial = 0; trial < 100; ++trial) {
    const Index k = 2 + static_cast<Index>(rng.uniform() * 7.0);
    const Index deg = std::min<Index>(4, 2 * k - 2);
    Matrix v(2 * k, deg + 1);
    Vector tau(2 * k);
    for (Index j = 0; j < 2 * k; ++j) {
      const double side = j < k ? -1.0 : 1.0;
      const Index step = j < k ? k - j : j - k + 1;
      tau(j) =
          side * (static_cast<double>(step) + rng.uniform(-0.3, 0.3)) / static_cast<double>(2 * k);
      double power = 1.0;
      for (Index m = 0; m <= deg; ++m, power *= tau(j)) v(j, m) = power;
    }
    const Vector w = dense::first_coefficient_weights(v);
    EXPECT_NEAR(w.sum(), 1.0, 1e-12) << "trial " << trial;
    const Vector c = rng.normal_matrix(deg + 1, 1, 1.0).col(0);
    const Vector y = v * c;
    EXPECT_NEAR(w.dot(y), c(0), 1e-11 * c.cwiseAbs().maxCoeff()) << "trial " << trial;
  }
}

}  // namespace
}  // namespace csympnet
