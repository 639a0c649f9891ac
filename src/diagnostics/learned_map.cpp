#include "csympnet/diagnostics/learned_map.hpp"

namespace csympnet {

LearnedMap learned_map(const Model& model, const Vector& theta, const OdeOptions& ode) {
  LearnedMap lm;
  lm.gamma_hat = model.damping_rate(theta);
  if (model.is_map()) {
    const OneStepMap* map = model.map.get();
    lm.step = [map, &theta](const Vector& z, double h) -> Vector {
      return map->apply(theta, z, Vector::Constant(1, h));
    };
    lm.jacobian = [map, &theta](const Vector& z, double h) { return map->jacobian(theta, z, h); };
    return lm;
  }
  const VectorFieldModel* field = model.field.get();
  VectorField f = [field, &theta](const Vector& z, Vector& dz) { dz = field->field(theta, z); };
  VectorFieldJacobian df = [field, &theta](const Vector& z) {
    return field->field_jacobian(theta, z);
  };
  lm.step = [f, ode](const Vector& z, double h) { return dopri5_flow(f, z, h, ode); };
  lm.jacobian = [f, df, ode](const Vector& z, double h) {
    return dopri5_flow_jacobian(f, df, z, h, ode).second;
  };
  return lm;
}

}  // namespace csympnet
