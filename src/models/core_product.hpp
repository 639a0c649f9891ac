// Internal to src/models: the cores' matrix products through the SSE2-order product kernels
// (src/kernels/product.hpp) where they cover the shape, else Eigen's product (product_into).
#pragma once

#include "../kernels/product.hpp"
#include "activation.hpp"

namespace csympnet::detail {

// The cores' products: through the kernels where they cover the shape, else Eigen's product
// (product_into), to the bit as the Eigen expression in each comment. A destination may be a
// matrix, a map, or a block of whole columns of a matrix (the column-split passes write their
// range of a batch in place).

// out = a b into a matrix resized to fit, as product_into(a, b, out).
template <typename ADerived, typename BDerived>
void core_product(const Eigen::MatrixBase<ADerived>& a, const Eigen::MatrixBase<BDerived>& b,
                  Matrix& out) {
  out.resize(a.rows(), b.cols());
  if (!kernels::sse2_order_product(a, b, out.data(), kernels::Epilogue::kStore, nullptr))
    product_into(a, b, out);
}

// out = a b into a destination of that shape, as `product_into(a, b, t); out = t;`.
template <typename ADerived, typename BDerived, typename Dst>
void core_product_to(const Eigen::MatrixBase<ADerived>& a, const Eigen::MatrixBase<BDerived>& b,
                     Dst&& out, Matrix& scratch) {
  if (out.outerStride() == a.rows() &&
      kernels::sse2_order_product(a, b, out.data(), kernels::Epilogue::kStore, nullptr)) {
    return;
  }
  product_into(a, b, scratch);
  out = scratch;
}

// dst += a b, as `product_into(a, b, t); dst += t;`.
template <typename ADerived, typename BDerived, typename Dst>
void core_product_add(const Eigen::MatrixBase<ADerived>& a, const Eigen::MatrixBase<BDerived>& b,
                      Dst&& dst, Matrix& scratch) {
  if (dst.outerStride() == a.rows() &&
      kernels::sse2_order_product(a, b, dst.data(), kernels::Epilogue::kAdd, nullptr)) {
    return;
  }
  product_into(a, b, scratch);
  dst += scratch;
}

// dst += (a b) h per column (h: b.cols() contiguous steps), as
// `product_into(a, b, t); dst.array() += t.array().rowwise() * hᵀ;`.
template <typename ADerived, typename BDerived, typename Dst>
void core_product_add_scaled(const Eigen::MatrixBase<ADerived>& a,
                             const Eigen::MatrixBase<BDerived>& b, const double* h, Dst&& dst,
                             Matrix& scratch) {
  if (dst.outerStride() == a.rows() &&
      kernels::sse2_order_product(a, b, dst.data(), kernels::Epilogue::kAddScaled, h)) {
    return;
  }
  product_into(a, b, scratch);
  dst.array() += scratch.array().rowwise() * Eigen::Map<const RowVector>(h, scratch.cols()).array();
}

}  // namespace csympnet::detail
