#include "csympnet/train/adamw.hpp"

#include <cmath>
#include <cstring>
#include <string>

#include "csympnet/core/error.hpp"

#include "../kernels/adamw_update.hpp"

namespace csympnet {

void AdamWOptions::validate() const {
  auto finite_pos = [](double x) { return std::isfinite(x) && x > 0.0; };
  kLrRange.check(lr);
  require(std::isfinite(beta1) && beta1 >= 0.0 && beta1 < 1.0,
          [&] { return "adamw.beta1 must be in [0, 1), got " + std::to_string(beta1); });
  require(std::isfinite(beta2) && beta2 >= 0.0 && beta2 < 1.0,
          [&] { return "adamw.beta2 must be in [0, 1), got " + std::to_string(beta2); });
  require(finite_pos(eps),
          [&] { return "adamw.eps must be a finite number > 0, got " + std::to_string(eps); });
  kWeightDecayRange.check(weight_decay);
}

void to_json(nlohmann::json& j, const AdamWOptions& o) {
  j = {{"lr", o.lr},
       {"beta1", o.beta1},
       {"beta2", o.beta2},
       {"eps", o.eps},
       {"weight_decay", o.weight_decay},
       {"decay_damping", o.decay_damping}};
}

void from_json(const nlohmann::json& j, AdamWOptions& o) {
  o.lr = j.value("lr", o.lr);
  o.beta1 = j.value("beta1", o.beta1);
  o.beta2 = j.value("beta2", o.beta2);
  o.eps = j.value("eps", o.eps);
  o.weight_decay = j.value("weight_decay", o.weight_decay);
  o.decay_damping = j.value("decay_damping", o.decay_damping);
}

AdamW::AdamW(Index n_params, AdamWOptions options, std::optional<Index> damping_index)
    : opt_(options), damping_index_(damping_index) {
  opt_.validate();
  m_.setZero(n_params);
  v_.setZero(n_params);
}

void AdamW::check_sizes(ParamsRef theta, const Vector& g) const {
  // Tested before the message is built: a std::string of it would be an allocation per step.
  if (theta.size() != m_.size() || g.size() != m_.size()) {
    throw Error("AdamW::step: parameter and gradient sizes must match the optimiser's (" +
                std::to_string(m_.size()) + "), got " + std::to_string(theta.size()) + " and " +
                std::to_string(g.size()));
  }
}

namespace {

// The step's scalars, formed once per step as Eigen's expressions of the update use them.
kernels::AdamWScalars step_scalars(const AdamWOptions& o, long t_steps) {
  const double t = static_cast<double>(t_steps);
  const double bias1 = 1.0 - std::pow(o.beta1, t);
  const double bias2_sqrt = std::sqrt(1.0 - std::pow(o.beta2, t));
  return {1.0 - o.lr * o.weight_decay,
          o.beta1,
          1.0 - o.beta1,
          o.beta2,
          1.0 - o.beta2,
          o.lr / bias1,
          bias2_sqrt,
          o.eps};
}

}  // namespace

void AdamW::step(ParamsRef theta, const Vector& g) {
  check_sizes(theta, g);
  ++t_;
  const bool exclude = !opt_.decay_damping && damping_index_.has_value();
  kernels::adamw_update(step_scalars(opt_, t_), theta.data(), m_.data(), v_.data(), g.data(),
                        m_.size(), exclude ? *damping_index_ : Index{-1});
}

}  // namespace csympnet
