// The few BLAS and LAPACK routines the normal-equations Levenberg–Marquardt needs
// (levenberg_marquardt.cpp), behind C++ signatures. They resolve to whatever libblas.so.3 and
// liblapack.so.3 Debian's alternatives select: OpenBLAS when libopenblas0-pthread is installed
// (scripts/install-deps.sh installs it), the reference implementation otherwise. Matrices are
// column-major; only the lower triangle of a symmetric matrix is read or written.
#pragma once

#include <functional>

#include "csympnet/core/types.hpp"

namespace csympnet::lapack {

// While alive, OpenBLAS runs on one thread. Its threaded dsyrk and dpotrf give results that
// differ in the last bits between thread counts (measured: 1 against 2 threads on s3), and
// csympnet promises the same bits for the same seed; on s3 the second thread saved 5 %.
// Restores the previous count on destruction. No effect with other BLAS implementations.
class SingleThreaded {
 public:
  SingleThreaded();
  ~SingleThreaded();
  SingleThreaded(const SingleThreaded&) = delete;
  SingleThreaded& operator=(const SingleThreaded&) = delete;

 private:
  int saved_ = 0;
};

// C = Aᵀ A (lower triangle), with A given as its transpose At (n × k, column-major, leading
// dimension n): that is a row-major k × n matrix, as residual_jacobian() writes it.
void gram_from_transpose(const double* at, Index n, Index k, double* c);
// C += Aᵀ A (lower triangle), At as above: accumulates a Gram matrix over row chunks of J.
void add_gram_from_transpose(const double* at, Index n, Index k, double* c);

// y = At x, At as above (n × k): the product Jᵀ r for a row-major J.
void transpose_times(const double* at, Index n, Index k, const double* x, double* y);
// y += At x.
void add_transpose_times(const double* at, Index n, Index k, const double* x, double* y);

// y = C x for symmetric C (n × n, lower triangle).
void symmetric_times(const double* c, Index n, const double* x, double* y);

// Cholesky factorisation of symmetric C (n × n, lower triangle) in place. Returns false when C
// is not numerically positive definite.
bool cholesky(double* c, Index n);

// The same factor, computed block column by block column (dpotrf on each diagonal block, dtrsm
// below it, dsyrk on the rest) with `should_stop` polled after each, so no single call runs
// much over kMaxUninterruptedFlops. Not bit-identical to cholesky(). Returns kStopped when
// asked to stop (the matrix is then partly factored).
enum class Factor { kDone, kNotPositiveDefinite, kStopped };
Factor cholesky_blocked(double* c, Index n, const std::function<bool()>& should_stop);

// About the most floating-point work (1e9 operations, ~0.1-0.3 s on one core) done in one BLAS
// or LAPACK call between two polls for an interrupt, where a computation is split to poll.
inline constexpr double kMaxUninterruptedFlops = 1e9;

// About the most fresh memory (1M doubles, 8 MB) first touched between two polls: the kernel
// hands out zeroed pages at about 0.4 GB/s on a 2-core virtual machine (a 4,111 × 4,111 matrix,
// 135 MB, took 0.31-0.37 s to fill the first time and 0.02 s once its pages were mapped).
inline constexpr Index kMaxUninterruptedTouch = Index{1} << 20;

// Solves L Lᵀ x = b in place, L from cholesky().
void cholesky_solve(const double* l, Index n, double* b);

}  // namespace csympnet::lapack
