#include "csympnet/train/loss.hpp"

namespace csympnet {

double one_step_loss(const OneStepMap& map, ConstParams theta, const PairSet& pairs, Vector* grad,
                     ForwardCache* cache) {
  ForwardCache local;
  ForwardCache* c = grad != nullptr ? (cache != nullptr ? cache : &local) : nullptr;
  const Matrix residual = map.forward(theta, pairs.z0, pairs.h, c) - pairs.z1;
  const double n = static_cast<double>(pairs.size());
  if (grad != nullptr) {
    grad->setZero(map.n_params());
    // dL/dΦ̂ = (2/N)(Φ̂ − z1)
    map.backward(theta, *c, (2.0 / n) * residual, *grad, nullptr);
  }
  return residual.squaredNorm() / n;
}

}  // namespace csympnet
