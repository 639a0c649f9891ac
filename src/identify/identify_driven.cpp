// identify_driven(): records driven by known inputs u(t) (docs/identification.md, "Driven
// records"; docs/derivations.md, "Known inputs").
//
//   1. units: q shifted by its mean per dof and scaled by one spread for every dof, time by the
//      median step (the inputs keep theirs: B absorbs them);
//   2. each trajectory is cut into segments of kSegment positions; every fifth is held out
//      (identify_driven_fit.cpp);
//   3. a start for θ by equation error: accelerations and velocities from three-point
//      differences of the positions, regressed on the terms' forces, the velocity and the
//      inputs (a start only);
//   4. multiple shooting on the positions with the inputs (train/shooting.hpp): the segments'
//      hidden start states and θ (W, the coefficients, β, B) jointly; the terms selected by BIC
//      over the training segments unless given (identify_driven_terms.cpp);
//   5. the segments linked by continuity over whole stretches of the record
//      (identify_driven_link.cpp → identify_chain.cpp), and the linked fit repeated with the
//      inputs' curvature between samples folded in (the input hold's share);
//   6. γ̂'s interval and the input gain's from the sandwich over the linked segments (each
//      position clustered in its training segment), with the degrees-of-freedom correction for
//      the hidden start states and the held-out inflation, as for positions alone, widened for
//      the input hold unless the positions favour the straight line between samples;
//   7. checks (the held-out fit; the dissipation check is not applicable: u supplies energy) and
//      the verdict; the model in the user's units.
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/QR>

#include "../train/lapack.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/core/options.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/identify/identify.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/train/gamma_sandwich.hpp"
#include "csympnet/train/shooting.hpp"
#include "identify_driven.hpp"
#include "identify_driven_link.hpp"
#include "identify_stages.hpp"

