// The fma-order products of fma_product.hpp: the portable reference, the blocking of the inner
// index that the kernels share, their self-checks and the choice among them.
#include "fma_product.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "fma_product_kernels.hpp"
#include "registry.hpp"

namespace csympnet::kernels {

namespace {

#ifdef CSYMPNET_FMA_KERNELS

// Inner block: the kernels run l in blocks of kInnerBlock, each continuing every chain from the
// partial the previous block stored, so A's m x kInnerBlock block stays in L2 and a tile's
// kInnerBlock x 8 block of B in L1 (at m = 100: 200 KiB and 16 KiB).
constexpr Index kInnerBlock = 256;

// Columns per panel when the inner index is blocked: the partials of one panel (m x kPanel)
// are all the scratch a product needs, whatever n is.
constexpr Index kPanel = 512;

// Partials of the inner blocks; one per thread (the column-split passes run products on
// several threads at once).
double* partials(Index size) {
  thread_local std::vector<double> buf;
  if (buf.size() < static_cast<std::size_t>(size)) buf.resize(static_cast<std::size_t>(size));
  return buf.data();
}

void run_blocked(FmaKernel kernel, const FmaArgs& p, Index kc) {
  if (p.k <= kc) {
    kernel(p, 0, p.k, nullptr, 0, nullptr, 0);
    return;
  }
  // Panel by panel of columns (an entry's chain does not depend on its panel), each through
  // every inner block. kStore keeps the partials in C itself; the other epilogues need C
  // until the end.
  for (Index j0 = 0; j0 < p.n; j0 += kPanel) {
    FmaArgs q = p;
    q.n = std::min(kPanel, p.n - j0);
    q.b = p.b + j0 * p.bj;
    q.c = p.c + j0 * p.ldc;
    q.h = p.h + j0;
    const bool in_c = p.mode == Epilogue::kStore;
    double* part = in_c ? q.c : partials(q.m * q.n);
    const Index ldp = in_c ? q.ldc : q.m;
    kernel(q, 0, kc, nullptr, 0, part, ldp);
    Index l = kc;
    for (; q.k - l > kc; l += kc) kernel(q, l, l + kc, part, ldp, part, ldp);
    kernel(q, l, q.k, part, ldp, nullptr, 0);
  }
}

FmaKernel kernel_named(const char* isa) {
  if (std::strcmp(isa, "avx512") == 0) return fma_product_avx512;
  if (std::strcmp(isa, "avx2") == 0) return fma_product_avx2;
  return nullptr;
}

Family family_named(const char* isa) {
  return std::strcmp(isa, "avx512") == 0 ? Family::kFmaProductAvx512 : Family::kFmaProductAvx2;
}

FmaKernel chosen() {
  if (use(Family::kFmaProductAvx512)) return fma_product_avx512;
  if (use(Family::kFmaProductAvx2)) return fma_product_avx2;
  return nullptr;
}

// Checks once, on random operands, that a kernel gives the reference's bits: every epilogue,
// B stored by columns and by rows, every tile height (m from 1 to 25 covers 1 to 3 masked and
// whole vectors of both kernels) and width, several inner blocks (k > kInnerBlock, and small
// blocks forced), and more than one panel of columns.
bool agrees_with_reference(FmaKernel kernel) {
  std::mt19937_64 gen(20261126);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  struct Shape {
    Index m, n, k, kc;
  };
  const Shape shapes[] = {{1, 1, 1, kInnerBlock},   {3, 9, 5, kInnerBlock},
                          {7, 17, 23, 4},           {10, 13, 10, kInnerBlock},
                          {13, 7, 31, kInnerBlock}, {17, 11, 2, kInnerBlock},
                          {25, 9, 40, 7},           {24, 16, 529, kInnerBlock},
                          {9, 8, 300, kInnerBlock}, {3, kPanel + 3, 5, 2}};
  for (const Shape& s : shapes) {
    const Index m = s.m, n = s.n, k = s.k;
    Matrix a(m, k), b(k, n), d(m, n);
    Vector h(n);
    for (Index i = 0; i < a.size(); ++i) a.data()[i] = u(gen);
    for (Index i = 0; i < b.size(); ++i) b.data()[i] = u(gen);
    for (Index i = 0; i < d.size(); ++i) d.data()[i] = u(gen);
    for (Index i = 0; i < n; ++i) h(i) = u(gen);
    const Matrix bt = b.transpose();
    for (int e = 0; e < 3; ++e) {
      const auto mode = static_cast<Epilogue>(e);
      Matrix ref = d, mine = d, mine_t = d;
      fma_order_reference(m, n, k, a.data(), m, b.data(), 1, k, ref.data(), m, mode, h.data());
      run_blocked(kernel, {m, n, k, a.data(), m, b.data(), 1, k, mine.data(), m, mode, h.data()},
                  s.kc);
      run_blocked(kernel, {m, n, k, a.data(), m, bt.data(), n, 1, mine_t.data(), m, mode, h.data()},
                  s.kc);
      const auto bytes = static_cast<std::size_t>(ref.size()) * sizeof(double);
      if (std::memcmp(ref.data(), mine.data(), bytes) != 0 ||
          std::memcmp(ref.data(), mine_t.data(), bytes) != 0) {
        return false;
      }
    }
  }
  return true;
}

#endif  // CSYMPNET_FMA_KERNELS

}  // namespace

void fma_order_reference(Index m, Index n, Index k, const double* a, Index lda, const double* b,
                         Index bl, Index bj, double* c, Index ldc, Epilogue mode, const double* h) {
  for (Index j = 0; j < n; ++j) {
    for (Index i = 0; i < m; ++i) {
      double s = 0.0;
      for (Index l = 0; l < k; ++l) s = std::fma(a[i + l * lda], b[l * bl + j * bj], s);
      double& dst = c[i + j * ldc];
      if (mode == Epilogue::kStore) {
        dst = s;
      } else if (mode == Epilogue::kAdd) {
        dst = dst + s;
      } else {
        dst = std::fma(s, h[j], dst);
      }
    }
  }
}

void fma_order_product(Index m, Index n, Index k, const double* a, Index lda, const double* b,
                       Index bl, Index bj, double* c, Index ldc, Epilogue mode, const double* h) {
  if (m <= 0 || n <= 0) return;
#ifdef CSYMPNET_FMA_KERNELS
  const FmaKernel kernel = k > 0 ? chosen() : nullptr;
  if (kernel != nullptr) {
    // Without column factors, any array of n doubles keeps the (unread) h + j pointers valid.
    run_blocked(kernel, {m, n, k, a, lda, b, bl, bj, c, ldc, mode, h != nullptr ? h : c},
                kInnerBlock);
    return;
  }
#endif
  fma_order_reference(m, n, k, a, lda, b, bl, bj, c, ldc, mode, h);
}

const char* fma_kernel_isa() {
#ifdef CSYMPNET_FMA_KERNELS
  const FmaKernel kernel = chosen();
  return kernel == fma_product_avx512 ? "avx512" : kernel == fma_product_avx2 ? "avx2" : "portable";
#else
  return "portable";
#endif
}

bool fma_kernel_using(const char* isa, Index kc, Index m, Index n, Index k, const double* a,
                      Index lda, const double* b, Index bl, Index bj, double* c, Index ldc,
                      Epilogue mode, const double* h) {
#ifdef CSYMPNET_FMA_KERNELS
  const FmaKernel kernel = kernel_named(isa);
  if (kernel == nullptr || !available(family_named(isa)) || m <= 0 || n <= 0 || k <= 0)
    return false;
  run_blocked(kernel, {m, n, k, a, lda, b, bl, bj, c, ldc, mode, h != nullptr ? h : c},
              kc > 0 ? kc : kInnerBlock);
  return true;
#else
  (void)isa, (void)kc, (void)m, (void)n, (void)k, (void)a, (void)lda, (void)b, (void)bl, (void)bj,
      (void)c, (void)ldc, (void)mode, (void)h;
  return false;
#endif
}

bool fma_product_avx512_self_check() {
#ifdef CSYMPNET_FMA_KERNELS
  return agrees_with_reference(fma_product_avx512);
#else
  return false;
#endif
}

bool fma_product_avx2_self_check() {
#ifdef CSYMPNET_FMA_KERNELS
  return agrees_with_reference(fma_product_avx2);
#else
  return false;
#endif
}

bool fma_kernels_built() {
#ifdef CSYMPNET_FMA_KERNELS
  return true;
#else
  return false;
#endif
}

}  // namespace csympnet::kernels
