// OneStepMap's defaults for known inputs (a free map takes none) and for forward-mode step
// sensitivities (a map without them refuses) (models/one_step_map.hpp).
#include "csympnet/core/error.hpp"
#include "csympnet/models/one_step_map.hpp"

namespace csympnet {

Matrix OneStepMap::forward_driven(ConstParams theta, const Matrix& Z, const Vector& h,
                                  const Matrix& U, ForwardCache* cache) const {
  require(U.rows() == 0, [&] {
    return type() + " forward: this map takes no inputs (U has " + std::to_string(U.rows()) +
           " rows); inputs are supported by the library core ({\"type\": \"library\", "
           "\"inputs\": {\"m\": ...}})";
  });
  return forward(theta, Z, h, cache);
}

Matrix OneStepMap::jacobian_driven(ConstParams theta, const Vector& z, double h,
                                   const Vector& u) const {
  require(u.size() == 0, [&] {
    return type() + " jacobian: this map takes no inputs (u has " + std::to_string(u.size()) +
           " values)";
  });
  return jacobian(theta, z, h);
}

void OneStepMap::step_tangents(ConstParams /*theta*/, double /*h*/, const double* /*u*/,
                               double* /*z*/, Matrix& /*t*/, Index /*n_theta*/) const {
  throw Error(type() + ": this map has no forward-mode step sensitivities (has_step_tangents())");
}

}  // namespace csympnet
