// The driven route's neural core (identify_driven.hpp, consider_neural_core): CSympNet-ID with a
// neural core Ψ and the inputs' half-kicks around it (models/inputs.hpp; docs/derivations.md,
// "Known inputs: the neural cores"), for a driven system whose potential the library cannot
// write. docs/identification.md, "Driven records: a neural core".
#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/models/inputs.hpp"
#include "identify_driven.hpp"
#include "identify_positions.hpp"

namespace csympnet::detail {

namespace {

// LM steps that teach the core the library fit's motion (its start on the positions); they end
// sooner on convergence (driven_options). The fit on the positions takes kNeuralIterations.
constexpr long kTeachIterations = 200;

// The default core: G(6, w), w = min(16, 8d): any smooth potential, coupled or not, with few
// enough parameters (144 at d = 1) for Levenberg–Marquardt over the shooting segments. On a
// saturating-spring record of the forced plan (f001, seed 1, 4,096 samples) G(6, 32) (578
// parameters) reached the same held-out loss in 4 times the CPU seconds (71 against 17.5) and a
// free run on the test record 3 times further off (RMS 0.0235 against 0.0075).
nlohmann::json default_driven_core(Index d) {
  return {{"type", "g"}, {"layers", 6}, {"width", std::min<Index>(16, 8 * d)}};
}

// The least excess of the lag-one correlation over noise's that trains a neural core. A smooth
// misfit holding a share s of the residuals' variance raises the correlation by about
// s (1 + 2/(L − 2)), 1.1 s over segments of 20: below 0.1, no core could lower the loss by more
// than about 9%, which on a long record three standard errors would still call structure (a
// 65,536-sample record: three standard errors 0.027) and a neural fit would take minutes for.
constexpr double kMinLagOneExcess = 0.1;

// Whether the library fit leaves the held-out positions at the noise floor: the lag-one
// correlation of their residuals within the held-out segments against what noise leaves,
// −2/(L − 2) (L the segments' mean length), plus the larger of three standard errors (1/√pairs
// each, the positions route's floor test) and kMinLagOneExcess.
bool library_at_floor(const DrivenFit& lib, const DrivenCut& cut, std::string& why) {
  const LagOne lag = residual_lag_one(lib.map, lib.theta, lib.vz0, cut.val);
  double positions = 0.0;
  for (const Matrix& q : cut.val.q) positions += static_cast<double>(q.cols());
  const double len = positions / static_cast<double>(std::max<Index>(1, cut.val.size()));
  const double noise = -2.0 / std::max(1.0, len - 2.0);
  const double three_se = 3.0 / std::sqrt(static_cast<double>(std::max<Index>(lag.pairs, 1)));
  const double bound = noise + std::max(three_se, kMinLagOneExcess);
  const bool white = lag.rho <= bound;
  why = std::string(white ? "the library fit's held-out position residuals are noise"
                          : "the library fit leaves smooth structure in the held-out positions") +
        " (lag-one correlation " + significant(lag.rho, 3) + " within segments of about " +
        significant(len, 3) + " positions, where noise leaves " + significant(noise, 3) +
        ", the bound " + significant(bound, 3) + ": the larger of three standard errors " +
        significant(three_se, 2) + " and " + significant(kMinLagOneExcess, 2) +
        " above it): a neural core was " + (white ? "not trained" : "trained too");
  return white;
}

std::shared_ptr<const OneStepMap> neural_map(const nlohmann::json& core, Index d, Index m,
                                             InputHold hold) {
  return make_one_step_map({{"type", "csympnet"},
                            {"d", d},
                            {"core", core},
                            {"inputs", {{"m", m}, {"hold", hold_name(hold)}}}});
}

// θ: the core's seeded draws, then B and β from the library fit (the momenta's unit is the
// library's, whose start states the neural fit takes over).
Vector neural_start(const OneStepMap& map, const DrivenFit& lib, Index d, Index m,
                    std::uint64_t seed) {
  Vector theta(map.n_params());
  Rng rng(seed, "driven neural core");
  map.init_params(rng, theta);
  const double beta = std::abs(lib.theta(*lib.map.damping_param_index()));
  theta(map.n_params() - 1) = std::max(beta, 1e-3);  // |β| has no slope at 0
  for (Index r = 0; r < d; ++r)
    for (Index j = 0; j < m; ++j)
      theta(map.n_params() - 1 - d * m + r * m + j) = lib.theta(lib.map.input_index(r, j));
  return theta;
}

// One-step pairs of the library fit's states along each segment, observed whole (2d rows), with
// their start states: what the neural core is taught first. One step at a time, as CSympNet-ID
// is trained on pairs: from the core's random start a rollout over a whole segment can run off
// before the fit has a slope to follow.
struct Teacher {
  ShootingSegments pairs;
  Matrix z0;
};
Teacher teacher_pairs(const DrivenFit& lib, const ShootingSegments& segs, const Matrix& z0) {
  Teacher t;
  t.pairs.d = segs.d;
  std::vector<Vector> starts;
  for (Index s = 0; s < segs.size(); ++s) {
    const auto k = static_cast<std::size_t>(s);
    const Matrix& u = segs.inputs(s);
    const Matrix states = shooting_states(lib.map, lib.theta, z0.col(s), segs.h[k], u);
    for (Index j = 0; j + 1 < states.cols(); ++j) {
      t.pairs.q.push_back(states.middleCols(j, 2));
      t.pairs.h.push_back(segs.h[k].segment(j, 1));
      if (u.rows() > 0) t.pairs.u.push_back(u.col(j));
      t.pairs.block.push_back(segs.block[k]);
      starts.push_back(states.col(j));
    }
  }
  t.z0.resize(2 * segs.d, static_cast<Index>(starts.size()));
  for (std::size_t j = 0; j < starts.size(); ++j) t.z0.col(static_cast<Index>(j)) = starts[j];
  return t;
}

nlohmann::json report_json(const ShootingReport& rep) {
  return {{"iterations", rep.iterations},
          {"train_loss", rep.final_loss},
          {"val_loss", rep.val_loss},
          {"message", rep.message}};
}

}  // namespace

DrivenFit consider_neural_core(DrivenFit library, const nlohmann::json& requested, Index m,
                               const DrivenCut& cut, const IdentifyConfig& config,
                               const IdentifyHooks& hooks, nlohmann::json& record) {
  const Index d = library.map.d();
  nlohmann::json& rec = record["neural"];
  const bool named = !requested.is_null();
  nlohmann::json core = requested;
  if (!named) {
    std::string why;
    const bool white = library_at_floor(library, cut, why);
    rec["floor"] = why;
    if (white) return library;
    core = default_driven_core(d);
  }
  rec["core"] = core;
  rec["named"] = named;
  if (hooks.stage) hooks.stage("a neural core with the inputs (" + core_name(core) + ")");
  const auto map = neural_map(core, d, m, library.map.inputs().hold);
  Vector theta = neural_start(*map, library, d, m, config.seed);
  rec["parameters"] = map->n_params();
  // Taught the library fit's motion along its own segments, one step at a time (states
  // observed), then fitted on the positions from the library's start states.
  Teacher teach = teacher_pairs(library, cut.train, library.z0);
  Teacher teach_val = teacher_pairs(library, cut.val, library.vz0);
  ShootingOptions opt = driven_options(config, hooks, kTeachIterations);
  const ShootingReport taught =
      fit_shooting(*map, theta, teach.z0, teach.pairs, teach_val.z0, teach_val.pairs, opt);
  rec["taught"] = report_json(taught);
  const auto keep_library = [&](const std::string& reason, bool stopped) {
    rec["chosen"] = "library";
    rec["reason"] = reason;
    library.rep.stopped = library.rep.stopped || stopped;
    return std::move(library);
  };
  if (taught.stopped) return keep_library("interrupted", true);
  Matrix z0 = library.z0, vz0 = library.vz0;
  fit_start_states(*map, theta, cut.train, z0, 30, false, kMaxAbsState);
  fit_start_states(*map, theta, cut.val, vz0, 30, false, kMaxAbsState, kScoringTolerance);
  const ShootingReport rep = fit_shooting(*map, theta, z0, cut.train, vz0, cut.val,
                                          driven_options(config, hooks, kNeuralIterations));
  rec["positions"] = report_json(rep);
  rec["library_val_loss"] = library.rep.val_loss;
  if (rep.stopped) return keep_library("interrupted", true);
  if (!theta.allFinite() || !std::isfinite(rep.val_loss))
    return keep_library(
        "the neural core's fit on the positions did not converge to finite "
        "values",
        false);
  const double n_val = static_cast<double>(std::max<Index>(1, cut.val.n_residuals()));
  const double margin = 3.0 * std::sqrt(2.0 / n_val);
  const bool lower = rep.val_loss < library.rep.val_loss * (1.0 - margin);
  rec["rule"] =
      "named on the command line, or a held-out loss of the positions lower than the "
      "library fit's by more than three standard errors (" +
      significant(margin, 2) + " of itself)";
  if (!named && !lower)
    return keep_library(
        "the neural core's held-out loss is not lower than the library fit's "
        "by the margin: the library core (a readable Hamiltonian) is kept",
        false);
  rec["chosen"] = core_name(core);
  DrivenFit out{std::move(library.map), std::move(theta), std::move(z0), std::move(vz0), rep, map};
  return out;
}

}  // namespace csympnet::detail
