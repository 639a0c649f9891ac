// The SSE2-order product kernels of product.hpp.
//
// The order, per entry C(i, j) of C = A B (k = inner dimension), that Eigen 3.4's GEMM uses
// in the SSE2 build when its blocking does not split the inner dimension (kc >= k):
//   * rows i < m4 = 4⌊m/4⌋ (its 2-packet micro-kernel): s = 0; s += A(i,l) B(l,j), l = 0..k−1;
//   * rows m4, m4+1 when m ≡ 2 (mod 4), columns j < 4⌊n/4⌋ (its 1-packet kernel): two sums,
//       c over even l and d over odd l for l < k8 = 8⌊k/8⌋, then s = c + d and s += A(i,l) B(l,j)
//       for l = k8..k−1;  other columns: the plain running sum;
//   * then C(i, j) = 0 + s (the destination is zeroed and the block added to it).
// Odd m, a split inner dimension, lazy (tiny) products and builds whose Eigen uses other
// packets or FMA are not covered: sse2_order_product() returns false there.
//
// An entry's arithmetic depends only on (i, l, m, k) and, for the two tail rows, on whether
// its column lies before 4⌊n/4⌋; so a product computed as calls on column ranges split at a
// multiple of 4 gives the same bits as one call. This file checks the kernels and picks one;
// product_avx512.cpp and product_avx.cpp hold them.
#include "product.hpp"

#include <cstring>
#include <random>

#include "sse2_order.hpp"
//
#include "product_targets.hpp"
#include "registry.hpp"

