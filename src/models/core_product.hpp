// Internal to src/models: the cores' matrix products in the process's arithmetic
// (kernels::arithmetic()): "sse2", through the SSE2-order product kernels
// (src/kernels/product.hpp) where they cover the shape, else Eigen's product (product_into);
// "fma", through the fma-order products (src/kernels/fma_product.hpp), which cover every shape.
#pragma once

#include "../kernels/fma_product.hpp"
#include "../kernels/product.hpp"
#include "../kernels/registry.hpp"
#include "activation.hpp"

namespace csympnet::detail {

inline bool fma_arithmetic() {
  return kernels::arithmetic() == kernels::Arithmetic::kFma;
}

// The cores' products. In the sse2 arithmetic: through the kernels where they cover the shape,
// else Eigen's product (product_into), to the bit as the Eigen expression in each comment. In
// the fma arithmetic: the fma-order product and epilogue of fma_product.hpp. A destination may be a
// matrix, a map, or a block of whole columns of a matrix (the column-split passes write their
// range of a batch in place).

// out = a b into a matrix resized to fit, as product_into(a, b, out).
template <typename ADerived, typename BDerived>
void core_product(const Eigen::MatrixBase<ADerived>& a, const Eigen::MatrixBase<BDerived>& b,
                  Matrix& out) {
  out.resize(a.rows(), b.cols());
  if (fma_arithmetic()) {
    kernels::fma_order_product(a, b, out.data(), out.rows(), kernels::Epilogue::kStore, nullptr);
    return;
  }
  if (!kernels::sse2_order_product(a, b, out.data(), kernels::Epilogue::kStore, nullptr))
    product_into(a, b, out);
}

// out = a b into a destination of that shape, as `product_into(a, b, t); out = t;`.
template <typename ADerived, typename BDerived, typename Dst>
void core_product_to(const Eigen::MatrixBase<ADerived>& a, const Eigen::MatrixBase<BDerived>& b,
                     Dst&& out, Matrix& scratch) {
  if (fma_arithmetic()) {
    kernels::fma_order_product(a, b, out.data(), out.outerStride(), kernels::Epilogue::kStore,
                               nullptr);
    return;
  }
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
  if (fma_arithmetic()) {
    kernels::fma_order_product(a, b, dst.data(), dst.outerStride(), kernels::Epilogue::kAdd,
                               nullptr);
    return;
  }
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
  if (fma_arithmetic()) {
    kernels::fma_order_product(a, b, dst.data(), dst.outerStride(), kernels::Epilogue::kAddScaled,
                               h);
    return;
  }
  if (dst.outerStride() == a.rows() &&
      kernels::sse2_order_product(a, b, dst.data(), kernels::Epilogue::kAddScaled, h)) {
    return;
  }
  product_into(a, b, scratch);
  dst.array() += scratch.array().rowwise() * Eigen::Map<const RowVector>(h, scratch.cols()).array();
}

}  // namespace csympnet::detail
