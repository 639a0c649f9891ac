#include "symplectic_core.hpp"

#include "csympnet/core/error.hpp"
#include "shape_checks.hpp"

namespace csympnet {

SymplecticCore::SymplecticCore(Index d) : d_(d) {
  require(d >= 1,
          [&] { return "symplectic core: d = " + std::to_string(d) + ", expected d >= 1"; });
}

void SymplecticCore::flow(ConstParams theta, Matrix& q, Matrix& p, const Vector& h,
                          ForwardCache* flow_cache) const {
  if (flow_cache != nullptr) size_flow(*flow_cache, q.cols(), false);
  flow_columns(theta, q, p, h, flow_cache, {0, q.cols()});
}

Matrix SymplecticCore::forward(ConstParams theta, const Matrix& Z, const Vector& h,
                               ForwardCache* cache) const {
  check_forward_args(*this, theta, Z, h);
  Matrix q = Z.topRows(d_);
  Matrix p = Z.bottomRows(d_);
  ForwardCache* flow_cache = nullptr;
  if (cache != nullptr) {
    auto& ctx = cache->make_context<MapContext>();
    ctx.h = h;
    flow_cache = &ctx.flow;
  }
  flow(theta, q, p, h, flow_cache);
  Matrix out(2 * d_, Z.cols());
  out.topRows(d_) = q;
  out.bottomRows(d_) = p;
  return out;
}

void SymplecticCore::backward(ConstParams theta, const ForwardCache& cache, const Matrix& dZout,
                              ParamsRef grad, Matrix* dZin) const {
  const auto& ctx = cache.context<MapContext>("symplectic core backward");
  check_backward_args(*this, theta, ctx.h.size(), dZout, grad);
  Matrix gq = dZout.topRows(d_);
  Matrix gp = dZout.bottomRows(d_);
  flow_backward(theta, ctx.flow, ctx.h, gq, gp, grad);
  if (dZin != nullptr) {
    dZin->resize(2 * d_, dZout.cols());
    dZin->topRows(d_) = gq;
    dZin->bottomRows(d_) = gp;
  }
}

Matrix SymplecticCore::jacobian(ConstParams theta, const Vector& z, double h) const {
  check_jacobian_args(*this, theta, z);
  Vector q = z.head(d_);
  Vector p = z.tail(d_);
  // Tangent columns start as the identity: tq = [I 0], tp = [0 I].
  Matrix tq = Matrix::Zero(d_, 2 * d_);
  Matrix tp = Matrix::Zero(d_, 2 * d_);
  tq.leftCols(d_).setIdentity();
  tp.rightCols(d_).setIdentity();
  flow_tangent(theta, q, p, tq, tp, h);
  Matrix jac(2 * d_, 2 * d_);
  jac.topRows(d_) = tq;
  jac.bottomRows(d_) = tp;
  return jac;
}

nlohmann::json SymplecticCore::hyperparams() const {
  nlohmann::json spec = core_spec();
  spec["d"] = d_;
  return spec;
}

}  // namespace csympnet
