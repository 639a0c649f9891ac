#include "csympnet/train/midpoint_loss.hpp"

#include "csympnet/core/error.hpp"

namespace csympnet {

MidpointData midpoint_data(const PairSet& pairs) {
  pairs.validate("pairs");
  MidpointData d;
  d.midpoints = 0.5 * (pairs.z0 + pairs.z1);
  d.slopes = (pairs.z1 - pairs.z0).array().rowwise() / pairs.h.transpose().array();
  return d;
}

double midpoint_loss(const VectorFieldModel& model, ConstParams theta, const MidpointData& data,
                     Vector* grad) {
  require(data.midpoints.rows() == model.dim(), [&] {
    return "midpoint loss: data dimension " + std::to_string(data.midpoints.rows()) +
           " does not match the model's " + std::to_string(model.dim());
  });
  const double n = static_cast<double>(data.midpoints.cols());
  const Matrix residual = model.field(theta, data.midpoints) - data.slopes;
  if (grad != nullptr) {
    grad->setZero(model.n_params());
    model.field_backward(theta, data.midpoints, (2.0 / n) * residual, *grad);  // dL/df
  }
  return residual.squaredNorm() / n;
}

}  // namespace csympnet
