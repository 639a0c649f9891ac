// Eigen's dense factorisations behind plain functions, compiled once (src/core/dense.cpp).
//
// Each decomposition of Eigen costs 3 to 16 CPU s of compile in every file that instantiates
// it (the symmetric eigensolver about 10 s under the sanitizers, the general one 16 s), and
// a dozen files of the identification used the same few. Here each is compiled once; the
// results are Eigen's, to the bit (the same code on the same values, fp-contract off).
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "csympnet/core/types.hpp"

namespace csympnet::dense {

using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// The least-squares solution x of a x ≈ b by column-pivoting Householder QR (Eigen's
// colPivHouseholderQr()), and the numerical rank that QR found. Eigen applies Qᵀ to a copy of
// b in b's own storage order, so a row-major b (a transposed matrix, as Eigen's
// solve(m.transpose()) sees it) is a different rounding from a column-major one: both are here.
Vector least_squares(const Matrix& a, const Vector& b);
Matrix least_squares(const Matrix& a, const Matrix& b);
Matrix least_squares(const Matrix& a, const RowMajor& b);
// w with wᵀy = the first entry of the least-squares solution of a x ≈ y, for every y (a of full
// column rank, rows ≥ columns): by Householder QR a = QR, w = Q R⁻ᵀ e₀. A local polynomial's
// value at its centre, as weights of the samples that one factorisation serves for every y.
Vector first_coefficient_weights(const Matrix& a);
struct RankedSolution {
  Matrix x;
  Index rank = 0;
};
RankedSolution least_squares_with_rank(const Matrix& a, const RowMajor& b);

// The least-squares solution of least norm, with pivots below threshold × the largest counted
// as 0 (Eigen's CompleteOrthogonalDecomposition and its setThreshold()).
Vector least_norm_solution(const Matrix& a, const Vector& b, double threshold);

// a⁻¹ and det a by LU with partial pivoting (Eigen's inverse() and determinant() of a
// dynamic-size matrix); whether LU with full pivoting finds a invertible (Eigen's
// fullPivLu().isInvertible(), its default threshold).
Matrix inverse(const Matrix& a);
double determinant(const Matrix& a);
bool is_invertible(const Matrix& a);
// a⁻¹ by LU with full pivoting (Eigen's fullPivLu().inverse()), for an invertible a.
Matrix full_pivot_inverse(const Matrix& a);

// The eigen-decomposition of a symmetric matrix, its lower triangle read: values ascending,
// unit vectors as columns (Eigen's SelfAdjointEigenSolver); ok is false where it did not
// converge (the values and vectors are then Eigen's as they stand).
struct SymmetricEigen {
  Vector values;
  Matrix vectors;
  bool ok = false;
};
SymmetricEigen symmetric_eigen(const Matrix& a);

// The eigenvalues of a general real square matrix, and its eigenvectors as columns where
// asked (Eigen's EigenSolver); ok is false where it did not converge.
struct Eigensystem {
  Eigen::VectorXcd values;
  Eigen::MatrixXcd vectors;
  bool ok = false;
};
Eigensystem eigensystem(const Matrix& a, bool with_vectors);

// The singular values of a, descending, and its thin U where asked (Eigen's JacobiSVD).
struct SingularValues {
  Vector values;
  Matrix u;
};
SingularValues singular_values(const Matrix& a, bool with_thin_u);

// LDLᵀ with pivoting of a symmetric matrix, its lower triangle read (Eigen's LDLT).
class Ldlt {
 public:
  explicit Ldlt(const Matrix& a);
  bool ok() const;  // Eigen's info() == Success
  Vector solve(const Vector& b) const;
  Matrix solve(const Matrix& b) const;

 private:
  Eigen::LDLT<Matrix> f_;
};

// LLᵀ of a symmetric positive-definite matrix, its lower triangle read (Eigen's LLT).
class Llt {
 public:
  explicit Llt(const Matrix& a);
  bool ok() const;                 // Eigen's info() == Success
  Vector factor_diagonal() const;  // the diagonal of L
  Vector solve(const Vector& b) const;
  Matrix lower_solve_transposed(const Matrix& w) const;  // (L⁻¹ wᵀ)ᵀ = w L⁻ᵀ

 private:
  Eigen::LLT<Matrix> f_;
};

}  // namespace csympnet::dense
