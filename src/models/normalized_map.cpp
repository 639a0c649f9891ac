#include "csympnet/models/normalized_map.hpp"

#include "csympnet/core/error.hpp"

namespace csympnet {

NormalizedMap::NormalizedMap(std::unique_ptr<OneStepMap> inner, Normalization normalization)
    : inner_(std::move(inner)), norm_(std::move(normalization)) {
  require(inner_ != nullptr, "normalized map: no inner model");
  norm_.validate("model spec.normalization");
  require(2 * norm_.d() == inner_->dim(), [&] {
    return "model spec.normalization: has " + std::to_string(norm_.d()) +
           " degrees of freedom, the model " + std::to_string(inner_->dim() / 2);
  });
  unit_ = norm_.unit();
}

Matrix NormalizedMap::forward(ConstParams theta, const Matrix& Z, const Vector& h,
                              ForwardCache* cache) const {
  require(h.size() == Z.cols(), "normalized map: need one step per column");
  const Vector hn = h / norm_.time_scale;
  return norm_.from_normal(inner_->forward(theta, norm_.to_normal(Z), hn, cache));
}

Matrix NormalizedMap::forward_driven(ConstParams theta, const Matrix& Z, const Vector& h,
                                     const Matrix& U, ForwardCache* cache) const {
  if (U.rows() == 0) return forward(theta, Z, h, cache);
  require(h.size() == Z.cols(), "normalized map: need one step per column");
  const Vector hn = h / norm_.time_scale;
  return norm_.from_normal(inner_->forward_driven(theta, norm_.to_normal(Z), hn, U, cache));
}

Matrix NormalizedMap::jacobian_driven(ConstParams theta, const Vector& z, double h,
                                      const Vector& u) const {
  if (u.size() == 0) return jacobian(theta, z, h);
  const Matrix zn = norm_.to_normal(z);
  const Matrix jn = inner_->jacobian_driven(theta, zn.col(0), h / norm_.time_scale, u);
  return unit_.asDiagonal() * jn * unit_.cwiseInverse().asDiagonal();
}

void NormalizedMap::backward(ConstParams theta, const ForwardCache& cache, const Matrix& dZout,
                             ParamsRef grad, Matrix* dZin) const {
  // out = N⁻¹ out̂ (+ shift): dL/dout̂ = diag(unit) dL/dout; ẑ = N z: dL/dz = dL/dẑ / unit.
  const Matrix upstream = unit_.asDiagonal() * dZout;
  inner_->backward(theta, cache, upstream, grad, dZin);
  if (dZin != nullptr) *dZin = unit_.cwiseInverse().asDiagonal() * (*dZin);
}

Matrix NormalizedMap::jacobian(ConstParams theta, const Vector& z, double h) const {
  const Matrix zn = norm_.to_normal(z);
  const Matrix jn = inner_->jacobian(theta, zn.col(0), h / norm_.time_scale);
  return unit_.asDiagonal() * jn * unit_.cwiseInverse().asDiagonal();
}

std::optional<double> NormalizedMap::damping_rate(ConstParams theta) const {
  const auto g = inner_->damping_rate(theta);
  if (!g) return g;
  return *g / norm_.time_scale;
}

nlohmann::json NormalizedMap::hyperparams() const {
  nlohmann::json j = inner_->hyperparams();
  j["normalization"] = norm_;
  return j;
}

}  // namespace csympnet
