// A model of either family, as the training loop, the diagnostics and model files see it:
// a one-step map (CSympNet-ID, SympNet, MapBaseline) or a vector field whose one-step map is
// induced by integration (ODE, DHNN, DHNN2, pHNN, pHNN2). Exactly one member is set.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/models/one_step_map.hpp"
#include "csympnet/models/vector_field_model.hpp"

namespace csympnet {

struct Model {
  std::unique_ptr<OneStepMap> map;
  std::unique_ptr<VectorFieldModel> field;

  bool is_map() const { return map != nullptr; }
  std::string type() const;
  Index dim() const;
  Index n_params() const;
  void init_params(Rng& rng, ParamsRef theta) const;
  std::optional<double> damping_rate(ConstParams theta) const;
  std::optional<Index> damping_param_index() const;
  nlohmann::json hyperparams() const;
};

// Every model type, map models first: csympnet, sympnet, map, ode, dhnn, dhnn2, phnn, phnn2.
std::vector<std::string> model_types();
bool is_vector_field_type(const std::string& type);

// The most parameters a model may have: 5e7 (400 MB per copy of θ; training holds several).
inline constexpr Index kMaxModelParams = 50'000'000;

// Dispatches on spec["type"] to make_one_step_map or make_vector_field_model; refuses a
// model with more than kMaxModelParams parameters.
Model make_model(const nlohmann::json& spec);

}  // namespace csympnet
