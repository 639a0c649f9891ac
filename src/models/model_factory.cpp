// make_one_step_map: builds a model from its hyperparams JSON, the inverse of
// OneStepMap::hyperparams(). Accepted specs:
//
//   {"type": "la", "d": D, "layers": L, "sublayers": M}          bare LA-SympNet core
//   {"type": "g", "d": D, "layers": L, "width": W}                 bare G-SympNet core
//   {"type": "sympnet", "d": D, "core": CORE}                      SympNet = the core alone
//   {"type": "csympnet", "d": D, "core": CORE, "beta_init": B}     CSympNet-ID (B optional,
//                                                                  default 0.1, nonzero)
//   {"type": "map", "d": D, "width": W}                            MapBaseline
//
// where CORE is {"type": "la", "layers": L, "sublayers": M} or {"type": "g", "layers": L,
// "width": W} (a "d" inside CORE is allowed if it equals the outer d). Unknown keys are
// rejected so that a misspelt option fails loudly instead of silently taking its default.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <string>

#include "csympnet/core/error.hpp"
#include "csympnet/models/csympnet_id.hpp"
#include "csympnet/models/g_sympnet.hpp"
#include "csympnet/models/la_sympnet.hpp"
#include "csympnet/models/map_baseline.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "csympnet/models/sympnet.hpp"

namespace csympnet {

namespace {

using nlohmann::json;

constexpr const char* kValidTypes =
    "csympnet, sympnet, map, ode, dhnn, dhnn2, phnn, phnn2, or a bare core la, g";
constexpr const char* kValidCoreTypes = "la, g";

void require_object(const json& spec, const std::string& where) {
  require(spec.is_object(), where + ": expected a JSON object, got " + spec.dump());
}

void reject_unknown_keys(const json& spec, const std::string& where,
                         std::initializer_list<const char*> allowed) {
  for (const auto& item : spec.items()) {
    const bool known = std::any_of(allowed.begin(), allowed.end(),
                                   [&](const char* key) { return item.key() == key; });
    std::string list;
    for (const char* key : allowed) list += std::string(list.empty() ? "" : ", ") + key;
    require(known, where + ": unknown key '" + item.key() + "' (allowed keys: " + list + ")");
  }
}

std::string get_type(const json& spec, const std::string& where, const char* valid) {
  require(spec.contains("type"),
          where + ": missing key 'type' (expected one of: " + std::string(valid) + ")");
  require(spec.at("type").is_string(), where + ": key 'type' = " + spec.at("type").dump() +
                                           ", expected a string (one of: " + valid + ")");
  return spec.at("type").get<std::string>();
}

Index get_count(const json& spec, const char* key, const std::string& where) {
  require(spec.contains(key), where + ": missing key '" + key + "' (expected an integer >= 1)");
  const json& value = spec.at(key);
  require(value.is_number_integer(),
          where + ": key '" + key + "' = " + value.dump() + ", expected an integer >= 1");
  const auto count = value.get<std::int64_t>();
  require(count >= 1,
          where + ": key '" + key + "' = " + std::to_string(count) + ", expected an integer >= 1");
  return static_cast<Index>(count);
}

// `d` comes from the enclosing spec; a core spec may repeat it only if it agrees.
std::unique_ptr<SymplecticCore> make_core(const json& spec, Index d, const std::string& where) {
  require_object(spec, where);
  const std::string type = get_type(spec, where, kValidCoreTypes);
  if (spec.contains("d")) {
    const Index inner = get_count(spec, "d", where);
    require(inner == d, where + ": key 'd' = " + std::to_string(inner) +
                            " disagrees with the model's d = " + std::to_string(d));
  }
  if (type == "la") {
    reject_unknown_keys(spec, where, {"type", "d", "layers", "sublayers"});
    return std::make_unique<LaSympNet>(d, get_count(spec, "layers", where),
                                       get_count(spec, "sublayers", where));
  }
  if (type == "g") {
    reject_unknown_keys(spec, where, {"type", "d", "layers", "width"});
    return std::make_unique<GSympNet>(d, get_count(spec, "layers", where),
                                      get_count(spec, "width", where));
  }
  throw Error(where + ": unknown core type '" + type + "' (valid core types: " + kValidCoreTypes +
              ")");
}

double get_beta_init(const json& spec, const std::string& where) {
  if (!spec.contains("beta_init")) return CSympNetId::kDefaultBetaInit;
  const json& value = spec.at("beta_init");
  require(value.is_number(),
          where + ": key 'beta_init' = " + value.dump() + ", expected a nonzero number");
  const double beta = value.get<double>();
  require(std::isfinite(beta) && beta != 0.0,
          where + ": key 'beta_init' = " + value.dump() +
              ", expected a finite nonzero number (d|beta|/dbeta vanishes at 0)");
  return beta;
}

}  // namespace

std::unique_ptr<OneStepMap> make_one_step_map(const nlohmann::json& spec) {
  const std::string where = "model spec";
  require_object(spec, where);
  const std::string type = get_type(spec, where, kValidTypes);
  if (type == "la" || type == "g") return make_core(spec, get_count(spec, "d", where), where);
  if (type == "sympnet" || type == "csympnet") {
    const bool conformal = type == "csympnet";
    if (conformal) {
      reject_unknown_keys(spec, where, {"type", "d", "core", "beta_init"});
    } else {
      reject_unknown_keys(spec, where, {"type", "d", "core"});
    }
    const Index d = get_count(spec, "d", where);
    require(spec.contains("core"), where + ": missing key 'core' (expected e.g. {\"type\": " +
                                       "\"la\", \"layers\": 5, \"sublayers\": 20})");
    auto core = make_core(spec.at("core"), d, where + ".core");
    if (!conformal) return std::make_unique<SympNet>(std::move(core));
    return std::make_unique<CSympNetId>(std::move(core), get_beta_init(spec, where));
  }
  if (type == "map") {
    reject_unknown_keys(spec, where, {"type", "d", "width"});
    return std::make_unique<MapBaseline>(get_count(spec, "d", where),
                                         get_count(spec, "width", where));
  }
  throw Error(where + ": unknown model type '" + type + "' (valid types: " + kValidTypes + ")");
}

}  // namespace csympnet