namespace csympnet::kernels {

namespace {

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

// Eigen blocks a product by its cache-size heuristic. Blocks of rows and columns in multiples
// of its micro-tile (4 x 4) leave every entry's arithmetic as above; a split of the inner
// dimension does not (the partial sums would be added), so it is not covered.
bool eigen_order_is_known(Index m, Index n, Index k) {
  Index kc = k, mc = m, nc = n;
  Eigen::internal::computeProductBlockingSizes<double, double, 1, Index>(kc, mc, nc, Index{1});
  return kc >= k && (mc >= m || mc % 4 == 0) && (nc >= n || nc % 4 == 0);
}

// The shapes sse2_order_product() hands to a kernel: Eigen's lazy product (tiny sizes), its GEMV
// fallbacks (a single row or column), odd row counts and blocked shapes follow other orders.
// The kernels read B by columns (bl = 1) or by rows (bj = 1), as every Eigen operand is stored.
bool covered(Index m, Index n, Index k, Index bl, Index bj) {
  constexpr Index kCoeffBasedThreshold = 20;  // EIGEN_GEMM_TO_COEFFBASED_THRESHOLD
  if (m < 2 || n < 2 || k < 1 || m % 2 != 0 || k + m + n < kCoeffBasedThreshold) return false;
  return (bl == 1 || bj == 1) && eigen_order_is_known(m, n, k);
}

void run(ProductKernel kernel, Index m, Index n, Index k, const double* a, Index lda,
         const double* b, Index bl, Index bj, double* c, Epilogue mode, const double* h) {
  // Without column factors, any array of n doubles keeps the (unread) h + j pointers valid.
  if (h == nullptr) h = c;
  kernel({m, n, k, a, lda, b, bl, bj, c, m, mode, h});
}

// Checks once, on random operands of every covered kind, that a kernel reproduces Eigen on
// this build and machine; a kernel that does not is never used. The shapes reach every tile
// kind: 8- and 4-row tiles, every panel width, and the tail rows from a copy of B, from B
// stored by rows and in a pass of their own (k > 128, m = 2), with and without 4-column rests.
bool agrees_with_eigen(ProductKernel kernel) {
  std::mt19937_64 gen(12345);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Index shapes[][3] = {{10, 37, 10}, {50, 21, 10}, {26, 13, 19},  {100, 9, 64}, {12, 47, 7},
                             {2, 30, 9},   {14, 27, 17}, {10, 10, 400}, {10, 23, 130}};
  for (const auto& s : shapes) {
    const Index m = s[0], n = s[1], k = s[2];
    if (!covered(m, n, k, 1, k)) continue;
    Matrix a(m, k), b(k, n), d(m, n);
    Vector h(n);
    for (Index i = 0; i < a.size(); ++i) a.data()[i] = u(gen);
    for (Index i = 0; i < b.size(); ++i) b.data()[i] = u(gen);
    for (Index i = 0; i < d.size(); ++i) d.data()[i] = u(gen);
    for (Index i = 0; i < n; ++i) h(i) = u(gen);
    const Matrix bt = b.transpose();
    Matrix prod(m, n);
    prod.noalias() = a * b;
    Matrix ref[3] = {prod, d + prod, d};
    ref[2].array() += prod.array().rowwise() * h.transpose().array();
    for (int e = 0; e < 3; ++e) {
      const auto mode = static_cast<Epilogue>(e);
      Matrix mine = d, mine_t = d;
      run(kernel, m, n, k, a.data(), m, b.data(), 1, k, mine.data(), mode, h.data());
      run(kernel, m, n, k, a.data(), m, bt.data(), n, 1, mine_t.data(), mode, h.data());
      const auto bytes = static_cast<std::size_t>(prod.size()) * sizeof(double);
      if (std::memcmp(ref[e].data(), mine.data(), bytes) != 0 ||
          std::memcmp(ref[e].data(), mine_t.data(), bytes) != 0) {
        return false;
      }
    }
  }
  return true;
}

ProductKernel kernel_named(const char* isa) {
  if (std::strcmp(isa, "avx512") == 0) return product_avx512;
  if (std::strcmp(isa, "avx") == 0) return product_avx;
  return nullptr;
}

Family family_named(const char* isa) {
  return std::strcmp(isa, "avx512") == 0 ? Family::kProductAvx512 : Family::kProductAvx;
}

// The kernel that runs now (the registry's rule: AVX-512 first, then AVX), or none.
ProductKernel chosen() {
  if (use(Family::kProductAvx512)) return product_avx512;
  if (use(Family::kProductAvx)) return product_avx;
  return nullptr;
}

#endif  // CSYMPNET_SSE2_ORDER_KERNELS

}  // namespace

bool sse2_order_product(Index m, Index n, Index k, const double* a, Index lda, const double* b,
                        Index bl, Index bj, double* c, Epilogue mode, const double* h) {
#ifdef CSYMPNET_SSE2_ORDER_KERNELS
  const ProductKernel kernel = chosen();
  if (kernel == nullptr || !covered(m, n, k, bl, bj)) return false;
  run(kernel, m, n, k, a, lda, b, bl, bj, c, mode, h);
  return true;
#else
  (void)m, (void)n, (void)k, (void)a, (void)lda, (void)b, (void)bl, (void)bj, (void)c, (void)mode,
      (void)h;
  return false;
#endif
}

bool product_kernel_using(const char* isa, Index m, Index n, Index k, const double* a, Index lda,
                          const double* b, Index bl, Index bj, double* c, Epilogue mode,
                          const double* h) {
#ifdef CSYMPNET_SSE2_ORDER_KERNELS
  const ProductKernel kernel = kernel_named(isa);
  if (kernel == nullptr || !available(family_named(isa)) || !covered(m, n, k, bl, bj)) return false;
  run(kernel, m, n, k, a, lda, b, bl, bj, c, mode, h);
  return true;
#else
  (void)isa, (void)m, (void)n, (void)k, (void)a, (void)lda, (void)b, (void)bl, (void)bj, (void)c,
      (void)mode, (void)h;
  return false;
#endif
}

const char* product_kernel_isa() {
#ifdef CSYMPNET_SSE2_ORDER_KERNELS
  const ProductKernel kernel = chosen();
  return kernel == product_avx512 ? "avx512" : kernel == product_avx ? "avx" : "portable";
#else
  return "portable";
#endif
}

bool product_avx512_self_check() {
#ifdef CSYMPNET_SSE2_ORDER_KERNELS
  return agrees_with_eigen(product_avx512);
#else
  return false;
#endif
}

bool product_avx_self_check() {
#ifdef CSYMPNET_SSE2_ORDER_KERNELS
  return agrees_with_eigen(product_avx);
#else
  return false;
#endif
}

bool product_kernel_covers(Index m, Index k, Index n) {
  if (m < 1 || k < 1 || n < 1) return false;
  // The fma order is the same for every shape and split (fma_product.hpp).
  if (arithmetic() == Arithmetic::kFma) return true;
  // The decision is the one the cores' calls meet: sse2_order_product() declines without writing
  // when the kernels do not cover the shape, whatever the values.
  const Matrix a = Matrix::Zero(m, k);
  const Matrix b = Matrix::Zero(k, n);
  Matrix c(m, n);
  return sse2_order_product(a, b, c.data(), Epilogue::kStore, nullptr);
}

}  // namespace csympnet::kernels