namespace csympnet {

namespace {

using detail::cut_driven;
using detail::driven_map;
using detail::driven_options;
using detail::DrivenCut;
using detail::DrivenFit;
using detail::fit_driven;
using detail::kDrivenIterations;
using detail::kSegment;
using detail::select_driven_terms;

// The held-out loss over the training loss beyond which the model does not explain new
// segments as it explains its own.
constexpr double kHeldOutRatioMax = 2.0;

struct DrivenData {
  Index d = 0, m = 0;
  bool had_momenta = false;
  std::vector<Trajectory> positions;  // normalised q (d × n) and u (m × n), as given
  Normalization units;
};

DrivenData check_driven(const std::vector<Trajectory>& trajs, bool positions_only,
                        const IdentifyConfig& config) {
  if (config.init != nullptr)
    throw OptionError("init",
                      "a record with inputs is fitted from the library core's start; "
                      "--init is not supported with inputs yet");
  if (config.dissipation != "auto" && config.dissipation != "viscous")
    throw OptionError("dissipation",
                      "a record with inputs is fitted with the viscous rate gamma alone; '" +
                          config.dissipation + "' is not supported with inputs yet");
  if (!config.core.is_null()) {
    const std::string type = config.core.is_object() ? config.core.value("type", "") : "";
    if (type != "library" && type != "la" && type != "g")
      throw OptionError("core",
                        "a record with inputs is fitted with the library core ({\"type\": "
                        "\"library\", \"terms\": [...]}) or a neural core (la:L:m, g:L:w)");
  }
  require(!trajs.empty(), "driven record: no trajectories");
  DrivenData out;
  out.m = trajs.front().u.rows();
  const Index rows = trajs.front().z.rows();
  out.had_momenta = !positions_only;
  for (std::size_t k = 0; k < trajs.size(); ++k) {
    const Trajectory& t = trajs[k];
    require(t.u.rows() == out.m && out.m >= 1 && t.u.cols() == t.t.size() && t.z.rows() == rows &&
                t.z.cols() == t.t.size(),
            [&] {
              return "trajectory " + std::to_string(k + 1) +
                     ": expected the same positions and inputs u1..um at every sample as the "
                     "first trajectory";
            });
  }
  require(positions_only || rows % 2 == 0, "driven record: states need 2d rows");
  return out;
}

// q̂ = (q − mean) / spread (one for every dof), t̂ = t / median step; β = c / α with c = the
// geometric mean of α² / τ (the momenta are hidden: their unit is a convention).
Normalization driven_units(const std::vector<Trajectory>& q, Index d) {
  Vector sum = Vector::Zero(d), sq = Vector::Zero(d);
  double n = 0.0;
  std::vector<double> steps;
  for (const Trajectory& t : q) {
    sum += t.z.rowwise().sum();
    n += static_cast<double>(t.z.cols());
    for (Index k = 1; k < t.t.size(); ++k) steps.push_back(t.t(k) - t.t(k - 1));
  }
  require(!steps.empty(), "driven record: expected a trajectory with at least two samples");
  Normalization u;
  u.q_shift = sum / n;
  for (const Trajectory& t : q)
    sq += (t.z.colwise() - u.q_shift).array().square().matrix().rowwise().sum();
  u.q_scale = (sq / n).cwiseSqrt();
  for (Index i = 0; i < d; ++i)
    require(u.q_scale(i) > 0.0 && std::isfinite(u.q_scale(i)), [&] {
      return "column 'q" + std::to_string(i + 1) +
             "' does not vary; expected a coordinate that moves";
    });
  // One spread for every dof (their root mean square): a difference term (qi - qj)^k of the
  // library is then the bond's own difference in the data's units, up to a shift; with a spread
  // per dof it would be (qi/si - qj/sj), which a bond's force does not have.
  u.q_scale.setConstant(std::sqrt(u.q_scale.squaredNorm() / static_cast<double>(d)));
  std::nth_element(steps.begin(), steps.begin() + static_cast<long>(steps.size() / 2), steps.end());
  u.time_scale = steps[steps.size() / 2];
  const double c = std::exp(u.q_scale.array().log().mean() * 2.0) / u.time_scale;
  u.p_scale = c * u.q_scale.cwiseInverse();
  u.validate("driven record units");
  return u;
}

// The neural core the options name ({"type": "la"|"g", ...}), else null.
nlohmann::json neural_core(const IdentifyConfig& config) {
  const bool neural = config.core.is_object() && config.core.value("type", "") != "library";
  return neural ? config.core : nlohmann::json();
}

// The given core's spec, or the quadratic terms (a linear system) to start the selection from;
// the inputs' count checked against the record's.
LibrarySpec driven_spec(const IdentifyConfig& config, Index d, Index m, nlohmann::json& record) {
  LibrarySpec s;
  if (neural_core(config).is_null() && !config.core.is_null())
    s = read_library_spec(config.core, d, "core");
  if (s.terms.empty()) {
    // A linear term per coordinate too: the rest position is not the positions' mean (without
    // it a linear record's selection took a sin/cos pair at a small wavenumber for the offset).
    for (Index i = 0; i < d; ++i) {
      s.terms.push_back(parse_term("q" + std::to_string(i + 1), d, "core"));
      s.terms.push_back(parse_term("q" + std::to_string(i + 1) + "^2", d, "core"));
    }
    for (Index i = 0; i < d; ++i)
      for (Index j = i + 1; j < d; ++j)
        s.terms.push_back(parse_term(
            "(q" + std::to_string(i + 1) + "-q" + std::to_string(j + 1) + ")^2", d, "core"));
    record["terms"] =
        "selected: the linear and quadratic terms (a linear system), then the additions that "
        "lower the "
        "information criterion (choices.driven.selection); --core names the terms instead";
  }
  if (s.inputs.m != 0 && s.inputs.m != m)
    throw OptionError("core", "the core's inputs.m = " + std::to_string(s.inputs.m) +
                                  " disagrees with the record's " + std::to_string(m) +
                                  " input columns");
  require(s.dissipation.empty(), [] {
    return std::string("core: friction and drag terms are not supported with inputs yet");
  });
  return s;
}

// Each block's information for the effective number of blocks (gamma_sandwich.hpp), when the
// normal equations carry it (shooting_block_equations leaves it out past its size limit).
const std::vector<Matrix>* blocks_information(const NormalEquations& ne) {
  return ne.block_information.empty() ? nullptr : &ne.block_information;
}

// The interval of a function f(θ) with gradient `grad`, in the user's units (value × unit).
SandwichInterval interval_of(const NormalEquations& ne, const Vector& grad, double value,
                             Index n_res, double scale, double inflation, double unit,
                             double level) {
  SandwichInterval iv = sandwich_interval_of(ne.a, ne.g, ne.scores, grad, value, n_res, ne.cost,
                                             scale, 1.0, level, blocks_information(ne));
  inflate_interval(iv, inflation);
  for (double* v : {&iv.gamma, &iv.low, &iv.high, &iv.std_error, &iv.sandwich, &iv.model_based,
                    &iv.optimisation, &iv.rounding})
    *v *= unit;
  return iv;
}

// γ̂'s interval (with the Hamiltonian's and the modes'), and the input gain's.
struct DrivenInterval {
  detail::GammaInterval gamma;
  nlohmann::json gain;  // {"B", "B_ci_low", "B_ci_high"}: the gain on the acceleration
};

// The normal equations over the training segments with their start states eliminated, scaled
// by 1/√n, the scores per block corrected for the 2d unknowns of every segment's start state
// (the degrees-of-freedom correction of the positions route), with each block's information
// (shooting_block_equations), from which the intervals count the blocks they rest on.
NormalEquations driven_normal_equations(const OneStepMap& map, const Vector& theta,
                                        const Matrix& z0, const ShootingSegments& train,
                                        const std::function<bool()>& stop) {
  const Index n_res = train.n_residuals();
  const double scale = 1.0 / std::sqrt(static_cast<double>(n_res));
  NormalEquations ne = shooting_block_equations(map, theta, z0, train, map.n_params(), scale, stop);
  const double hidden = static_cast<double>(map.dim() * train.size());
  ne.scores *=
      std::sqrt(static_cast<double>(n_res) / std::max(1.0, static_cast<double>(n_res) - hidden));
  return ne;
}

// γ̂'s interval (user's units) from `ne` over n_res residuals, inflated by `inflation`; throws
// Error when the Gauss–Newton matrix cannot be factored even regularised.
SandwichInterval driven_gamma_interval(const OneStepMap& map, const Vector& theta,
                                       const NormalEquations& ne, Index n_res, double tau,
                                       double level, double inflation) {
  const Index bi = *map.damping_param_index();
  const double scale = 1.0 / std::sqrt(static_cast<double>(n_res));
  SandwichInterval s = sandwich_interval(ne.a, ne.g, ne.scores, bi, std::abs(theta(bi)),
                                         theta(bi) >= 0.0 ? 1.0 : -1.0, n_res, ne.cost, scale, 1.0,
                                         level, blocks_information(ne));
  inflate_interval(s, inflation);
  for (double* v : {&s.gamma, &s.low, &s.high, &s.std_error, &s.sandwich, &s.model_based,
                    &s.optimisation, &s.rounding})
    *v /= tau;
  s.method += " over hidden start states (positions with known inputs)";
  return s;
}

// The interval widened to span the estimate moved by `shift` (what the first-order hold's straight
// lines cost, hold_shift) with its own half-widths: whether the input between samples was
// straight (as the hold assumes) or smooth (as a sampled signal usually is), the interval is
// the one that estimate would have. `shift`'s size is recorded as the integrator share.
void span_the_hold(SandwichInterval& s, double shift) {
  s.integrator = std::abs(shift);
  s.low = std::min(s.gamma, s.gamma + shift) - (s.gamma - s.low);
  s.high = std::max(s.gamma, s.gamma + shift) + (s.high - s.gamma);
}

// The held-out inflation of a fit: √(held-out over training loss), at least 1.
double held_out_inflation(const ShootingReport& rep) {
  const double ratio =
      rep.final_loss > 0.0 && std::isfinite(rep.val_loss) ? rep.val_loss / rep.final_loss : 1.0;
  return std::sqrt(std::max(1.0, ratio));
}

// γ̂'s interval, the input gain's and the modes', from the training segments' normal
// equations with the start states eliminated (as segments_interval of identify_segments): the
// linked chain's segments, each position clustered in its training block. `starts`: the states
// the modes' mean state is taken over; `hold`: how far θ moves with the inputs' curvature
// between samples (hold_shift), which γ̂'s and the gain's intervals are widened to span.
DrivenInterval driven_interval(const DrivenFit& fit, const Normalization& units, double level,
                               const Matrix& z0, const ShootingSegments& train, double inflation,
                               const WindowSet& starts, const Vector& hold,
                               const IdentifyHooks& hooks) {
  if (hooks.stage) hooks.stage("interval");
  DrivenInterval out;
  const auto stop = [&hooks] { return hooks.should_stop && hooks.should_stop(); };
  const OneStepMap& map = fit.used();
  const Vector& theta = fit.theta;
  const Index d = map.dim() / 2, m = map.n_inputs(), p = map.n_params();
  const double tau = units.time_scale;
  const Index n_res = train.n_residuals();
  const double scale = 1.0 / std::sqrt(static_cast<double>(n_res));
  const NormalEquations ne = driven_normal_equations(map, theta, z0, train, stop);
  if (ne.stopped) {
    out.gamma.stopped = true;
    return out;
  }
  try {
    SandwichInterval s = driven_gamma_interval(map, theta, ne, n_res, tau, level, inflation);
    const Index bi = fit.beta_index();
    span_the_hold(s, (std::abs(theta(bi) + hold(bi)) - std::abs(theta(bi))) / tau);
    out.gamma.interval = s;
  } catch (const Error&) {
    out.gamma.reasons.push_back(
        "the positions and inputs do not fix the parameters: the Gauss-Newton matrix could not "
        "be factored even regularised, so no interval can be formed");
    return out;
  }
  out.gamma.hamiltonian =
      detail::hamiltonian_report(map, theta, units, {&ne, n_res, scale, inflation, level});
  out.gamma.modes = detail::modal_analysis(map, theta, starts, tau, level,
                                           {&ne, n_res, scale, 1.0, inflation, stop});
  out.gamma.stopped = out.gamma.modes.stopped;
  // A neural core's momentum unit is its own: the gain on the acceleration is read from the
  // library core's diagonal mass, which it does not have.
  if (fit.neural) return out;
  // The gain on the acceleration, q''_i = ... + G_ij u_j: G = W B, which the hidden momenta's
  // unit leaves alone (B alone is not fixed by positions).
  nlohmann::json gain = nlohmann::json::array(), low = gain, high = gain;
  for (Index i = 0; i < d; ++i) {
    nlohmann::json g_row = nlohmann::json::array(), l_row = g_row, h_row = g_row;
    const double w = theta(i);
    for (Index j = 0; j < m; ++j) {
      Vector grad = Vector::Zero(p);
      const double b = theta(fit.input_index(i, j));
      grad(i) = b;
      grad(fit.input_index(i, j)) = w;
      const double unit = units.q_scale(i) / (tau * tau);
      SandwichInterval iv = interval_of(ne, grad, w * b, n_res, scale, inflation, unit, level);
      const double shifted = (w + hold(i)) * (b + hold(fit.input_index(i, j)));
      span_the_hold(iv, (shifted - w * b) * unit);
      g_row.push_back(iv.gamma);
      l_row.push_back(iv.low);
      h_row.push_back(iv.high);
    }
    gain.push_back(g_row);
    low.push_back(l_row);
    high.push_back(h_row);
  }
  out.gain = {{"B", gain}, {"B_ci_low", low}, {"B_ci_high", high}};
  return out;
}

// The checks a driven record can take, and the verdict; `reasons`: the interval's.
detail::Verdict driven_verdict(const ShootingReport& rep, const IdentifyQuality& quality,
                               const std::optional<SandwichInterval>& interval, bool stopped,
                               std::vector<std::string> reasons) {
  detail::Verdict v;
  v.reasons = std::move(reasons);
  ModelCheck held;
  held.name = "held_out";
  held.assumption = "the model explains held-out segments as it explains its training segments";
  held.effect_name = "held-out over training loss of the positions";
  held.effect = quality.train_loss > 0.0 ? quality.val_loss / quality.train_loss : 1.0;
  held.effect_threshold = kHeldOutRatioMax;
  held.passed = std::isfinite(held.effect) && held.effect <= kHeldOutRatioMax;
  held.sentence = "held-out loss " + detail::significant(held.effect) +
                  " times the training loss (at most " + detail::significant(kHeldOutRatioMax) +
                  ")";
  ModelCheck energy;
  energy.name = "dissipation";
  energy.assumption = "the motion loses energy without input";
  energy.applicable = false;
  energy.sentence =
      "not applicable: the known input supplies energy (H = H0 - q^T B u), so growing motion "
      "is no evidence against the model; gamma_hat's interval says whether damping is found";
  v.checks = {held, energy};
  if (stopped) {
    v.text = "interrupted";
    v.reasons.push_back("interrupted");
    return v;
  }
  if (!held.passed) v.reasons.push_back("check held_out failed: " + held.sentence);
  if (!interval) v.reasons.push_back("no interval for gamma_hat: " + rep.message);
  // As for free records (identification_reasons): an interval that reaches 0, or that the
  // regularisation of the Gauss-Newton matrix moves, does not identify the damping.
  if (interval && std::isfinite(interval->low) && interval->low <= 0.0)
    v.reasons.push_back("the " + detail::significant(100.0 * interval->level) + "% interval [" +
                        detail::significant(interval->low) + ", " +
                        detail::significant(interval->high) +
                        "] reaches 0: these data do not tell the damping rate from no damping");
  if (interval && !interval->stable)
    v.reasons.push_back("the interval changes " +
                        detail::significant(interval->regularisation_ratio) +
                        "-fold with the regularisation of the Gauss-Newton matrix: the data do "
                        "not separate the damping from the other parameters");
  v.rejected = !held.passed;
  v.identified = v.reasons.empty() && interval && std::isfinite(interval->low) &&
                 std::isfinite(interval->high);
  v.text = v.identified ? "identified" : v.rejected ? "model rejected" : "not identified";
  return v;
}

// The segment fit's segments linked into chains over whole stretches of the record
// (identify_driven_link.hpp): the training segments and start states the interval is formed
// over, and the states of the training positions (the modes' mean state).
struct DrivenChain {
  ShootingSegments train;
  Matrix z0;
  WindowSet starts;
  Index per_piece = 0;         // training positions per linked segment (0: not linked)
  std::vector<Matrix> states;  // per trajectory, the state at every sample
};

// γ̂'s interval from the segment fit, before the linking (the independent segments, each its
// own start state), for comparison with the linked fit's: {gamma_hat, low, high} in the user's
// units, null when it cannot be formed.
nlohmann::json segment_fit_interval(const DrivenFit& fit, const ShootingSegments& train,
                                    const Normalization& units, double level,
                                    const IdentifyHooks& hooks) {
  const auto stop = [&hooks] { return hooks.should_stop && hooks.should_stop(); };
  const NormalEquations ne = driven_normal_equations(fit.used(), fit.theta, fit.z0, train, stop);
  if (ne.stopped) return nullptr;
  try {
    const SandwichInterval s =
        driven_gamma_interval(fit.used(), fit.theta, ne, train.n_residuals(), units.time_scale,
                              level, held_out_inflation(fit.rep));
    return {{"gamma_hat", s.gamma}, {"low", s.low}, {"high", s.high}};
  } catch (const Error&) {
    return nullptr;
  }
}

// The LM options of the linked fits: they end when γ̂ stops moving (kDampingConvergedSe of its
// standard error). For a neural core too: going on to the neural budget cost 2.5 times the fit
// on four saturating-spring records and changed neither the stage kept nor the free run.
ShootingOptions linking_options(const DrivenFit& fit, const IdentifyConfig& config,
                                const IdentifyHooks& hooks) {
  ShootingOptions opt = driven_options(config, hooks, kDrivenIterations);
  opt.converged_se = detail::kDampingConvergedSe;
  return detail::watching_damping(fit.used(), opt);
}

// `fit` (θ, the held-out start states, the report) becomes the linked fit's; linking ends at a
// stop request (then the segments stay as they are). The stages go into record["linking"].
DrivenChain link_driven(DrivenFit& fit, const std::vector<Trajectory>& nt, const DrivenCut& cut,
                        const Normalization& units, const IdentifyConfig& config,
                        const IdentifyHooks& hooks, nlohmann::json& record) {
  const detail::DrivenRecord rec = detail::driven_record(nt, cut.places);
  const detail::DrivenSegments segments{cut.train, fit.z0, cut.val, fit.rep};
  DrivenChain out{cut.train, fit.z0, {}, 0, {}};
  std::vector<Matrix> states;
  if (fit.rep.stopped) {
    out.states = detail::driven_states(fit.used(), fit.theta, rec, cut.places, segments, fit.vz0);
    out.starts = detail::training_state_windows(rec, out.states);
    return out;
  }
  record["segment_fit_interval"] = segment_fit_interval(fit, cut.train, units, config.level, hooks);
  if (hooks.stage) hooks.stage("linking the segments");
  ShootingOptions opt = linking_options(fit, config, hooks);
  detail::LinkedFit linked = detail::link_driven_segments(fit.used(), fit.theta, rec, cut.places,
                                                          segments, kSegment, fit.vz0, opt, states);
  record["linking"] = linked.record;
  out.starts = detail::training_state_windows(rec, states);
  if (linked.chain.segs.size() > 0) {
    out.train = std::move(linked.chain.segs);
    out.z0 = std::move(linked.chain.z0);
    out.per_piece = linked.per_piece;
    fit.rep = linked.report;
  }
  out.states = std::move(states);
  fit.rep.stopped = fit.rep.stopped || linked.report.stopped;
  return out;
}

// γ̂'s standard error at `fit` over the linked segments (the fit's units); NaN when the
// Gauss–Newton matrix cannot be factored or on a stop request.
double gamma_standard_error(const DrivenFit& fit, const DrivenChain& chain, double level,
                            const IdentifyHooks& hooks) {
  const auto stop = [&hooks] { return hooks.should_stop && hooks.should_stop(); };
  const NormalEquations ne =
      driven_normal_equations(fit.used(), fit.theta, chain.z0, chain.train, stop);
  if (ne.stopped) return std::numeric_limits<double>::quiet_NaN();
  try {
    return driven_gamma_interval(fit.used(), fit.theta, ne, chain.train.n_residuals(), 1.0, level,
                                 held_out_inflation(fit.rep))
        .std_error;
  } catch (const Error&) {
    return std::numeric_limits<double>::quiet_NaN();
  }
}

// The map's substeps doubled, the linked fit refitted from itself each time, while that moves
// γ̂ by more than kSubstepShare of its standard error (at most kMaxSubstepDoublings times):
// over linked segments the integrator's error of one substep (order 4) shows in γ̂ (on a
// two-mass Duffing chain at 20 to 40 samples per period, one standard error). Each fit at
// twice the substeps that moved γ̂ so is kept; every round goes into record["substeps"]. Not when
// the core names its substeps, nothing was linked, or on a stop.
constexpr double kSubstepShare = 0.1;
constexpr int kMaxSubstepDoublings = 3;
void refine_substeps(DrivenFit& fit, DrivenChain& chain, LibrarySpec spec, Index m,
                     const DrivenCut& cut, const IdentifyConfig& config, const IdentifyHooks& hooks,
                     double tau, nlohmann::json& record) {
  if (config.core.is_object() && config.core.contains("substeps")) return;
  if (chain.per_piece == 0 || fit.rep.stopped || fit.neural) return;
  nlohmann::json rounds = nlohmann::json::array();
  const Index bi = *fit.map.damping_param_index();
  for (int round = 0; round < kMaxSubstepDoublings; ++round) {
    if (hooks.stage) hooks.stage("the integrator's substeps");
    spec.substeps = 2 * fit.map.substeps();
    HamiltonianLibraryMap map = driven_map(spec, fit.map.terms(), fit.map.d(), m);
    Vector theta = fit.theta;
    Matrix z0 = chain.z0, val_z0 = fit.vz0;
    ShootingOptions opt = driven_options(config, hooks, kDrivenIterations);
    opt.converged_se = detail::kDampingConvergedSe;
    const ShootingReport rep = fit_shooting(map, theta, z0, chain.train, val_z0, cut.val,
                                            detail::watching_damping(map, opt));
    if (rep.stopped || !theta.allFinite()) break;
    const double change = std::abs(theta(bi)) - std::abs(fit.theta(bi));
    DrivenFit finer{std::move(map), std::move(theta), fit.z0, std::move(val_z0), rep, nullptr};
    DrivenChain at = chain;
    at.z0 = std::move(z0);
    const double se = gamma_standard_error(finer, at, config.level, hooks);
    const bool moved = std::abs(change) > kSubstepShare * se;
    rounds.push_back({{"substeps", spec.substeps},
                      {"gamma_change", change / tau},
                      {"std_error", se / tau},
                      {"kept", moved}});
    if (!moved) break;
    fit = std::move(finer);
    chain = std::move(at);
  }
  record["substeps"] = {
      {"rule", "doubled, the linked fit refitted, while that moves gamma_hat by more than " +
                   detail::significant(kSubstepShare) + " of its standard error (at most " +
                   std::to_string(kMaxSubstepDoublings) + " times)"},
      {"fitted", fit.map.substeps()},
      {"rounds", rounds}};
}

// The linked fit refitted, from itself, with the inputs' curvature between samples folded in
// (detail::curved_inputs): how far θ moves (what the first-order hold's straight lines cost if
// the input was smooth) and the refit's training loss.
struct HoldRefit {
  Vector shift;                                            // zero: no refit
  double loss = std::numeric_limits<double>::quiet_NaN();  // NaN: no refit
};

// The refit; none when nothing was linked, on a stop request, or when the refit fails.
HoldRefit hold_refit(const DrivenFit& fit, const std::vector<Trajectory>& nt,
                     const DrivenChain& chain, const IdentifyConfig& config,
                     const IdentifyHooks& hooks) {
  const HoldRefit none{Vector::Zero(fit.theta.size())};
  if (chain.per_piece == 0 || fit.rep.stopped) return none;
  if (hooks.stage) hooks.stage("the input hold's share");
  const std::vector<Trajectory> curved = detail::curved_inputs(nt);
  const DrivenCut cut = cut_driven(curved, fit.used().dim() / 2);
  const detail::DrivenRecord rec = detail::driven_record(curved, cut.places);
  detail::Chain c = detail::cut_chain(rec.states, rec.layout, chain.per_piece, chain.states);
  c.z0 = chain.z0;  // the linked fit's start states (its states are its rollouts)
  if (c.segs.size() != chain.train.size()) return none;
  Vector theta = fit.theta;
  Matrix val_z0 = fit.vz0;
  const ShootingReport rep = fit_shooting(fit.used(), theta, c.z0, c.segs, val_z0, cut.val,
                                          linking_options(fit, config, hooks));
  if (rep.stopped || !theta.allFinite()) return none;
  return {theta - fit.theta, rep.final_loss};
}

// The evidence of the positions for the straight-line hold over the curved one, n log(loss of
// the curved refit / loss of the linked fit) over the n training residuals: the two fits have
// the same parameters, so this is their log-likelihood ratio (twice it, Gaussian noise).
// Above kHoldEvidence the input was straight between samples, as the model holds it, and the
// intervals are not widened; else they span the curved refit's estimate (span_the_hold).
constexpr double kHoldEvidence = 10.0;
Vector hold_shift(const HoldRefit& refit, const ShootingReport& linked, Index n,
                  nlohmann::json& record) {
  const double evidence = static_cast<double>(n) * std::log(refit.loss / linked.final_loss);
  record["evidence_for_the_straight_line"] =
      std::isfinite(evidence) ? nlohmann::json(evidence) : nlohmann::json(nullptr);
  record["widened"] = std::isfinite(evidence) && evidence <= kHoldEvidence;
  return std::isfinite(evidence) && evidence <= kHoldEvidence
             ? refit.shift
             : Vector(Vector::Zero(refit.shift.size()));
}

// The input's record in the report (r.input): the gain B on the acceleration with its interval
// (null without one), B_p in the model's momentum units.
nlohmann::json input_record(const DrivenFit& fit, const Normalization& units, Index d, Index m,
                            const nlohmann::json& gain) {
  nlohmann::json input = {
      {"m", m},
      {"hold", hold_name(fit.map.inputs().hold)},
      {"about",
       "H = H0(q, p) - q^T B_p u(t); B is the gain on the acceleration, q''_i = ... + "
       "sum_j B_ij u_j (data units), which positions fix; B_momentum is B_p in the "
       "model's momentum units (a convention when the momenta are hidden)"}};
  if (fit.neural)
    input["about"] =
        "H = H0(q, p) - q^T B_p u(t), the input's force as half-kicks around the neural core; "
        "B_momentum is B_p in the core's own momentum units (a convention when the momenta are "
        "hidden), so the gain on the acceleration B is not formed (null): the library core's "
        "diagonal mass gives it";
  nlohmann::json b_p = nlohmann::json::array();
  for (Index i = 0; i < d; ++i) {
    nlohmann::json row = nlohmann::json::array();
    for (Index j = 0; j < m; ++j)
      row.push_back(units.p_scale(i) * fit.theta(fit.input_index(i, j)) / units.time_scale);
    b_p.push_back(row);
  }
  input["B_momentum"] = b_p;
  if (gain.is_null())
    input["B"] = nullptr;
  else
    input.update(gain);
  return input;
}

// The fit in the data's units with its interval and verdict: the one place a driven record's
// result is put together.
IdentifyResult assemble_driven(const DrivenFit& fit, const DrivenData& data,
                               const Normalization& units, const IdentifyConfig& config,
                               nlohmann::json choices, nlohmann::json summary,
                               const DrivenInterval& iv, const detail::Verdict& v, bool stopped) {
  const OneStepMap& map = fit.used();
  const ShootingReport& rep = fit.rep;
  IdentifyResult r;
  r.config = config;
  r.observed = "positions";
  r.normalization = units;
  r.data = std::move(summary);
  r.choices = std::move(choices);
  r.stopped = stopped;
  r.theta = fit.theta;
  r.lm.iterations = rep.iterations;
  r.lm.accepted = rep.accepted;
  r.lm.initial_cost = rep.initial_loss;
  r.lm.final_cost = rep.final_loss;
  r.lm.message = rep.message;
  r.lm_best_iteration = rep.best_iteration;
  r.quality.train_loss = rep.final_loss;
  r.quality.val_loss = rep.val_loss;
  r.gamma = std::abs(fit.theta(*map.damping_param_index())) / units.time_scale;
  r.input = input_record(fit, units, data.d, data.m, iv.gain);
  r.interval = iv.gamma.interval;
  r.modes = iv.gamma.modes.list;
  r.modes_note = iv.gamma.modes.note;
  r.checks = v.checks;
  r.reasons = v.reasons;
  r.identified = v.identified;
  r.rejected = v.rejected;
  r.verdict = v.text;
  r.hamiltonian = iv.gamma.hamiltonian.is_null()
                      ? detail::hamiltonian_report(map, fit.theta, units, {})
                      : iv.gamma.hamiltonian;
  nlohmann::json model_spec = map.hyperparams();
  model_spec["normalization"] = units;
  r.model = make_model(model_spec);
  return r;
}

}  // namespace

IdentifyResult identify_driven(const std::vector<Trajectory>& trajs, bool positions_only,
                               const IdentifyConfig& config, const IdentifyHooks& hooks) {
  const lapack::SingleThreaded one_thread;  // the same bits on every core count (lapack.hpp)
  config.validate();
  DrivenData data = check_driven(trajs, positions_only, config);
  nlohmann::json choices = nlohmann::json::object();
  std::vector<Trajectory> q;
  for (const Trajectory& t : trajs) {
    Trajectory x;
    x.t = t.t;
    x.z = data.had_momenta ? Matrix(t.z.topRows(t.z.rows() / 2)) : t.z;
    x.u = t.u;
    q.push_back(std::move(x));
  }
  data.d = q.front().z.rows();
  if (data.had_momenta)
    choices["momenta_set_aside"] =
        "a record with inputs is fitted on its positions (the momenta are hidden states)";
  const Normalization units = driven_units(q, data.d);
  std::vector<Trajectory> nt;
  for (Trajectory t : q) {
    t.z = (t.z.colwise() - units.q_shift).array().colwise() / units.q_scale.array();
    t.t = t.t / units.time_scale;
    nt.push_back(std::move(t));
  }
  Index samples = 0;
  for (const Trajectory& t : q) samples += t.t.size();
  nlohmann::json summary = {
      {"d", data.d}, {"inputs", data.m}, {"trajectories", q.size()}, {"samples", samples}};
  nlohmann::json record;
  const LibrarySpec spec = driven_spec(config, data.d, data.m, record);
  const bool terms_given = !config.core.is_null() && config.core.contains("terms");
  DrivenCut cut = cut_driven(nt, data.d);
  record["segment_length"] = kSegment;
  record["segments"] = {{"train", cut.train.size()}, {"held_out", cut.val.size()}};
  if (hooks.stage) hooks.stage("LM on the positions with the inputs");
  DrivenFit fit = fit_driven(driven_map(spec, spec.terms, data.d, data.m), nt, cut, config, hooks);
  const nlohmann::json neural = neural_core(config);
  if (!terms_given && neural.is_null() && !fit.rep.stopped) {
    if (hooks.stage) hooks.stage("terms: selected on the positions with the inputs");
    fit = select_driven_terms(std::move(fit), spec, data.m, nt, cut, config, hooks, record);
  }
  record["terms_fitted"] = nlohmann::json::array();
  for (const LibraryTerm& t : fit.map.terms()) record["terms_fitted"].push_back(term_name(t));
  // A neural core when named, or when the library leaves structure (not when --core library).
  if ((config.core.is_null() || !neural.is_null()) && !fit.rep.stopped)
    fit = consider_neural_core(std::move(fit), neural, data.m, cut, config, hooks, record);
  DrivenChain chain = link_driven(fit, nt, cut, units, config, hooks, record);
  refine_substeps(fit, chain, spec, data.m, cut, config, hooks, units.time_scale, record);
  const HoldRefit refit = hold_refit(fit, nt, chain, config, hooks);
  const Index bi = fit.beta_index();
  nlohmann::json& held = record["input_hold"];
  held = {{"gamma_change", (std::abs(fit.theta(bi) + refit.shift(bi)) - std::abs(fit.theta(bi))) /
                               units.time_scale},
          {"about",
           "the change of gamma_hat when the fit is repeated with the inputs' curvature between "
           "samples folded in (u_k - h^2 u''_k / 12 held first-order); unless the positions "
           "favour the straight line between samples by more than " +
               detail::significant(kHoldEvidence) +
               " in n log(loss ratio), gamma_hat's and B's intervals are widened to span that "
               "fit's too (their 'integrator' share)"}};
  const Vector hold = hold_shift(refit, fit.rep, chain.train.n_residuals(), held);
  const ShootingReport& rep = fit.rep;
  bool stopped = rep.stopped;
  DrivenInterval iv;
  if (!stopped) {
    iv = driven_interval(fit, units, config.level, chain.z0, chain.train, held_out_inflation(rep),
                         chain.starts, hold, hooks);
    stopped = stopped || iv.gamma.stopped;
  }
  choices["driven"] = record;
  IdentifyQuality quality;
  quality.train_loss = rep.final_loss;
  quality.val_loss = rep.val_loss;
  const detail::Verdict v =
      driven_verdict(rep, quality, iv.gamma.interval, stopped, iv.gamma.reasons);
  return assemble_driven(fit, data, units, config, std::move(choices), std::move(summary), iv, v,
                         stopped);
}

}  // namespace csympnet
