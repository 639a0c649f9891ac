#include "csympnet/core/rng.hpp"

#include <cmath>

namespace csympnet {

namespace {
// SplitMix64 finaliser: decorrelates nearby seeds before they reach the Mersenne Twister.
std::uint64_t mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// FNV-1a: a stable hash of the purpose string.
std::uint64_t hash(std::string_view s) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (char c : s) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001b3ULL;
  }
  return h;
}
}  // namespace

Rng::Rng(std::uint64_t seed, std::string_view purpose) : engine_(mix(mix(seed) ^ hash(purpose))) {}

double Rng::uniform() {
  return static_cast<double>(engine_() >> 11) * 0x1.0p-53;
}

double Rng::normal() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  double u, v, s;
  do {
    u = 2.0 * uniform() - 1.0;
    v = 2.0 * uniform() - 1.0;
    s = u * u + v * v;
  } while (s >= 1.0 || s == 0.0);
  const double f = std::sqrt(-2.0 * std::log(s) / s);
  spare_ = v * f;
  has_spare_ = true;
  return u * f;
}

Vector Rng::uniform_vector(Index n, double lo, double hi) {
  Vector x(n);
  for (Index i = 0; i < n; ++i) x(i) = uniform(lo, hi);
  return x;
}

Matrix Rng::uniform_matrix(Index rows, Index cols, double lo, double hi) {
  Matrix x(rows, cols);
  for (Index j = 0; j < cols; ++j)
    for (Index i = 0; i < rows; ++i) x(i, j) = uniform(lo, hi);
  return x;
}

Matrix Rng::normal_matrix(Index rows, Index cols, double stddev) {
  Matrix x(rows, cols);
  for (Index j = 0; j < cols; ++j)
    for (Index i = 0; i < rows; ++i) x(i, j) = stddev * normal();
  return x;
}

}  // namespace csympnet
