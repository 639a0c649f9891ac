// make_one_step_map: builds a model from its hyperparams JSON, the inverse of
// OneStepMap::hyperparams(). Accepted specs:
//
//   {"type": "la", "d": D, "layers": L, "sublayers": M}          bare LA-SympNet core
//   {"type": "g", "d": D, "layers": L, "width": W}                 bare G-SympNet core
//   {"type": "sympnet", "d": D, "core": CORE}                      SympNet = the core alone
//   {"type": "csympnet", "d": D, "core": CORE, "beta_init": B}     CSympNet-ID (B optional,
//                                                                  default 0.1, nonzero;
//                                                                  "inputs": {"m": M, "hold":
//                                                                  "foh"} for a driven map)
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
#include <algorithm>
#include <cmath>
#include <string>

#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"
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
constexpr const char* kTermsExpected =
    "key 'terms' must be a non-empty list of term names, e.g. [\"q1^2\", \"q1^4\"] "
    "(csympnet fit --core library selects them)";

// A value as a message quotes it: at most 40 characters of its JSON.
std::string short_dump(const json& v) {
  const std::string text = v.dump();
  return text.size() <= 40 ? text : text.substr(0, 40) + "\u2026";
}

// {"type": "library", "terms": [...], "order": 4, "substeps": n, "mass": "full"|"diagonal"}
// inside a "csympnet" spec: the Hamiltonian-library map (hamiltonian_library.hpp).
std::unique_ptr<OneStepMap> make_library_map(const json& spec, Index d, double beta_init,
                                             const std::string& where) {
  LibrarySpec s = read_library_spec(spec, d, where);
  require(!s.terms.empty(), [&] { return where + ": " + kTermsExpected; });
  return std::make_unique<HamiltonianLibraryMap>(
      d, std::move(s.terms), s.order, s.substeps, s.full_mass, beta_init, std::move(s.scales),
      std::move(s.dissipation), s.inputs, s.coulomb_in_kicks);
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

LibrarySpec read_library_spec(const nlohmann::json& spec, Index d, const std::string& where) {
  require_object(spec, where);
  reject_unknown_keys(spec, where,
                      {"type", "d", "terms", "order", "substeps", "mass", "coordinate_scales",
                       "dissipation", "friction", "inputs"});
  if (spec.contains("d"))
    require(spec.at("d") == d, [&] {
      return where + ": key 'd' disagrees with the model's d = " + std::to_string(d);
    });
  LibrarySpec out;
  if (spec.contains("terms")) {
    const json& names = spec.at("terms");
    require(names.is_array() && !names.empty(), [&] { return where + ": " + kTermsExpected; });
    out.terms.reserve(names.size());
    for (std::size_t k = 0; k < names.size(); ++k) {
      if (k % 4096 == 4095) throw_if_stop_requested(where + ": reading the terms");
      const json& name = names[k];
      require(name.is_string(), [&] {
        return where + ".terms[" + std::to_string(k) + "] = " + short_dump(name) +
               ", expected a term name (a string such as \"q1^2\")";
      });
      out.terms.push_back(parse_term(name.get<std::string>(), d, where + ".terms"));
    }
  }
  const Index order = spec.contains("order") ? get_count(spec, "order", where) : 4;
  require(order == 2 || order == 4 || order == 6, [&] {
    return where + ": key 'order' = " + std::to_string(order) + ", expected 2, 4 or 6";
  });
  out.order = static_cast<int>(order);
  out.substeps = spec.contains("substeps") ? get_count(spec, "substeps", where) : 1;
  if (spec.contains("mass")) {
    require(spec.at("mass") == "full" || spec.at("mass") == "diagonal", [&] {
      return where + ": key 'mass' = " + short_dump(spec.at("mass")) +
             ", expected \"full\" or \"diagonal\"";
    });
    out.full_mass = spec.at("mass") == "full";
  }
  if (spec.contains("coordinate_scales")) {
    const json& v = spec.at("coordinate_scales");
    require(v.is_array() && static_cast<Index>(v.size()) == d, [&] {
      return where + ": key 'coordinate_scales' must be a list of " + std::to_string(d) +
             " positive numbers";
    });
    out.scales.resize(d);
    for (Index i = 0; i < d; ++i) {
      const json& x = v.at(static_cast<std::size_t>(i));
      require(x.is_number() && x.get<double>() > 0.0 && std::isfinite(x.get<double>()), [&] {
        return where + ".coordinate_scales[" + std::to_string(i) + "] = " + short_dump(x) +
               ", expected a positive finite number";
      });
      out.scales(i) = x.get<double>();
    }
  }
  if (spec.contains("dissipation")) {
    const json& v = spec.at("dissipation");
    require(v.is_array(), [&] {
      return where + ": key 'dissipation' = " + short_dump(v) +
             ", expected a list of terms such as [\"coulomb(p1)\", \"drag(p1)\"]";
    });
    for (std::size_t k = 0; k < v.size(); ++k) {
      const std::string at = where + ".dissipation[" + std::to_string(k) + "]";
      require(v[k].is_string(), [&] {
        return at + " = " + short_dump(v[k]) + ", expected a term name such as \"coulomb(p1)\"";
      });
      const DissipationTerm t = parse_dissipation(v[k].get<std::string>(), d, at);
      require(std::find(out.dissipation.begin(), out.dissipation.end(), t) == out.dissipation.end(),
              [&] { return at + ": '" + dissipation_name(t) + "' appears twice"; });
      out.dissipation.push_back(t);
    }
  }
  if (spec.contains("friction")) {
    require(spec.at("friction") == "in_kicks" || spec.at("friction") == "split", [&] {
      return where + ": key 'friction' = " + short_dump(spec.at("friction")) +
             ", expected \"in_kicks\" (Coulomb friction inside the kicks) or \"split\" (beside "
             "them, as in model files written before 2026-11-29)";
    });
    out.coulomb_in_kicks = spec.at("friction") == "in_kicks";
  }
  if (spec.contains("inputs")) out.inputs = read_input_spec(spec.at("inputs"), where);
  return out;
}

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
      reject_unknown_keys(spec, where, {"type", "d", "core", "beta_init", "inputs"});
    } else {
      reject_unknown_keys(spec, where, {"type", "d", "core"});
    }
    const Index d = get_count(spec, "d", where);
    if (conformal && spec.contains("core") && spec.at("core").is_object() &&
        spec.at("core").contains("type") && spec.at("core").at("type") == "library") {
      require(!spec.contains("inputs"), [&] {
        return where +
               ": key 'inputs' belongs inside the library core ({\"type\": \"library\", "
               "\"inputs\": {\"m\": ...}}), where the kicks take them";
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
    const InputSpec inputs =
        spec.contains("inputs") ? read_input_spec(spec.at("inputs"), where) : InputSpec{};
    return std::make_unique<CSympNetId>(
        std::move(core), get_beta_init(spec, where, CSympNetId::kDefaultBetaInit), inputs);
  }
  if (type == "map") {
    reject_unknown_keys(spec, where, {"type", "d", "width"});
    return std::make_unique<MapBaseline>(get_count(spec, "d", where),
                                         get_count(spec, "width", where));
  }
  throw Error(where + ": unknown model type '" + type + "'; expected one of " + kValidTypes);
}

}  // namespace csympnet
