// Bit-for-bit comparison, for the tests that hold an optimised path to the code it replaced:
// same shape and the same bytes (so −0 ≠ +0, and a NaN equals only the same NaN).
#pragma once

#include <cstddef>
#include <cstring>

namespace csympnet::testing {

template <typename A, typename B>
bool same_bits(const A& a, const B& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         std::memcmp(a.data(), b.data(), static_cast<std::size_t>(a.size()) * sizeof(double)) == 0;
}

inline bool same_bits(double a, double b) {
  return std::memcmp(&a, &b, sizeof(double)) == 0;
}

}  // namespace csympnet::testing
