// LA-SympNet(L, m) (Jin et al. 2020), step-dependent: every increment is multiplied by h.
//
//   linear module k (m sublayers, kick first; S = A + Aᵀ keeps each shear symplectic):
//     kick  p += h S q,   drift  q += h S p,   ...,   then  p += h b_p,  q += h b_q
//   activation module j between linear modules j and j+1 (kick for even j, drift for odd j):
//     kick  p += h a ⊙ σ(q),   drift  q += h a ⊙ σ(p)
//
// Layout of θ, in application order; d x d matrices are column-major:
//   for k = 0 .. L-1:  A_{k,0}, ..., A_{k,m-1} (d² each), b_p (d), b_q (d),
//                      then, if k < L-1, the activation amplitude a_k (d).
// n_params = L (m d² + 2d) + (L − 1) d.
//
// init_params walks θ in that order and draws one rng.normal() per A or a entry (scaled by
// kInitStddev = 0.01); biases are set to 0 without consuming draws.
#pragma once

#include "csympnet/models/symplectic_core.hpp"

namespace csympnet {

class LaSympNet final : public SymplecticCore {
 public:
  static constexpr double kInitStddev = 0.01;

  // Throws Error unless d, layers, sublayers >= 1.
  LaSympNet(Index d, Index layers, Index sublayers);

  std::string type() const override { return "la"; }
  Index n_params() const override;
  void init_params(Rng& rng, ParamsRef theta) const override;
  nlohmann::json core_spec() const override;
  std::size_t cache_slots() const override;

  void flow(ConstParams theta, Matrix& q, Matrix& p, const Vector& h, ForwardCache* cache,
            std::size_t slot0) const override;
  void flow_backward(ConstParams theta, const ForwardCache& cache, std::size_t slot0,
                     const Vector& h, Matrix& gq, Matrix& gp, ParamsRef grad) const override;
  void flow_tangent(ConstParams theta, Vector& q, Vector& p, Matrix& tq, Matrix& tp,
                    double h) const override;

  Index layers() const { return layers_; }
  Index sublayers() const { return sublayers_; }

 private:
  // flow() and flow_backward() for d = 1 (src/models/la_sympnet.cpp).
  void flow_scalar(ConstParams theta, Matrix& q, Matrix& p, const Vector& h, ForwardCache* cache,
                   std::size_t slot0) const;
  void flow_backward_scalar(ConstParams theta, const ForwardCache& cache, std::size_t slot0,
                            const Vector& h, Matrix& gq, Matrix& gp, ParamsRef grad) const;

  // Offset of linear module k in θ (each module but the last is followed by its activation).
  Index module_offset(Index k) const { return k * (sublayers_ * d() * d() + 3 * d()); }

  Index layers_;
  Index sublayers_;
};

}  // namespace csympnet
