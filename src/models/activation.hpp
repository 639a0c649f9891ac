// Internal to src/models: small helpers shared by the SympNet cores (the sigmoid activation,
// the per-column step scaling through which h enters every increment, the products).
#pragma once

#include <cmath>

#include "../kernels/sigmoid.hpp"
#include "csympnet/core/types.hpp"

namespace csympnet {

// σ(x) = 1 / (1 + e^{-x}), evaluated without overflow: for x < 0 the equivalent
// e^{x} / (1 + e^{x}) is used, so exp() only ever sees a non-positive argument.
inline double sigmoid(double x) {
  if (x >= 0.0) return 1.0 / (1.0 + std::exp(-x));
  const double e = std::exp(x);
  return e / (1.0 + e);
}

namespace detail {
// Whether sigmoid_into() may hand x of type In to kernels::sigmoid_simd(): the kernel assumes
// Eigen's linear traversal (packets from element 0, an odd last element alone), which Eigen uses
// when x's *evaluator* allows linear access (matrices, maps, whole columns). The expression's own
// Flags never carry LinearAccessBit, so they cannot be used for this test.
template <typename In>
constexpr bool sigmoid_kernel_applies() {
  constexpr int kEval = static_cast<int>(Eigen::internal::evaluator<In>::Flags);
  constexpr int kLinear = Eigen::DirectAccessBit | Eigen::LinearAccessBit;
  return (kEval & kLinear) == kLinear && !(kEval & Eigen::RowMajorBit);
}
}  // namespace detail

namespace detail {
// Whether x's storage is one contiguous column-major run of x.size() values.
template <typename Derived>
bool contiguous(const Eigen::MatrixBase<Derived>& x) {
  const auto& xe = x.derived();
  return xe.innerStride() == 1 && (xe.outerStride() == xe.rows() || xe.cols() == 1);
}
}  // namespace detail

// out = σ(x) elementwise into out, a matrix of x's shape or a writable block or map of one
// (out may not alias x). Same stable formula as sigmoid(), written with whole-array operations
// so that Eigen vectorises exp():
//   e = exp(−|x|),  σ(x) = n/(1+e) with n = 1 for x ≥ 0, n = e for x < 0.
// The numerator is picked first and divided once (Eigen's select() is not vectorised and
// would evaluate both quotients); the quotient is the same IEEE division either way.
template <typename In, typename Out>
void sigmoid_to(const Eigen::MatrixBase<In>& x, const Eigen::MatrixBase<Out>& out_) {
  auto& out = const_cast<Eigen::MatrixBase<Out>&>(out_).derived();  // Eigen's idiom for blocks
  const auto& xe = x.derived();
  constexpr int kInFlags = static_cast<int>(In::Flags);
  constexpr int kOutFlags = static_cast<int>(Out::Flags);
  constexpr bool kDirect =
      (kInFlags & Eigen::DirectAccessBit) && !(kInFlags & Eigen::RowMajorBit) &&
      (kOutFlags & Eigen::DirectAccessBit) && !(kOutFlags & Eigen::RowMajorBit);
  if constexpr (detail::sigmoid_kernel_applies<In>() && kDirect) {
    if (detail::contiguous(x) && detail::contiguous(out) &&
        kernels::sigmoid_simd(xe.data(), out.data(), out.size())) {
      return;
    }
  }
  out = (-x.array().abs()).exp().matrix();
  if constexpr (kDirect) {
    // Contiguous column-major x and out: element j of both is the same (r, c).
    if (detail::contiguous(x) && detail::contiguous(out)) {
      namespace ei = Eigen::internal;
      using Packet = ei::packet_traits<double>::type;
      constexpr Index kSize = ei::packet_traits<double>::size;
      const Index n = out.size();
      double* o = out.data();
      const double* xp = xe.data();
      const Packet one = ei::pset1<Packet>(1.0);
      const Packet zero = ei::pset1<Packet>(0.0);
      Index j = 0;
      for (; j + kSize <= n; j += kSize) {
        const Packet e = ei::ploadu<Packet>(o + j);
        const Packet num = ei::pselect(ei::pcmp_le(zero, ei::ploadu<Packet>(xp + j)), one, e);
        ei::pstoreu(o + j, ei::pdiv(num, ei::padd(one, e)));
      }
      for (; j < n; ++j) o[j] = (xp[j] >= 0.0 ? 1.0 : o[j]) / (1.0 + o[j]);
      return;
    }
  }
  for (Index c = 0; c < out.cols(); ++c) {
    for (Index r = 0; r < out.rows(); ++r) {
      double& v = out(r, c);
      v = (x(r, c) >= 0.0 ? 1.0 : v) / (1.0 + v);
    }
  }
}

// sigmoid_to() into a matrix resized to x's shape.
template <typename In>
void sigmoid_into(const Eigen::MatrixBase<In>& x, Matrix& out) {
  out.resize(x.rows(), x.cols());
  sigmoid_to(x, out);
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
