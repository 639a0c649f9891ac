// Internal to src: the per-column scalings through which a sample's step h_j (or its
// conformal factor a_j) enters the cores. Each element gets the IEEE operations, in the
// order, of the Eigen broadcast expression named beside each function; they are single
// multiplies and adds, so the result does not depend on how elements are grouped into
// registers. Why not the expressions: Eigen's `.rowwise() * hᵀ` broadcasts have no packet
// access and run element by element, and per column (10 rows at d = 10) the loop overhead
// outweighs the arithmetic; the AVX-512 kernels of column_scaling_avx512.cpp handle a column in one
// or two registers (the AVX2 ones of column_scaling_avx2.cpp in two or three). Blocks must be whole
// columns of a column-major matrix (outer stride = rows); others take the per-column Eigen loop.
#pragma once

#include <cstring>

#include "csympnet/core/types.hpp"

namespace csympnet::kernels {

// Raw kernels on m x n column-major arrays with leading dimension m (a: m values, h: n
// values); false when the column_scaling family does not run now (registry.hpp; nothing
// written).
bool columns_times_simd(Index m, Index n, const double* x, const double* h, double* out);
bool columns_times_scaled_simd(Index m, Index n, const double* x, const double* a, const double* h,
                               double* out, bool accumulate);
bool add_outer_simd(Index m, Index n, const double* b, const double* h, double* out);

// Their AVX2 forms, without asking the registry (only where Family::kColumnScalingAvx2 is
// available()).
void columns_times_avx2(Index m, Index n, const double* x, const double* h, double* out);
void columns_times_scaled_avx2(Index m, Index n, const double* x, const double* a, const double* h,
                               double* out, bool accumulate);
void add_outer_avx2(Index m, Index n, const double* b, const double* h, double* out);

template <typename M>
bool whole_columns(const Eigen::MatrixBase<M>& x) {
  return x.derived().innerStride() == 1 && x.derived().outerStride() == x.rows();
}

// out = x for blocks of whole columns: one run of memory each, copied by memcpy (glibc's
// copies with the widest vectors; Eigen's loop, in the portable build, 16 bytes at a time).
template <typename X, typename Out>
void copy_columns(const Eigen::MatrixBase<X>& x, const Eigen::MatrixBase<Out>& out_) {
  auto& out = const_cast<Eigen::MatrixBase<Out>&>(out_);
  if (whole_columns(x) && whole_columns(out)) {
    std::memcpy(out.derived().data(), x.derived().data(),
                static_cast<std::size_t>(x.size()) * sizeof(double));
  } else {
    out = x;
  }
}

// out = x.array().rowwise() * hᵀ   (h: x.cols() contiguous values; out may be x itself)
template <typename X, typename Out>
void columns_times(const Eigen::MatrixBase<X>& x, const double* h,
                   const Eigen::MatrixBase<Out>& out_) {
  auto& out = const_cast<Eigen::MatrixBase<Out>&>(out_);  // Eigen's idiom for writable blocks
  if (whole_columns(x) && whole_columns(out) &&
      columns_times_simd(x.rows(), x.cols(), x.derived().data(), h, out.derived().data())) {
    return;
  }
  for (Index j = 0; j < x.cols(); ++j) out.col(j).array() = x.col(j).array() * h[j];
}

// x.array().rowwise() *= hᵀ
template <typename X>
void scale_columns(const Eigen::MatrixBase<X>& x, const double* h) {
  columns_times(x, h, x);
}

// out = (x.array().colwise() * a).rowwise() * hᵀ, or out += it with `accumulate`
// (a: x.rows() contiguous values).
template <typename X, typename Out>
void columns_times_scaled(const Eigen::MatrixBase<X>& x, const double* a, const double* h,
                          const Eigen::MatrixBase<Out>& out_, bool accumulate = false) {
  auto& out = const_cast<Eigen::MatrixBase<Out>&>(out_);
  if (whole_columns(x) && whole_columns(out) &&
      columns_times_scaled_simd(x.rows(), x.cols(), x.derived().data(), a, h, out.derived().data(),
                                accumulate)) {
    return;
  }
  const auto av = Eigen::Map<const Eigen::ArrayXd>(a, x.rows());
  for (Index j = 0; j < x.cols(); ++j) {
    if (accumulate) {
      out.col(j).array() += (x.col(j).array() * av) * h[j];
    } else {
      out.col(j).array() = (x.col(j).array() * av) * h[j];
    }
  }
}

// out.noalias() += b * hᵀ (b: out.rows() values, h: out.cols()): Eigen's outer product adds
// h_j b to column j, so each element is out + h_j b_i.
template <typename Out>
void add_outer(const double* b, const double* h, const Eigen::MatrixBase<Out>& out_) {
  auto& out = const_cast<Eigen::MatrixBase<Out>&>(out_);
  if (whole_columns(out) && add_outer_simd(out.rows(), out.cols(), b, h, out.derived().data())) {
    return;
  }
  const auto bv = Eigen::Map<const Vector>(b, out.rows());
  for (Index j = 0; j < out.cols(); ++j) out.col(j) += h[j] * bv;
}

// out.array() += (x.array().colwise() * a).rowwise() * hᵀ
template <typename X, typename Out>
void add_columns_times_scaled(const Eigen::MatrixBase<X>& x, const double* a, const double* h,
                              const Eigen::MatrixBase<Out>& out) {
  columns_times_scaled(x, a, h, out, true);
}

}  // namespace csympnet::kernels
