#include "map_baseline.hpp"

#include <string>
#include <utility>

#include "csympnet/core/error.hpp"
#include "shape_checks.hpp"

namespace csympnet {

namespace {

std::vector<Index> map_net_sizes(Index d, Index width) {
  require(d >= 1 && width >= 1, [&] {
    return "map: d = " + std::to_string(d) + ", width = " + std::to_string(width) +
           ", expected both >= 1";
  });
  return {2 * d + 1, width, width, 2 * d};
}

}  // namespace

MapBaseline::MapBaseline(Index d, Index width)
    : d_(d), width_(width), net_(map_net_sizes(d, width)) {}

void MapBaseline::init_params(Rng& rng, ParamsRef theta) const {
  check_theta(*this, theta, "init_params");
  net_.init_params(rng, theta);
}

Matrix MapBaseline::forward(ConstParams theta, const Matrix& Z, const Vector& h,
                            ForwardCache* cache) const {
  check_forward_args(*this, theta, Z, h);
  Matrix input(Z.rows() + 1, Z.cols());
  input.topRows(Z.rows()) = Z;
  input.row(Z.rows()) = h.transpose();
  if (cache == nullptr) return Z + net_.forward(theta, input, nullptr);
  Context& ctx = cache->make_context<Context>();
  Matrix out = Z + net_.forward(theta, input, &ctx.net);
  ctx.h = h;
  return out;
}

void MapBaseline::backward(ConstParams theta, const ForwardCache& cache, const Matrix& dZout,
                           ParamsRef grad, Matrix* dZin) const {
  const Context& ctx = cache.context<Context>("map::backward");
  check_backward_args(*this, theta, ctx.h.size(), dZout, grad);
  if (dZin == nullptr) {
    net_.backward(theta, ctx.net, dZout, grad, nullptr);
    return;
  }
  // z' = z + MLP([z; h]): the identity path adds dZout; the h row of dX is dropped.
  Matrix dx;
  net_.backward(theta, ctx.net, dZout, grad, &dx);
  *dZin = dZout + dx.topRows(dim());
}

Matrix MapBaseline::jacobian(ConstParams theta, const Vector& z, double h) const {
  check_jacobian_args(*this, theta, z);
  Vector x(dim() + 1);
  x.head(dim()) = z;
  x(dim()) = h;
  Matrix jac = net_.input_jacobian(theta, x).leftCols(dim());
  jac.diagonal().array() += 1.0;
  return jac;
}

nlohmann::json MapBaseline::hyperparams() const {
  return {{"type", "map"}, {"d", d_}, {"width", width_}};
}

}  // namespace csympnet
