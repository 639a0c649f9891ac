// Stages of the identification after training: the interval, the quality on held-out data,
// the checks of the model's assumptions, and the verdict (identify_stages.hpp).
#include <chrono>
#include <cmath>

#include "csympnet/diagnostics/diagnostics.hpp"
#include "csympnet/identify/model_checks.hpp"
#include "csympnet/models/dof_scaled_map.hpp"
#include "identify_evaluators.hpp"
#include "identify_stages.hpp"

namespace csympnet::detail {

namespace {

// The model's held-out quality below which it has learned no dynamics (the verdict's reasons).
constexpr double kMaxUnexplainedShare = 0.9;  // of the motion over a window
constexpr double kMaxNullRatio = 0.5;         // squared error over a pure contraction's

}  // namespace

double data_scale(const std::vector<Trajectory>& nt) {
  double s = 0.0;
  for (const Trajectory& t : nt) s = std::max(s, t.z.cwiseAbs().maxCoeff());
  return s;
}

GammaInterval interval(const OneStepMap& map, const IntervalBasis& at, const BlockSplit& split,
                       const std::vector<Trajectory>& nt, const IdentifyHooks& hooks,
                       const Communicator& comm) {
  if (hooks.stage) hooks.stage("interval");
  GammaInterval out;
  const auto t0 = std::chrono::steady_clock::now();
  const WindowSet& train = split.train;
  const double scale = 1.0 / std::sqrt(static_cast<double>(train.size()));
  const auto stop = [&hooks] { return hooks.should_stop && hooks.should_stop(); };
  const NormalEquations ne =
      normal_equations_over_ranks(map, at.theta, train, at.balanced, scale, true, stop, comm);
  if (ne.stopped) {
    out.stopped = true;  // interrupted: no interval
  } else {
    const double tau = at.units.time_scale;
    const double gamma_n = map.damping_rate(at.theta).value_or(0.0);
    const Index bi = *map.damping_param_index();
    const double beta = at.theta(bi);
    SandwichInterval s;
    try {
      s = sandwich_interval(ne.a, ne.g, ne.scores, bi, gamma_n, beta >= 0.0 ? 1.0 : -1.0,
                            train.size() * train.dim(), ne.cost, scale, data_scale(nt), at.level);
    } catch (const Error&) {
      // What the data leave undetermined is a reason for no interval, not an error.
      out.reasons.push_back(
          "the data do not fix the parameters: the Gauss-Newton matrix could not be factored "
          "even regularised, so no interval can be formed");
      return out;
    }
    // The scores are formed from training residuals, which a flexible core has fitted: they
    // understate the residuals it makes on data it has not seen. The held-out blocks measure
    // by how much; the variance is scaled by that ratio of losses when it exceeds 1 (a
    // jackknife-like correction, docs/derivations.md "Held-out inflation").
    const double ratio =
        at.train_loss > 0.0 && std::isfinite(at.val_loss) ? at.val_loss / at.train_loss : 1.0;
    inflate_interval(s, std::sqrt(std::max(1.0, ratio)));
    // The library core: its integrator's share, measured at twice the substeps (normalised).
    const nlohmann::json& lib = at.library;
    if (lib.contains("gamma_change_at_twice_the_substeps"))
      add_integrator(s, lib["gamma_change_at_twice_the_substeps"].get<double>());
    std::vector<double> dissipation_integrator;
    if (lib.contains("dissipation_change_at_twice_the_substeps"))
      dissipation_integrator =
          lib["dissipation_change_at_twice_the_substeps"].get<std::vector<double>>();
    for (double* v : {&s.gamma, &s.low, &s.high, &s.std_error, &s.sandwich, &s.model_based,
                      &s.optimisation, &s.rounding, &s.integrator})
      *v /= tau;
    out.interval = s;
    out.modes = modal_analysis(map, at.theta, train, tau, at.level,
                               {&ne, train.size() * train.dim(), scale, data_scale(nt),
                                std::sqrt(std::max(1.0, ratio)), stop});
    out.stopped = out.modes.stopped;
    const HamiltonianIntervalInput shared = {&ne, train.size() * train.dim(), scale,
                                             std::sqrt(std::max(1.0, ratio)), at.level};
    out.hamiltonian = hamiltonian_report(map, at.theta, at.units, shared);
    out.dissipation =
        dissipation_terms_report(map, at.theta, at.units, shared, dissipation_integrator);
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

HeldOutQuality measure_quality(const OneStepMap& map, ConstParams theta, const BlockSplit& split,
                               Index d) {
  HeldOutQuality q;
  const WindowSet& val = split.val;
  const WindowSet& train = split.train;
  Matrix z = val.z0;
  Vector h(val.size());
  for (Index k = 0; k < val.m; ++k) {
    h = val.h.row(k).transpose();
    z = map.apply(theta, z, h);
  }
  q.val_relative_residual = (z - val.zm).norm() / (val.zm - val.z0).norm();
  // The null model: a pure contraction towards a fixed point, zm ≈ c z0 + b (c scalar),
  // fitted on the training windows. A map that predicts held-out windows hardly better has
  // learned no dynamics, whatever γ̂ it reports (pure noise fits as strong damping).
  const Vector m0 = train.z0.rowwise().mean(), mm = train.zm.rowwise().mean();
  const Matrix d0 = train.z0.colwise() - m0, dm = train.zm.colwise() - mm;
  const double cc = d0.squaredNorm() > 0.0 ? (d0.cwiseProduct(dm)).sum() / d0.squaredNorm() : 0.0;
  const Matrix null_pred = (cc * val.z0).colwise() + (mm - cc * m0);
  const double null_sq = (null_pred - val.zm).squaredNorm();
  q.null_ratio = null_sq > 0.0 ? (z - val.zm).squaredNorm() / null_sq : 0.0;
  const Index n_check = std::min<Index>(val.size(), 50);
  const double g = map.damping_rate(theta).value_or(0.0);
  for (Index j = 0; j < n_check; ++j) {
    const Index i = j * val.size() / n_check;
    Matrix jac = map.jacobian(theta, val.z0.col(i), val.h(0, i));
    // With learned dof scales the map is conformally symplectic for Dᵀ J D: D DΦ D⁻¹ is the
    // Jacobian of the unscaled map, to be checked against J.
    if (const auto* scaled = dynamic_cast<const DofScaledMap*>(&map)) {
      Vector diag = Vector::Ones(2 * d);
      diag.tail(d) = scaled->scales(theta);
      jac = diag.asDiagonal() * jac * diag.cwiseInverse().asDiagonal();
    }
    const double own = std::exp(-g * val.h(0, i));
    q.structure_residual_max =
        std::max(q.structure_residual_max, structure_at(jac, own, own).self_residual);
  }
  return q;
}

ModelChecks run_checks(const OneStepMap& map, ConstParams theta, const BlockSplit& split,
                       double time_scale, double level, const IdentifyHooks& hooks) {
  if (hooks.stage) hooks.stage("checks");
  CheckInput in;
  in.map = &map;
  in.theta = theta;
  in.damping_index = *map.damping_param_index();
  in.blocks = split.blocks;
  in.time_scale = time_scale;
  in.level = level;
  return check_model(in, hooks.should_stop);
}

namespace {

// When the signed rate leans below 0 without the dissipation check's confidence: say that the
// data may as well show a slow growth, with the signed rate, rather than only "no damping".
std::string possible_growth(const std::vector<ModelCheck>& checks) {
  for (const ModelCheck& k : checks) {
    if (k.name != "dissipation" || !k.passed || !k.details.contains("signed_rate")) continue;
    const double c = k.details["signed_rate"].get<double>();
    const auto& iv = k.details["interval"];
    if (!(c < 0.0)) return "";
    return " or from a slow growth (signed rate " + significant(c) + " [" +
           significant(iv[0].get<double>()) + ", " + significant(iv[1].get<double>()) +
           "] per time unit, not below 0 with 99% confidence)";
  }
  return "";
}

// Reasons that the data cannot tell γ (not identified), appended to `reasons`.
void identification_reasons(const BlockSplit& split, double h_max, bool lm_fits, bool growing,
                            const Evidence& e, const ModelChecks& checks,
                            std::vector<std::string>& reasons) {
  auto reason = [&](const std::string& s) { reasons.push_back(s); };
  const double level = e.level;
  if (e.training_stop == StopReason::kDiverged)
    reason("training diverged (non-finite loss or gradient)");
  if (!std::isfinite(e.gamma)) reason("gamma_hat is not finite");
  if (!lm_fits) reason("the model has more than 6000 parameters: no interval can be formed");
  if (e.interval) {
    const SandwichInterval& s = *e.interval;
    if (!std::isfinite(s.low) || !std::isfinite(s.high))
      reason("the interval is not finite");
    else if (s.low <= 0.0 && !growing)  // growth has its own reason, from the checks
      reason("the " + significant(100.0 * level) + "% interval [" + significant(s.low) + ", " +
             significant(s.high) +
             "] reaches 0: these data do not tell the damping rate from no damping" +
             possible_growth(checks));
    if (!s.stable)
      reason("the interval changes " + significant(s.regularisation_ratio) +
             "-fold with the regularisation of the Gauss-Newton matrix: the data do not "
             "separate the damping from the core's parameters");
  }
  // Not the estimate itself (a fit can collapse to γ̂ ≈ 0): the largest rate the interval
  // allows, over the longest step.
  if (e.interval && std::isfinite(e.interval->high) && e.interval->high * h_max < 1e-13 && !growing)
    reason(
        "even the interval's upper end gives e^(-gamma h) = 1 to 13 digits at every step: "
        "damping that weak is invisible in these data");
  const WindowSet& train = split.train;
  if ((train.zm - train.z0).norm() == 0.0)
    reason("the states do not change over any step: there is no motion to learn from");
  else if (e.quality.val_relative_residual > kMaxUnexplainedShare)
    reason(
        "the model explains less than 10% of the motion over a window on held-out data "
        "(unexplained share " +
        significant(e.quality.val_relative_residual) + ")");
  if (e.quality.null_ratio > kMaxNullRatio)
    reason("on held-out data the model predicts only " +
           significant(100.0 * (1.0 - e.quality.null_ratio)) +
           "% better than a pure contraction towards a fixed point: it has learned no dynamics "
           "to tell damping from");
  // A generalisation gap matters when the held-out error is itself a visible share of the
  // motion; below 1% the interval's held-out inflation accounts for it.
  if (e.quality.val_loss > 10.0 * e.quality.train_loss && e.quality.val_loss > 1e-20 &&
      e.quality.val_relative_residual > 1e-2)
    reason("the validation loss is " + significant(e.quality.val_loss / e.quality.train_loss) +
           " times the training loss and the model misses " +
           significant(100.0 * e.quality.val_relative_residual) +
           "% of the held-out motion: it does not generalise to held-out data");
}

}  // namespace

Verdict verdict(const BlockSplit& split, double h_max, bool lm_fits, Evidence e) {
  Verdict v;
  v.checks = std::move(e.checks);
  v.reasons = std::move(e.reasons);
  // A model that explains little of the held-out motion cannot test its own assumptions: its
  // checks are reported, undecided, and the verdict is "not identified" for that reason.
  const bool usable = e.quality.val_relative_residual <= kMaxUnexplainedShare &&
                      e.quality.null_ratio <= kMaxNullRatio &&
                      e.training_stop != StopReason::kDiverged;
  for (ModelCheck& k : v.checks)  // measured_momenta tests the data alone: it stays decided
    if (!usable && !k.passed && k.name != "measured_momenta") {
      k.passed = true;
      k.applicable = false;
      k.sentence =
          "not decided: the model explains too little of the held-out motion to test "
          "its assumptions (" +
          k.sentence + ")";
    }
  // The checks first: a broken assumption is the finding, and it explains the rest.
  bool growing = false;
  for (const ModelCheck& k : v.checks) {
    if (k.passed) continue;
    v.rejected = true;
    if (k.name == "dissipation") growing = true;
    v.reasons.push_back("the model's assumption of " + k.assumption + " fails: " + k.sentence);
  }
  identification_reasons(split, h_max, lm_fits, growing, e, v.checks, v.reasons);
  v.identified = v.reasons.empty() && !e.stopped;
  v.text = e.stopped      ? "interrupted"
           : v.rejected   ? "model rejected"
           : v.identified ? "identified"
                          : "not identified";
  return v;
}

}  // namespace csympnet::detail
