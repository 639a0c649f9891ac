#include "csympnet/train/residual_jacobian.hpp"

#include <string>

#include "csympnet/core/error.hpp"

namespace csympnet {

namespace {
void check_shapes(const OneStepMap& map, ConstParams theta, const PairSet& pairs) {
  pairs.validate("residual pairs");
  require(pairs.dim() == map.dim(), [&] {
    return "residuals: data dimension " + std::to_string(pairs.dim()) +
           " does not match the model's " + std::to_string(map.dim());
  });
  require(theta.size() == map.n_params(), [&] {
    return "residuals: parameter vector has size " + std::to_string(theta.size()) + ", expected " +
           std::to_string(map.n_params());
  });
}
}  // namespace

Vector one_step_residuals(const OneStepMap& map, ConstParams theta, const PairSet& pairs) {
  check_shapes(map, theta, pairs);
  const Matrix r = map.forward(theta, pairs.z0, pairs.h, nullptr) - pairs.z1;
  // Column-major storage of a 2d × N matrix is already sample-major.
  return Eigen::Map<const Vector>(r.data(), r.size());
}

void residual_jacobian(const OneStepMap& map, ConstParams theta, const PairSet& pairs,
                       Eigen::Ref<RowMajorMatrix> jac, const std::function<bool()>& should_stop) {
  check_shapes(map, theta, pairs);
  const Index m = pairs.dim(), n = pairs.size(), p = map.n_params();
  require(jac.rows() == n * m && jac.cols() == p, [&] {
    return "residual_jacobian: output must be " + std::to_string(n * m) + " x " + std::to_string(p);
  });
  ForwardCache cache;
  Matrix z(m, 1);
  Vector h(1);
  Matrix upstream = Matrix::Zero(m, 1);
  for (Index j = 0; j < n; ++j) {
    if (should_stop && should_stop()) return;  // per pair: 2d backward passes
    z = pairs.z0.col(j);
    h(0) = pairs.h(j);
    map.forward(theta, z, h, &cache);
    for (Index k = 0; k < m; ++k) {
      Eigen::Map<Vector> row(jac.row(j * m + k).data(), p);
      row.setZero();
      upstream(k, 0) = 1.0;
      map.backward(theta, cache, upstream, row, nullptr);
      upstream(k, 0) = 0.0;
    }
  }
}

RowMajorMatrix residual_jacobian(const OneStepMap& map, ConstParams theta, const PairSet& pairs) {
  RowMajorMatrix jac(pairs.size() * pairs.dim(), map.n_params());
  residual_jacobian(map, theta, pairs, jac);
  return jac;
}

}  // namespace csympnet
