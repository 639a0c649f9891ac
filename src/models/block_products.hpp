// Internal to src/models: the SympNet cores' products with a destination that may be a block
// of columns of a larger matrix (the column-split passes write their range of a batch in
// place), through the exact kernels of exact_product.hpp where they run and Eigen's product
// otherwise, to the bit as the Eigen expression in each comment.
#pragma once

#include "exact_product.hpp"

namespace csympnet::detail {

// out = a b, as `product_into(a, b, t); out = t;`. out: m x n, column-major, outer stride m.
template <typename ADerived, typename BDerived, typename Out>
void product_to(const Eigen::MatrixBase<ADerived>& a, const Eigen::MatrixBase<BDerived>& b,
                Out&& out, Matrix& scratch) {
  if (out.outerStride() == a.rows() && exact_product(a, b, out.data(), Epilogue::kStore, nullptr)) {
    return;
  }
  product_into(a, b, scratch);
  out = scratch;
}

// out += a b, as `product_into(a, b, t); out += t;`.
template <typename ADerived, typename BDerived, typename Out>
void add_product(const Eigen::MatrixBase<ADerived>& a, const Eigen::MatrixBase<BDerived>& b,
                 Out&& out, Matrix& scratch) {
  if (out.outerStride() == a.rows() && exact_product(a, b, out.data(), Epilogue::kAdd, nullptr)) {
    return;
  }
  product_into(a, b, scratch);
  out += scratch;
}

// out += (a b) h per column (h: n contiguous steps), as
// `product_into(a, b, t); out.array() += t.array().rowwise() * hᵀ;`.
template <typename ADerived, typename BDerived, typename Out>
void add_product_scaled(const Eigen::MatrixBase<ADerived>& a, const Eigen::MatrixBase<BDerived>& b,
                        const double* h, Out&& out, Matrix& scratch) {
  if (out.outerStride() == a.rows() && exact_product(a, b, out.data(), Epilogue::kAddScaled, h)) {
    return;
  }
  product_into(a, b, scratch);
  out.array() += scratch.array().rowwise() * Eigen::Map<const RowVector>(h, scratch.cols()).array();
}

// Whether the exact kernels compute a b for A m x k and B k x n (both column-major), so that
// the product's entries do not depend on how its columns are split into calls.
bool exact_product_covers(Index m, Index k, Index n);

}  // namespace csympnet::detail
