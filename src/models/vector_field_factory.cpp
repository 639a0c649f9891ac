// make_vector_field_model: the inverse of VectorFieldModel::hyperparams(). Accepted specs:
//
//   {"type": "ode",   "d": D, "width": W}
//   {"type": "dhnn",  "d": D, "width": W, "freeze_structure": F}
//   {"type": "phnn",  "d": D, "width": W, "freeze_structure": F}
//   {"type": "dhnn2", "d": D, "width": W, "beta_init": B, "freeze_structure": F}
//   {"type": "phnn2", "d": D, "width": W, "beta_init": B, "freeze_structure": F}
//
// freeze_structure (default false) and beta_init (default 0.1, finite and nonzero) are
// optional. Unknown keys are rejected so that a misspelt option fails loudly.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <string>

#include "csympnet/core/error.hpp"
#include "csympnet/models/vector_field_models.hpp"

namespace csympnet {

namespace {

using nlohmann::json;

constexpr const char* kValidTypes = "ode, dhnn, dhnn2, phnn, phnn2";
const std::string kWhere = "vector-field model spec";

void reject_unknown_keys(const json& spec, std::initializer_list<const char*> allowed) {
  std::string list;
  for (const char* key : allowed) list += std::string(list.empty() ? "" : ", ") + key;
  for (const auto& item : spec.items()) {
    const bool known = std::any_of(allowed.begin(), allowed.end(),
                                   [&](const char* key) { return item.key() == key; });
    require(known, kWhere + " (type '" + spec.at("type").get<std::string>() + "'): unknown key '" +
                       item.key() + "' (allowed keys: " + list + ")");
  }
}

Index get_count(const json& spec, const char* key) {
  require(spec.contains(key), kWhere + ": missing key '" + key + "' (expected an integer >= 1)");
  const json& value = spec.at(key);
  require(value.is_number_integer(),
          kWhere + ": key '" + key + "' = " + value.dump() + ", expected an integer >= 1");
  const auto count = value.get<std::int64_t>();
  require(count >= 1,
          kWhere + ": key '" + key + "' = " + std::to_string(count) + ", expected an integer >= 1");
  return static_cast<Index>(count);
}

bool get_freeze(const json& spec) {
  if (!spec.contains("freeze_structure")) return false;
  const json& value = spec.at("freeze_structure");
  require(value.is_boolean(),
          kWhere + ": key 'freeze_structure' = " + value.dump() + ", expected true or false");
  return value.get<bool>();
}

double get_beta_init(const json& spec) {
  if (!spec.contains("beta_init")) return HamiltonianField::kDefaultBetaInit;
  const json& value = spec.at("beta_init");
  require(value.is_number(),
          kWhere + ": key 'beta_init' = " + value.dump() + ", expected a nonzero number");
  const double beta = value.get<double>();
  require(std::isfinite(beta) && beta != 0.0,
          kWhere + ": key 'beta_init' = " + value.dump() +
              ", expected a finite nonzero number (d|beta|/dbeta vanishes at 0)");
  return beta;
}

}  // namespace

std::unique_ptr<VectorFieldModel> make_vector_field_model(const nlohmann::json& spec) {
  require(spec.is_object(), kWhere + ": expected a JSON object, got " + spec.dump());
  require(spec.contains("type"),
          kWhere + ": missing key 'type' (expected one of: " + std::string(kValidTypes) + ")");
  require(spec.at("type").is_string(), kWhere + ": key 'type' = " + spec.at("type").dump() +
                                           ", expected a string (one of: " + kValidTypes + ")");
  const std::string type = spec.at("type").get<std::string>();
  if (type == "ode") {
    reject_unknown_keys(spec, {"type", "d", "width"});
    return std::make_unique<OdeField>(get_count(spec, "d"), get_count(spec, "width"));
  }
  Dissipation kind;
  if (type == "dhnn") {
    kind = Dissipation::kNetwork;
  } else if (type == "dhnn2") {
    kind = Dissipation::kMomentumDamping;
  } else if (type == "phnn") {
    kind = Dissipation::kPortMatrix;
  } else if (type == "phnn2") {
    kind = Dissipation::kPortDamping;
  } else {
    throw Error(kWhere + ": unknown model type '" + type + "' (valid types: " + kValidTypes + ")");
  }
  const bool damped = kind == Dissipation::kMomentumDamping || kind == Dissipation::kPortDamping;
  if (damped) {
    reject_unknown_keys(spec, {"type", "d", "width", "beta_init", "freeze_structure"});
  } else {
    reject_unknown_keys(spec, {"type", "d", "width", "freeze_structure"});
  }
  const double beta_init = damped ? get_beta_init(spec) : HamiltonianField::kDefaultBetaInit;
  return std::make_unique<HamiltonianField>(kind, get_count(spec, "d"), get_count(spec, "width"),
                                            beta_init, get_freeze(spec));
}

}  // namespace csympnet
