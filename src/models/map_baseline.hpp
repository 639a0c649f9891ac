// MapBaseline (docs/protocol.md, "Baselines"): an unstructured one-step map
//
//   Φ̂_h(z) = z + MLP([z; h]),   MLP: (q, p, h) → w → w → 2d  (tanh hidden, linear output),
//
// with the step h appended to each column as the last input row. It carries no symplectic or
// conformal structure; it is the paper's "no structure" reference.
//
// Layout of θ: the MLP's (mlp.hpp: per layer W column-major, then b);
// n_params = (2d + 2) w + (w + 1) w + (w + 1) 2d. init_params: PyTorch's nn.Linear default.
#pragma once

#include "csympnet/models/one_step_map.hpp"
#include "mlp.hpp"

namespace csympnet {

class MapBaseline final : public OneStepMap {
 public:
  // Throws Error unless d, width >= 1.
  MapBaseline(Index d, Index width);

  Index width() const { return width_; }

  std::string type() const override { return "map"; }
  Index dim() const override { return 2 * d_; }
  Index n_params() const override { return net_.n_params(); }
  void init_params(Rng& rng, ParamsRef theta) const override;

  // What forward() keeps for backward().
  struct Context final : ForwardContext {
    const char* owner() const override { return "map"; }
    Vector h;      // the steps
    MlpCache net;  // the MLP's activations (its input [Z; hᵀ] first)
  };

  Matrix forward(ConstParams theta, const Matrix& Z, const Vector& h,
                 ForwardCache* cache) const override;
  void backward(ConstParams theta, const ForwardCache& cache, const Matrix& dZout, ParamsRef grad,
                Matrix* dZin) const override;
  // I + the first 2d columns of the MLP's input Jacobian at [z; h].
  Matrix jacobian(ConstParams theta, const Vector& z, double h) const override;
  nlohmann::json hyperparams() const override;

 private:
  Index d_;
  Index width_;
  Mlp net_;
};

}  // namespace csympnet
