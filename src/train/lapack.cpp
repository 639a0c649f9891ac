#include "lapack.hpp"

#include <algorithm>
#include <climits>
#include <cstddef>

#include "csympnet/core/error.hpp"

// Fortran entry points. The trailing size_t arguments are the hidden lengths of the character
// arguments that gfortran passes; implementations written in C ignore them.
extern "C" {
void dsyrk_(const char* uplo, const char* trans, const int* n, const int* k, const double* alpha,
            const double* a, const int* lda, const double* beta, double* c, const int* ldc,
            std::size_t, std::size_t);
void dgemv_(const char* trans, const int* m, const int* n, const double* alpha, const double* a,
            const int* lda, const double* x, const int* incx, const double* beta, double* y,
            const int* incy, std::size_t);
void dsymv_(const char* uplo, const int* n, const double* alpha, const double* a, const int* lda,
            const double* x, const int* incx, const double* beta, double* y, const int* incy,
            std::size_t);
void dtrsm_(const char* side, const char* uplo, const char* transa, const char* diag, const int* m,
            const int* n, const double* alpha, const double* a, const int* lda, double* b,
            const int* ldb, std::size_t, std::size_t, std::size_t, std::size_t);
void dpotrf_(const char* uplo, const int* n, double* a, const int* lda, int* info, std::size_t);
void dpotrs_(const char* uplo, const int* n, const int* nrhs, const double* a, const int* lda,
             double* b, const int* ldb, int* info, std::size_t);
// OpenBLAS' thread control; weak, so that other BLAS implementations leave them null.
void openblas_set_num_threads(int) __attribute__((weak));
int openblas_get_num_threads() __attribute__((weak));
}

namespace csympnet::lapack {

namespace {
int as_int(Index v, const char* what) {
  require(v >= 0 && v <= INT_MAX,
          [&] { return std::string("lapack: ") + what + " is out of BLAS's int range"; });
  return static_cast<int>(v);
}
}  // namespace

SingleThreaded::SingleThreaded() {
  if (openblas_get_num_threads != nullptr && openblas_set_num_threads != nullptr) {
    saved_ = openblas_get_num_threads();
    openblas_set_num_threads(1);
  }
}

SingleThreaded::~SingleThreaded() {
  if (saved_ > 0 && openblas_set_num_threads != nullptr) openblas_set_num_threads(saved_);
}

namespace {
void gram(const double* at, Index n, Index k, double* c, double beta) {
  const int ni = as_int(n, "n"), ki = as_int(k, "k"), lda = ni > 0 ? ni : 1;
  const double one = 1.0;
  dsyrk_("L", "N", &ni, &ki, &one, at, &lda, &beta, c, &lda, 1, 1);
}
void at_times(const double* at, Index n, Index k, const double* x, double* y, double beta) {
  const int ni = as_int(n, "n"), ki = as_int(k, "k"), lda = ni > 0 ? ni : 1, inc = 1;
  const double one = 1.0;
  dgemv_("N", &ni, &ki, &one, at, &lda, x, &inc, &beta, y, &inc, 1);
}
}  // namespace

void gram_from_transpose(const double* at, Index n, Index k, double* c) {
  gram(at, n, k, c, 0.0);
}
void add_gram_from_transpose(const double* at, Index n, Index k, double* c) {
  gram(at, n, k, c, 1.0);
}
void transpose_times(const double* at, Index n, Index k, const double* x, double* y) {
  at_times(at, n, k, x, y, 0.0);
}
void add_transpose_times(const double* at, Index n, Index k, const double* x, double* y) {
  at_times(at, n, k, x, y, 1.0);
}

void symmetric_times(const double* c, Index n, const double* x, double* y) {
  const int ni = as_int(n, "n"), lda = ni > 0 ? ni : 1, inc = 1;
  const double one = 1.0, zero = 0.0;
  dsymv_("L", &ni, &one, c, &lda, x, &inc, &zero, y, &inc, 1);
}

bool cholesky(double* c, Index n) {
  const int ni = as_int(n, "n"), lda = ni > 0 ? ni : 1;
  int info = 0;
  dpotrf_("L", &ni, c, &lda, &info, 1);
  require(info >= 0, [&] { return "lapack: dpotrf rejected argument " + std::to_string(-info); });
  return info == 0;
}

Factor cholesky_blocked(double* c, Index n, const std::function<bool()>& should_stop) {
  const int ni = as_int(n, "n"), lda = ni > 0 ? ni : 1;
  // Each step's largest call is the dsyrk of the trailing block: about n² · block flops.
  const double nn = static_cast<double>(n) * static_cast<double>(n);
  const int block =
      static_cast<int>(std::clamp(kMaxUninterruptedFlops / std::max(nn, 1.0), 32.0, 256.0));
  const double one = 1.0, minus_one = -1.0;
  for (int k = 0; k < ni; k += block) {
    if (should_stop && should_stop()) return Factor::kStopped;
    const int kb = std::min(block, ni - k), rest = ni - k - kb;
    double* a11 = c + k + static_cast<std::size_t>(k) * lda;
    int info = 0;
    dpotrf_("L", &kb, a11, &lda, &info, 1);
    require(info >= 0, [&] { return "lapack: dpotrf rejected argument " + std::to_string(-info); });
    if (info > 0) return Factor::kNotPositiveDefinite;
    if (rest == 0) break;
    double* a21 = a11 + kb;
    double* a22 = a21 + static_cast<std::size_t>(kb) * lda;
    // L21 = A21 L11⁻ᵀ, then A22 -= L21 L21ᵀ (lower triangle).
    dtrsm_("R", "L", "T", "N", &rest, &kb, &one, a11, &lda, a21, &lda, 1, 1, 1, 1);
    dsyrk_("L", "N", &rest, &kb, &minus_one, a21, &lda, &one, a22, &lda, 1, 1);
  }
  return Factor::kDone;
}

void cholesky_solve(const double* l, Index n, double* b) {
  const int ni = as_int(n, "n"), lda = ni > 0 ? ni : 1, one = 1;
  int info = 0;
  dpotrs_("L", &ni, &one, l, &lda, b, &lda, &info, 1);
  require(info == 0, [&] { return "lapack: dpotrs rejected argument " + std::to_string(-info); });
}

}  // namespace csympnet::lapack
