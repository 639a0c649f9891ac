#include "csympnet/models/csympnet_id.hpp"

#include <cmath>

#include "csympnet/core/error.hpp"
#include "csympnet/models/shape_checks.hpp"

namespace csympnet {

namespace {

// d|β|/dβ, with the subgradient 0 at β = 0.
double abs_derivative(double beta) {
  if (beta > 0.0) return 1.0;
  if (beta < 0.0) return -1.0;
  return 0.0;
}

}  // namespace

CSympNetId::CSympNetId(std::unique_ptr<SymplecticCore> core, double beta_init)
    : core_(std::move(core)), beta_init_(beta_init) {
  require(core_ != nullptr, "csympnet: the symplectic core must not be null");
  require(std::isfinite(beta_init) && beta_init != 0.0,
          "csympnet: beta_init = " + std::to_string(beta_init) +
              ", expected a finite nonzero value (d|beta|/dbeta vanishes at 0, so beta would "
              "never train)");
}

void CSympNetId::init_params(Rng& rng, ParamsRef theta) const {
  check_theta(*this, theta, "init_params");
  const Index nc = core_->n_params();
  core_->init_params(rng, theta.head(nc));
  theta(nc) = beta_init_;
}

Matrix CSympNetId::forward(ConstParams theta, const Matrix& Z, const Vector& h,
                           ForwardCache* cache) const {
  check_forward_args(*this, theta, Z, h);
  const Index d = core_->d();
  const Index nc = core_->n_params();
  const double gamma = std::abs(theta(nc));
  // a_j = exp(−γ̂ h_j / 2), the conformal factor of S_a for sample j.
  const Vector a = (-0.5 * gamma * h.array()).exp().matrix();
  Matrix q = Z.topRows(d);
  Matrix p = Z.bottomRows(d);
  p.array().rowwise() *= a.transpose().array();
  if (cache != nullptr) {
    if (cache->vecs.size() < 2) cache->vecs.resize(2);
    if (cache->mats.size() < kCoreSlot0) cache->mats.resize(kCoreSlot0);
    cache->vecs[0] = h;
    cache->vecs[1] = a;
    cache->mats[0] = Z.bottomRows(d);
  }
  core_->flow(theta.head(nc), q, p, h, cache, kCoreSlot0);
  if (cache != nullptr) cache->mats[1] = p;
  Matrix out(2 * d, Z.cols());
  out.topRows(d) = q;
  out.bottomRows(d) = (p.array().rowwise() * a.transpose().array()).matrix();
  return out;
}

void CSympNetId::backward(ConstParams theta, const ForwardCache& cache, const Matrix& dZout,
                          ParamsRef grad, Matrix* dZin) const {
  const bool recorded =
      cache.vecs.size() >= 2 && cache.mats.size() >= kCoreSlot0 + core_->cache_slots();
  check_backward_args(*this, theta, recorded ? cache.vecs[0].size() : -1, dZout, grad);
  const Index d = core_->d();
  const Index nc = core_->n_params();
  const Vector& h = cache.vecs[0];
  const Vector& a = cache.vecs[1];
  const auto arow = a.transpose().array();
  Matrix gq = dZout.topRows(d);
  Matrix gp = dZout.bottomRows(d);
  // Outer scaling p_out = a ⊙ p_core:  dL/da_j = Σ_i G_ij p_core,ij,  dL/dp_core = a G.
  Vector grad_a = (gp.array() * cache.mats[1].array()).colwise().sum().transpose();
  gp.array().rowwise() *= arow;
  core_->flow_backward(theta.head(nc), cache, kCoreSlot0, h, gq, gp, grad.head(nc));
  // Inner scaling p̃ = a ⊙ p_in:  dL/da_j += Σ_i G̃_ij p_in,ij,  dL/dp_in = a G̃.
  grad_a.array() += (gp.array() * cache.mats[0].array()).colwise().sum().transpose();
  // a_j = exp(−|β| h_j / 2):  da_j/dβ = −(h_j / 2) a_j sign(β).
  grad(nc) += -0.5 * abs_derivative(theta(nc)) * (grad_a.array() * h.array() * a.array()).sum();
  if (dZin != nullptr) {
    gp.array().rowwise() *= arow;
    dZin->resize(2 * d, dZout.cols());
    dZin->topRows(d) = gq;
    dZin->bottomRows(d) = gp;
  }
}

Matrix CSympNetId::jacobian(ConstParams theta, const Vector& z, double h) const {
  check_jacobian_args(*this, theta, z);
  const Index d = core_->d();
  const Index nc = core_->n_params();
  const double a = std::exp(-0.5 * std::abs(theta(nc)) * h);
  // DΦ̂ = diag(I, aI) DΨ(S_a z) diag(I, aI): start the tangents at diag(I, aI).
  Vector q = z.head(d);
  Vector p = a * z.tail(d);
  Matrix tq = Matrix::Zero(d, 2 * d);
  Matrix tp = Matrix::Zero(d, 2 * d);
  tq.leftCols(d).setIdentity();
  tp.rightCols(d).diagonal().setConstant(a);
  core_->flow_tangent(theta.head(nc), q, p, tq, tp, h);
  Matrix jac(2 * d, 2 * d);
  jac.topRows(d) = tq;
  jac.bottomRows(d) = a * tp;
  return jac;
}

std::optional<double> CSympNetId::damping_rate(ConstParams theta) const {
  check_theta(*this, theta, "damping_rate");
  return std::abs(theta(n_params() - 1));
}

nlohmann::json CSympNetId::hyperparams() const {
  return {{"type", "csympnet"},
          {"d", core_->d()},
          {"core", core_->core_spec()},
          {"beta_init", beta_init_}};
}

}  // namespace csympnet
