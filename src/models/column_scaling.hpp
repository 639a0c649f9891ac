// Internal to src/models: the per-column scalings through which a sample's step h_j (or its
// conformal factor a_j) enters the cores, one column at a time. Eigen's `.rowwise() * hᵀ`
// broadcasts have no packet access and run element by element; per column, each is an
// array times a scalar, which Eigen vectorises. Each element gets the same IEEE operations in
// the same order as in the broadcast expression named beside each function.
#pragma once

#include "csympnet/core/types.hpp"

namespace csympnet::detail {

// out = x.array().rowwise() * hᵀ   (h: x.cols() contiguous values)
template <typename X, typename Out>
void columns_times(const Eigen::MatrixBase<X>& x, const double* h,
                   const Eigen::MatrixBase<Out>& out_) {
  auto& out = const_cast<Eigen::MatrixBase<Out>&>(out_);  // Eigen's idiom for writable blocks
  for (Index j = 0; j < x.cols(); ++j) out.col(j).array() = x.col(j).array() * h[j];
}

// x.array().rowwise() *= hᵀ
template <typename X>
void scale_columns(const Eigen::MatrixBase<X>& x_, const double* h) {
  auto& x = const_cast<Eigen::MatrixBase<X>&>(x_);
  for (Index j = 0; j < x.cols(); ++j) x.col(j).array() *= h[j];
}

// out = (x.array().colwise() * a).rowwise() * hᵀ   (a: an array of x.rows() values)
template <typename X, typename A, typename Out>
void columns_times_scaled(const Eigen::MatrixBase<X>& x, const A& a, const double* h,
                          const Eigen::MatrixBase<Out>& out_) {
  auto& out = const_cast<Eigen::MatrixBase<Out>&>(out_);
  for (Index j = 0; j < x.cols(); ++j) out.col(j).array() = (x.col(j).array() * a) * h[j];
}

// out.array() += (x.array().colwise() * a).rowwise() * hᵀ
template <typename X, typename A, typename Out>
void add_columns_times_scaled(const Eigen::MatrixBase<X>& x, const A& a, const double* h,
                              const Eigen::MatrixBase<Out>& out_) {
  auto& out = const_cast<Eigen::MatrixBase<Out>&>(out_);
  for (Index j = 0; j < x.cols(); ++j) out.col(j).array() += (x.col(j).array() * a) * h[j];
}

}  // namespace csympnet::detail
