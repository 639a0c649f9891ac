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
//
// Any of the map specs may carry "normalization": {"q_shift": [..], "q_scale": [..],
// "p_scale": [..], "time_scale": T} (data/normalization.hpp): the model then works in the
// user's units (NormalizedMap) around the same parameters, and "dof_scales": "learned" (data
// with velocities: DofScaledMap, d − 1 parameters after the others).
//
// where CORE is {"type": "la", "layers": L, "sublayers": M}, {"type": "g", "layers": L,
// "width": W}, or, for "csympnet" only, {"type": "library", "terms": [...], "order": 4,
// "substeps": N, "mass": "full"} (the Hamiltonian-library map, hamiltonian_library.hpp) (a "d"
// inside CORE is allowed if it equals the outer d). Unknown keys are rejected so that a misspelt
// option fails loudly instead of silently taking its default.
#include <cmath>
#include <string>

#include "csympnet/core/error.hpp"
#include "csympnet/models/dof_scaled_map.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/models/normalized_map.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "csympnet_id.hpp"
#include "g_sympnet.hpp"
#include "la_sympnet.hpp"
#include "map_baseline.hpp"
#include "spec_reading.hpp"
#include "sympnet.hpp"

namespace csympnet {

namespace {

using nlohmann::json;
using namespace specs;

constexpr const char* kValidTypes =
    "csympnet, sympnet, map, ode, dhnn, dhnn2, phnn, phnn2, or a bare core la, g";
constexpr const char* kValidCoreTypes = "la, g (and library inside a csympnet spec)";

// {"type": "library", "terms": [...], "order": 4, "substeps": n, "mass": "full"|"diagonal"}
// inside a "csympnet" spec: the Hamiltonian-library map (hamiltonian_library.hpp).
std::unique_ptr<OneStepMap> make_library_map(const json& spec, Index d, double beta_init,
                                             const std::string& where) {
  reject_unknown_keys(spec, where,
                      {"type", "d", "terms", "order", "substeps", "mass", "coordinate_scales"});
  require(spec.contains("terms") && spec.at("terms").is_array() && !spec.at("terms").empty(), [&] {
    return where + ": key 'terms' must be a non-empty list of term names, e.g. " +
           "[\"q1^2\", \"q1^4\"] (csympnet fit --core library selects them)";
  });
  std::vector<LibraryTerm> terms;
  for (const json& name : spec.at("terms")) {
    require(name.is_string(),
            [&] { return where + ".terms: expected strings, got " + name.dump(); });
    terms.push_back(parse_term(name.get<std::string>(), d, where + ".terms"));
  }
  const Index order = spec.contains("order") ? get_count(spec, "order", where) : 4;
  const Index substeps = spec.contains("substeps") ? get_count(spec, "substeps", where) : 1;
  std::string mass = "full";
  if (spec.contains("mass")) {
    require(spec.at("mass") == "full" || spec.at("mass") == "diagonal", [&] {
      return where + ": key 'mass' = " + spec.at("mass").dump() +
             ", expected \"full\" or \"diagonal\"";
    });
    mass = spec.at("mass").get<std::string>();
  }
  require(order == 2 || order == 4 || order == 6, [&] {
    return where + ": key 'order' = " + std::to_string(order) + ", expected 2, 4 or 6";
  });
  Vector scales;
  if (spec.contains("coordinate_scales")) {
    const json& v = spec.at("coordinate_scales");
    require(v.is_array() && static_cast<Index>(v.size()) == d, [&] {
      return where + ": key 'coordinate_scales' must be a list of " + std::to_string(d) +
             " positive numbers";
    });
    scales.resize(d);
    for (Index i = 0; i < d; ++i) {
      const json& x = v.at(static_cast<std::size_t>(i));
      require(x.is_number() && x.get<double>() > 0.0 && std::isfinite(x.get<double>()), [&] {
        return where + ".coordinate_scales[" + std::to_string(i) + "] = " + x.dump() +
               ", expected a positive finite number";
      });
      scales(i) = x.get<double>();
    }
  }
  return std::make_unique<HamiltonianLibraryMap>(d, std::move(terms), static_cast<int>(order),
                                                 substeps, mass == "full", beta_init,
                                                 std::move(scales));
}

// `d` comes from the enclosing spec; a core spec may repeat it only if it agrees.
std::unique_ptr<SymplecticCore> make_core(const json& spec, Index d, const std::string& where) {
  require_object(spec, where);
  const std::string type = get_type(spec, where, kValidCoreTypes);
  if (spec.contains("d")) {
    const Index inner = get_count(spec, "d", where);
    require(inner == d, [&] {
      return where + ": key 'd' = " + std::to_string(inner) +
             " disagrees with the model's d = " + std::to_string(d);
    });
  }
  if (type == "la") {
    reject_unknown_keys(spec, where, {"type", "d", "layers", "sublayers", "step_terms"});
    const Index step_terms = spec.contains("step_terms") ? get_count(spec, "step_terms", where) : 1;
    require(step_terms == 1 || step_terms == 2, [&] {
      return where + ": key 'step_terms' = " + std::to_string(step_terms) + ", expected 1 or 2";
    });
    return std::make_unique<LaSympNet>(d, get_count(spec, "layers", where),
                                       get_count(spec, "sublayers", where), step_terms);
  }
  if (type == "g") {
    reject_unknown_keys(spec, where, {"type", "d", "layers", "width"});
    return std::make_unique<GSympNet>(d, get_count(spec, "layers", where),
                                      get_count(spec, "width", where));
  }
  throw Error(where + ": unknown core type '" + type + "'; expected one of " + kValidCoreTypes);
}

}  // namespace

std::unique_ptr<OneStepMap> make_one_step_map(const nlohmann::json& spec) {
  const std::string where = "model spec";
  require_object(spec, where);
  if (spec.contains("normalization")) {
    nlohmann::json inner = spec;
    inner.erase("normalization");
    Normalization n;
    from_json(spec.at("normalization"), n);
    return std::make_unique<NormalizedMap>(make_one_step_map(inner), std::move(n));
  }
  if (spec.contains("dof_scales")) {
    require(spec.at("dof_scales") == "learned", [&] {
      return where + ".dof_scales: expected \"learned\" (per-dof momentum scales as parameters)";
    });
    nlohmann::json inner = spec;
    inner.erase("dof_scales");
    return std::make_unique<DofScaledMap>(make_one_step_map(inner));
  }
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
    if (conformal && spec.contains("core") && spec.at("core").is_object() &&
        spec.at("core").contains("type") && spec.at("core").at("type") == "library") {
      if (spec.at("core").contains("d"))
        require(spec.at("core").at("d") == d, [&] {
          return where + ".core: key 'd' disagrees with the model's d = " + std::to_string(d);
        });
      return make_library_map(spec.at("core"), d,
                              get_beta_init(spec, where, CSympNetId::kDefaultBetaInit),
                              where + ".core");
    }
    require(spec.contains("core"), [&] {
      return where + ": missing key 'core' (expected e.g. {\"type\": " +
             "\"la\", \"layers\": 5, \"sublayers\": 20})";
    });
    auto core = make_core(spec.at("core"), d, where + ".core");
    if (!conformal) return std::make_unique<SympNet>(std::move(core));
    return std::make_unique<CSympNetId>(std::move(core),
                                        get_beta_init(spec, where, CSympNetId::kDefaultBetaInit));
  }
  if (type == "map") {
    reject_unknown_keys(spec, where, {"type", "d", "width"});
    return std::make_unique<MapBaseline>(get_count(spec, "d", where),
                                         get_count(spec, "width", where));
  }
  throw Error(where + ": unknown model type '" + type + "'; expected one of " + kValidTypes);
}

}  // namespace csympnet
