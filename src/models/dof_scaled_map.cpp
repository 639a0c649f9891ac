#include "csympnet/models/dof_scaled_map.hpp"

#include <cmath>

#include "csympnet/core/error.hpp"

namespace csympnet {

DofScaledMap::DofScaledMap(std::unique_ptr<OneStepMap> inner)
    : inner_(std::move(inner)), d_(inner_ ? inner_->dim() / 2 : 0) {
  require(inner_ != nullptr, "dof-scaled map: no inner model");
  require(inner_->n_inputs() == 0,
          "dof-scaled map: the inner map takes known inputs, which the per-dof scales do not "
          "pass on; a driven record is fitted on its positions, without dof scales");
}

void DofScaledMap::init_params(Rng& rng, ParamsRef theta) const {
  require(theta.size() == n_params(), "dof-scaled map: parameter vector has the wrong size");
  inner_->init_params(rng, theta.head(inner_->n_params()));
  theta.tail(d_ - 1).setZero();  // μ = 1: the wrapped map to the bit
}

Vector DofScaledMap::scales(ConstParams theta) const {
  require(theta.size() == n_params(), [&] {
    return "dof-scaled map: parameter vector has size " + std::to_string(theta.size()) +
           ", expected " + std::to_string(n_params());
  });
  Vector mu(d_);
  mu(0) = 1.0;
  for (Index i = 1; i < d_; ++i) mu(i) = std::exp(theta(inner_->n_params() + i - 1));
  return mu;
}

Matrix DofScaledMap::forward(ConstParams theta, const Matrix& Z, const Vector& h,
                             ForwardCache* cache) const {
  const Vector mu = scales(theta);
  Matrix zs = Z;
  zs.bottomRows(d_) = mu.asDiagonal() * Z.bottomRows(d_);
  Context* ctx = cache != nullptr ? &cache->make_context<Context>() : nullptr;
  Matrix out = inner_->forward(theta.head(inner_->n_params()), zs, h,
                               ctx != nullptr ? &ctx->inner : nullptr);
  out.bottomRows(d_) = mu.cwiseInverse().asDiagonal() * out.bottomRows(d_);
  if (ctx != nullptr) {
    ctx->p_scaled = zs.bottomRows(d_);
    ctx->p_out = out.bottomRows(d_);
  }
  return out;
}

void DofScaledMap::backward(ConstParams theta, const ForwardCache& cache, const Matrix& dZout,
                            ParamsRef grad, Matrix* dZin) const {
  const Context& ctx = cache.context<Context>("dof-scaled map: backward");
  const Vector mu = scales(theta);
  const Index pin = inner_->n_params();
  // out_p = out'_p / μ: dL/dout'_p = dL/dout_p / μ, and ∂/∂ν_i of out_p,i = −out_p,i.
  Matrix up = dZout;
  up.bottomRows(d_) = mu.cwiseInverse().asDiagonal() * dZout.bottomRows(d_);
  Matrix dzs;
  inner_->backward(theta.head(pin), ctx.inner, up, grad.head(pin), &dzs);
  // z'_p = μ z_p: ∂/∂ν_i of z'_p,i = z'_p,i.
  for (Index i = 1; i < d_; ++i)
    grad(pin + i - 1) +=
        dzs.row(d_ + i).dot(ctx.p_scaled.row(i)) - dZout.row(d_ + i).dot(ctx.p_out.row(i));
  if (dZin != nullptr) {
    *dZin = dzs;
    dZin->bottomRows(d_) = mu.asDiagonal() * dzs.bottomRows(d_);
  }
}

Matrix DofScaledMap::jacobian(ConstParams theta, const Vector& z, double h) const {
  const Vector mu = scales(theta);
  Vector diag = Vector::Ones(2 * d_);
  diag.tail(d_) = mu;
  Vector zs = z;
  zs.tail(d_) = mu.asDiagonal() * z.tail(d_);
  const Matrix j = inner_->jacobian(theta.head(inner_->n_params()), zs, h);
  return diag.cwiseInverse().asDiagonal() * j * diag.asDiagonal();
}

nlohmann::json DofScaledMap::hyperparams() const {
  nlohmann::json j = inner_->hyperparams();
  j["dof_scales"] = "learned";
  return j;
}

}  // namespace csympnet
