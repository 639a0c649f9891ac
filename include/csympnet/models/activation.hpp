// Small helpers shared by the SympNet cores: the sigmoid activation and the per-column
// step scaling through which h enters every increment.
#pragma once

#include <cmath>

#include "csympnet/core/types.hpp"

namespace csympnet {

// σ(x) = 1 / (1 + e^{-x}), evaluated without overflow: for x < 0 the equivalent
// e^{x} / (1 + e^{x}) is used, so exp() only ever sees a non-positive argument.
inline double sigmoid(double x) {
  if (x >= 0.0) return 1.0 / (1.0 + std::exp(-x));
  const double e = std::exp(x);
  return e / (1.0 + e);
}

// out = σ(x) elementwise (out may not alias x). Same stable formula as sigmoid(), written
// with whole-array operations so that Eigen vectorises exp():
//   e = exp(−|x|),  σ(x) = 1/(1+e) for x ≥ 0,  e/(1+e) for x < 0.
template <typename In>
void sigmoid_into(const Eigen::MatrixBase<In>& x, Matrix& out) {
  out = (-x.array().abs()).exp().matrix();
  out.array() =
      (x.array() >= 0.0).select(1.0 / (1.0 + out.array()), out.array() / (1.0 + out.array()));
}

// σ'(x) = σ(x)(1 − σ(x)), written in terms of the cached s = σ(x).
template <typename In>
auto sigmoid_derivative_from_value(const Eigen::MatrixBase<In>& s) {
  return (s.array() * (1.0 - s.array())).matrix();
}

// M(:, j) *= h(j): the step of sample j multiplies column j.
template <typename Derived>
void scale_columns(Eigen::MatrixBase<Derived>& m, const Vector& h) {
  m.array().rowwise() *= h.transpose().array();
}

// out = A B. When A has few rows or a short inner dimension (d = 1 cores), Eigen's blocked
// GEMM costs more than the arithmetic, so the coefficient-based lazy product is used there.
template <typename ADerived, typename BDerived>
void product_into(const Eigen::MatrixBase<ADerived>& a, const Eigen::MatrixBase<BDerived>& b,
                  Matrix& out) {
  constexpr Index kLazyBelow = 8;
  if (a.rows() == 1 && a.cols() == 1) {
    out.noalias() = a.coeff(0, 0) * b;  // d = 1: S is a scalar
  } else if (a.rows() == 1 && b.cols() == 1) {
    out.resize(1, 1);
    out(0, 0) = a.row(0).dot(b.col(0));  // d = 1: an inner product over the batch
  } else if (a.rows() < kLazyBelow || a.cols() < kLazyBelow) {
    out.noalias() = a.lazyProduct(b);
  } else {
    out.noalias() = a * b;
  }
}

}  // namespace csympnet
