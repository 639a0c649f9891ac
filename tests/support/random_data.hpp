// Random operands for the bit-for-bit tests: seeded, so every run compares the same values.
#pragma once

#include <cmath>
#include <random>

#include "csympnet/core/types.hpp"
#include "csympnet/data/dataset.hpp"

namespace csympnet::testing {

// rows x cols, entries scale·N(0, 1).
inline Matrix random_matrix(std::mt19937_64& gen, Index rows, Index cols, double scale = 1.0) {
  std::normal_distribution<double> normal;
  Matrix m(rows, cols);
  for (Index i = 0; i < m.size(); ++i) m.data()[i] = scale * normal(gen);
  return m;
}

// n pairs of dimension dim with N(0, 1) states and steps 0.05 + 0.2|N(0, 1)|.
inline PairSet random_pairs(Index dim, Index n, std::mt19937_64& gen) {
  std::normal_distribution<double> normal;
  PairSet p;
  p.z0 = random_matrix(gen, dim, n);
  p.z1 = random_matrix(gen, dim, n);
  p.h.resize(n);
  for (Index j = 0; j < n; ++j) p.h(j) = 0.05 + 0.2 * std::abs(normal(gen));
  return p;
}

}  // namespace csympnet::testing
