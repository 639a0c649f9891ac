// Eigen's dense factorisations, compiled once (core/dense.hpp).
#include "csympnet/core/dense.hpp"

#include <Eigen/Dense>

namespace csympnet::dense {

Vector least_squares(const Matrix& a, const Vector& b) {
  return a.colPivHouseholderQr().solve(b);
}

Matrix least_squares(const Matrix& a, const Matrix& b) {
  return a.colPivHouseholderQr().solve(b);
}

Matrix least_squares(const Matrix& a, const RowMajor& b) {
  return a.colPivHouseholderQr().solve(b);
}

Vector first_coefficient_weights(const Matrix& a) {
  const Eigen::HouseholderQR<Matrix> qr(a);
  const Index n = a.cols();
  Vector u = Vector::Zero(a.rows());
  u(0) = 1.0;
  qr.matrixQR().topLeftCorner(n, n).triangularView<Eigen::Upper>().transpose().solveInPlace(
      u.head(n));
  return qr.householderQ() * u;
}

RankedSolution least_squares_with_rank(const Matrix& a, const RowMajor& b) {
  const Eigen::ColPivHouseholderQR<Matrix> qr(a);
  return {qr.solve(b), qr.rank()};
}

Vector least_norm_solution(const Matrix& a, const Vector& b, double threshold) {
  Eigen::CompleteOrthogonalDecomposition<Matrix> cod(a);
  cod.setThreshold(threshold);
  return cod.solve(b);
}

Matrix inverse(const Matrix& a) {
  return a.inverse();
}

double determinant(const Matrix& a) {
  return a.determinant();
}

bool is_invertible(const Matrix& a) {
  return a.fullPivLu().isInvertible();
}

Matrix full_pivot_inverse(const Matrix& a) {
  return a.fullPivLu().inverse();
}

SymmetricEigen symmetric_eigen(const Matrix& a) {
  const Eigen::SelfAdjointEigenSolver<Matrix> e(a);
  SymmetricEigen out;
  out.ok = e.info() == Eigen::Success;
  out.values = e.eigenvalues();
  out.vectors = e.eigenvectors();
  return out;
}

Eigensystem eigensystem(const Matrix& a, bool with_vectors) {
  const Eigen::EigenSolver<Matrix> e(a, with_vectors);
  Eigensystem out;
  out.ok = e.info() == Eigen::Success;
  out.values = e.eigenvalues();
  if (with_vectors) out.vectors = e.eigenvectors();
  return out;
}

SingularValues singular_values(const Matrix& a, bool with_thin_u) {
  if (!with_thin_u) return {Eigen::JacobiSVD<Matrix>(a).singularValues(), Matrix()};
  const Eigen::JacobiSVD<Matrix> svd(a, Eigen::ComputeThinU);
  return {svd.singularValues(), svd.matrixU()};
}

Ldlt::Ldlt(const Matrix& a) : f_(a) {}
bool Ldlt::ok() const {
  return f_.info() == Eigen::Success;
}
Vector Ldlt::solve(const Vector& b) const {
  return f_.solve(b);
}
Matrix Ldlt::solve(const Matrix& b) const {
  return f_.solve(b);
}

Llt::Llt(const Matrix& a) : f_(a) {}
bool Llt::ok() const {
  return f_.info() == Eigen::Success;
}
Vector Llt::factor_diagonal() const {
  return f_.matrixLLT().diagonal();
}
Vector Llt::solve(const Vector& b) const {
  return f_.solve(b);
}
Matrix Llt::lower_solve_transposed(const Matrix& w) const {
  return f_.matrixL().solve(w.transpose()).transpose();
}

}  // namespace csympnet::dense
