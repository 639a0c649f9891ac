#include "csympnet/core/types.hpp"

namespace csympnet {

Matrix canonical_j(Index d) {
  Matrix j = Matrix::Zero(2 * d, 2 * d);
  j.topRightCorner(d, d).setIdentity();
  j.bottomLeftCorner(d, d) = -Matrix::Identity(d, d);
  return j;
}

}  // namespace csympnet
