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
#include <string>

#include "csympnet/core/error.hpp"
#include "spec_reading.hpp"
#include "vector_field_models.hpp"

namespace csympnet {

namespace {

using nlohmann::json;
using namespace specs;

constexpr const char* kValidFieldTypes = "ode, dhnn, dhnn2, phnn, phnn2";
const std::string kWhere = "vector-field model spec";

}  // namespace

std::unique_ptr<VectorFieldModel> make_vector_field_model(const nlohmann::json& spec) {
  require_object(spec, kWhere);
  const std::string type = get_type(spec, kWhere, kValidFieldTypes);
  const std::string typed = kWhere + " (type '" + type + "')";
  if (type == "ode") {
    reject_unknown_keys(spec, typed, {"type", "d", "width"});
    return std::make_unique<OdeField>(get_count(spec, "d", kWhere),
                                      get_count(spec, "width", kWhere));
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
    throw Error(kWhere + ": unknown model type '" + type + "'; expected one of " +
                kValidFieldTypes);
  }
  const bool damped = kind == Dissipation::kMomentumDamping || kind == Dissipation::kPortDamping;
  if (damped) {
    reject_unknown_keys(spec, typed, {"type", "d", "width", "beta_init", "freeze_structure"});
  } else {
    reject_unknown_keys(spec, typed, {"type", "d", "width", "freeze_structure"});
  }
  const double beta_init = damped ? get_beta_init(spec, kWhere, HamiltonianField::kDefaultBetaInit)
                                  : HamiltonianField::kDefaultBetaInit;
  return std::make_unique<HamiltonianField>(kind, get_count(spec, "d", kWhere),
                                            get_count(spec, "width", kWhere), beta_init,
                                            get_flag(spec, "freeze_structure", kWhere));
}

}  // namespace csympnet
