#include "csympnet/core/error.hpp"
#include "vector_field_checks.hpp"
#include "vector_field_models.hpp"

namespace csympnet {

namespace {

// Sizes n → w → w → n, validated first so the error names the model's own arguments.
std::vector<Index> field_net_sizes(Index d, Index width) {
  require(d >= 1 && width >= 1, [&] {
    return "ode: d = " + std::to_string(d) + ", width = " + std::to_string(width) +
           ", expected both >= 1";
  });
  return {2 * d, width, width, 2 * d};
}

}  // namespace

OdeField::OdeField(Index d, Index width) : d_(d), width_(width), net_(field_net_sizes(d, width)) {}

void OdeField::init_params(Rng& rng, ParamsRef theta) const {
  detail::check_field_theta(*this, theta.size(), "init_params");
  net_.init_params(rng, theta);
}

Matrix OdeField::field(ConstParams theta, const Matrix& Z) const {
  detail::check_field_theta(*this, theta.size(), "field");
  detail::check_field_rows(*this, Z.rows(), "field", "Z");
  return net_.forward(theta, Z, nullptr);
}

void OdeField::field_backward(ConstParams theta, const Matrix& Z, const Matrix& G,
                              ParamsRef grad) const {
  detail::check_field_backward_args(*this, theta, Z, G, grad);
  // The interface passes no cache, so the forward pass is redone here.
  MlpCache cache;
  net_.forward(theta, Z, &cache);
  net_.backward(theta, cache, G, grad, nullptr);
}

Matrix OdeField::field_jacobian(ConstParams theta, const Vector& z) const {
  detail::check_field_theta(*this, theta.size(), "field_jacobian");
  detail::check_field_rows(*this, z.size(), "field_jacobian", "z");
  return net_.input_jacobian(theta, z);
}

nlohmann::json OdeField::hyperparams() const {
  return {{"type", "ode"}, {"d", d_}, {"width", width_}};
}

}  // namespace csympnet
