// Deterministic random numbers, identical on every platform and compiler.
//
// The standard distributions (std::normal_distribution, ...) are implementation-defined, so
// the same seed could give different data on another standard library. Rng therefore draws
// raw 64-bit words from std::mt19937_64 (fully specified by the standard) and maps them to
// uniforms and normals with fixed formulas of its own.
#pragma once

#include <cstdint>
#include <random>
#include <string_view>

#include "csympnet/core/types.hpp"

namespace csympnet {

class Rng {
 public:
  // A stream is named by (seed, purpose): Rng(42, "train-data") and Rng(42, "init") are
  // independent, and adding a new purpose never shifts an existing stream.
  explicit Rng(std::uint64_t seed, std::string_view purpose = "");

  std::uint64_t next_u64() { return engine_(); }
  // Uniform in [0, 1) with 53 random bits.
  double uniform();
  // Uniform in [lo, hi).
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  // Standard normal, Marsaglia's polar method (pairs cached).
  double normal();
  double normal(double mean, double stddev) { return mean + stddev * normal(); }

  Vector uniform_vector(Index n, double lo, double hi);
  Matrix uniform_matrix(Index rows, Index cols, double lo, double hi);
  Matrix normal_matrix(Index rows, Index cols, double stddev);

 private:
  std::mt19937_64 engine_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

}  // namespace csympnet
