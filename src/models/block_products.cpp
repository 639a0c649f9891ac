#include "block_products.hpp"

namespace csympnet::detail {

bool exact_product_covers(Index m, Index k, Index n) {
  if (m < 1 || k < 1 || n < 1) return false;
  // The decision is the one the cores' calls meet: exact_product() declines without writing
  // when the kernels do not cover the shape, whatever the values.
  const Matrix a = Matrix::Zero(m, k);
  const Matrix b = Matrix::Zero(k, n);
  Matrix c(m, n);
  return exact_product(a, b, c.data(), Epilogue::kStore, nullptr);
}

}  // namespace csympnet::detail
