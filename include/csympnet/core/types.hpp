// Basic numeric types shared by every layer.
//
// A batch of phase-space states is a 2d x N matrix whose columns are samples, with the
// d position rows (q) first and the d momentum rows (p) after them.
#pragma once

#include <Eigen/Core>

namespace csympnet {

using Index = Eigen::Index;
using Matrix = Eigen::MatrixXd;
using Vector = Eigen::VectorXd;
using RowVector = Eigen::RowVectorXd;

// Read-only and writable views into a flat parameter (or gradient) vector.
using ConstParams = Eigen::Ref<const Vector>;
using ParamsRef = Eigen::Ref<Vector>;

// The canonical symplectic matrix J = [[0, I], [-I, 0]] of size 2d x 2d.
Matrix canonical_j(Index d);

}  // namespace csympnet
