#include "csympnet/train/loss.hpp"

namespace csympnet {

double one_step_loss(const OneStepMap& map, ConstParams theta, const PairSet& pairs, Vector* grad,
                     ForwardCache* cache) {
  ForwardCache local;
  ForwardCache* c = grad != nullptr ? (cache != nullptr ? cache : &local) : nullptr;
  // In place: the same elementwise differences and products as `Φ̂ − z1` and `(2/N) r`, without
  // two temporaries per epoch.
  Matrix residual = map.forward(theta, pairs.z0, pairs.h, c);
  residual -= pairs.z1;
  const double n = static_cast<double>(pairs.size());
  const double loss = residual.squaredNorm() / n;
  if (grad != nullptr) {
    grad->setZero(map.n_params());
    // dL/dΦ̂ = (2/N)(Φ̂ − z1)
    residual *= 2.0 / n;
    map.backward(theta, *c, residual, *grad, nullptr);
  }
  return loss;
}

}  // namespace csympnet
