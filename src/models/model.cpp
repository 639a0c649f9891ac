#include "csympnet/models/model.hpp"

#include "csympnet/core/error.hpp"

namespace csympnet {

std::string Model::type() const {
  return map ? map->type() : field->type();
}
Index Model::dim() const {
  return map ? map->dim() : field->dim();
}
Index Model::n_params() const {
  return map ? map->n_params() : field->n_params();
}

void Model::init_params(Rng& rng, ParamsRef theta) const {
  map ? map->init_params(rng, theta) : field->init_params(rng, theta);
}

std::optional<double> Model::damping_rate(ConstParams theta) const {
  return map ? map->damping_rate(theta) : field->damping_rate(theta);
}

std::optional<Index> Model::damping_param_index() const {
  return map ? map->damping_param_index() : field->damping_param_index();
}

nlohmann::json Model::hyperparams() const {
  return map ? map->hyperparams() : field->hyperparams();
}

std::vector<std::string> model_types() {
  return {"csympnet", "sympnet", "map", "ode", "dhnn", "dhnn2", "phnn", "phnn2"};
}

bool is_vector_field_type(const std::string& type) {
  return type == "ode" || type == "dhnn" || type == "dhnn2" || type == "phnn" || type == "phnn2";
}

Model make_model(const nlohmann::json& spec) {
  require(spec.is_object() && spec.contains("type") && spec["type"].is_string(),
          "model spec needs a string \"type\"; expected one of csympnet, sympnet, map, ode, dhnn, "
          "dhnn2, phnn, phnn2, la, g");
  Model m;
  if (is_vector_field_type(spec["type"].get<std::string>()))
    m.field = make_vector_field_model(spec);
  else
    m.map = make_one_step_map(spec);
  // Refused here, before any parameter vector is allocated: a size accepted by every option
  // check must not end in std::bad_alloc later (a parameter vector, its AdamW moments and
  // gradients take several copies).
  const Index n = m.n_params();
  require(n >= 0 && n <= kMaxModelParams, [&] {
    return "the model would have " + std::to_string(n) + " parameters, more than the " +
           std::to_string(kMaxModelParams) +
           " this tool holds in memory; expected smaller sizes (the core's layers, "
           "sublayers or width, as in --core, the hidden widths, or d)";
  });
  return m;
}

}  // namespace csympnet
