// Dry friction offered on the linked positions (docs/identification.md, "Dry friction
// and drag"): the velocity start chooses them from local fits whose velocities are noisy and
// from an amplitude check that has little power over a narrow range of amplitudes. An encoder
// pendulum with dry friction as strong as its viscous damping, over two decays of 40 s, passed
// that check (p = 0.5) and was reported with γ̂ 55% high and an interval that missed, while the
// true form fitted to its positions finds both to 0.2%. Over the linked chain the positions
// speak for themselves: a group that explains them enters when the information criterion
// falls clearly and the held-out positions do not speak against it.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>

#include "csympnet/core/dense.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/train/shooting.hpp"
#include "identify_chain.hpp"

namespace csympnet::detail {

namespace {

// A group enters only with very strong evidence (Kass and Raftery's scale: a Bayes factor
// beyond e^5), so that a viscous record's noise does not buy a friction term.
constexpr double kClearlyBetter = 10.0;
// And its rate must stand clear of 0 by this many of its Gauss–Newton standard errors.
constexpr double kRateStandardErrors = 3.0;
// The trials run only when the score test at zero rates predicts at least this share of the
// gain in the criterion that the group must show (kClearlyBetter + its parameters × log n):
// the Gauss–Newton model's gain is an upper bound for rates that must stay ≥ 0, and the margin
// of four covers its error where the loss is not quadratic in the rates.
constexpr double kScreenShare = 0.25;
// A current fit whose loss is below this share of the positions' mean square explains them to
// rounding: there the criterion's n log(loss ratio) measures the last bits (a clean linear
// oscillator's trials moved the loss by 0.2% at 1e-25 and "gained" 42), so nothing is offered.
constexpr double kRoundingShare = 1e-20;

double mean_square(const ShootingSegments& segs) {
  double sum = 0.0;
  for (const Matrix& q : segs.q) sum += q.squaredNorm();
  return sum / static_cast<double>(std::max<Index>(segs.n_residuals(), 1));
}

// gᵀA⁺g for the symmetric positive semi-definite A (eigenvalues below 1e-12 of the largest
// count as 0): the Gauss–Newton decrease of the loss when the normal equations are scaled by
// the number of residuals.
// `step` (optional) receives the Gauss–Newton step −A⁺g.
double gauss_newton_gain(const Matrix& a, const Vector& g, Vector* step = nullptr) {
  if (g.size() == 0) return 0.0;
  const dense::SymmetricEigen e = dense::symmetric_eigen(a);
  const Vector& l = e.values;
  const double top = std::max(l.maxCoeff(), 0.0);
  const Vector c = e.vectors.transpose() * g;
  Vector w = Vector::Zero(l.size());
  double gain = 0.0;
  for (Index k = 0; k < l.size(); ++k)
    if (l(k) > 1e-12 * top) {
      gain += c(k) * c(k) / l(k);
      w(k) = -c(k) / l(k);
    }
  if (step != nullptr) *step = e.vectors * w;
  return gain;
}

// The score test of Coulomb friction on every coordinate at zero rates, at the current fit
// (θ, start states z0, loss): the criterion's gain n·log(L/(L − ΔL)) that the Gauss–Newton model
// predicts, ΔL the decrease of the loss with every parameter and start state free less the one
// with the rates held at 0 (their efficient score's quadratic form). The rates start at 1e-300,
// where |θ| has its slope and the map is the current one to rounding.
double coulomb_score_gain(const Candidate& current, Index d, const Matrix& z0,
                          const ShootingSegments& segs, double loss,
                          const ShootingOptions& options) {
  const auto& map = dynamic_cast<const HamiltonianLibraryMap&>(*current.inner.map);
  std::vector<DissipationTerm> next = map.dissipation();
  const Index first = static_cast<Index>(next.size());
  for (const DissipationTerm& t : dissipation_group(DissipationKind::kCoulomb, d))
    next.push_back(t);
  Candidate c = library_with(current, d, map.terms(), next);
  const auto& nm = dynamic_cast<const HamiltonianLibraryMap&>(*c.inner.map);
  std::vector<Index> rates, others;
  for (Index k = 0; k < nm.n_params(); ++k) {
    const bool rate = k >= nm.dissipation_index(first) && k < nm.dissipation_index(first + d);
    (rate ? rates : others).push_back(k);
  }
  for (Index k : rates) c.theta(k) = 1e-300;
  const Index n = segs.n_residuals();
  const NormalEquations ne = shooting_normal_equations(nm, c.theta, z0, segs, nm.n_params(),
                                                       1.0 / std::sqrt(static_cast<double>(n)),
                                                       false, options.should_stop);
  if (ne.stopped) throw_if_stop_requested("the score test of dry friction on the positions");
  const Matrix a = ne.a.selfadjointView<Eigen::Lower>();
  Matrix ar(others.size(), others.size());
  Vector gr(others.size());
  for (std::size_t i = 0; i < others.size(); ++i) {
    gr(static_cast<Index>(i)) = ne.g(others[i]);
    for (std::size_t j = 0; j < others.size(); ++j)
      ar(static_cast<Index>(i), static_cast<Index>(j)) = a(others[i], others[j]);
  }
  Vector step;
  const double full = gauss_newton_gain(a, ne.g, &step);
  // One rate: the model's gain with the rate held ≥ 0 is 0 where its step is not upward. With
  // more, the unconstrained gain stands as the bound.
  if (d == 1 && step(rates.front()) <= 0.0) return 0.0;
  const double drop = std::max(0.0, full - gauss_newton_gain(ar, gr));
  if (!std::isfinite(drop) || !(loss > 0.0)) return std::numeric_limits<double>::infinity();
  if (drop >= loss) return std::numeric_limits<double>::infinity();
  return static_cast<double>(n) * std::log(loss / (loss - drop));
}

struct FrictionTrial {
  std::string name;
  Candidate candidate;
  Matrix z0, val_z0;
  ShootingReport report;
  Index added = 0;
  double delta_bic = std::numeric_limits<double>::infinity();
};

// The group of `kind` on every coordinate, started so that it takes the share `share` of the
// current viscous dissipation over a cycle of the chain's motion, γ keeping the rest. Over a
// cycle of momentum amplitude P, viscous damping γ removes as much energy as Coulomb friction
// μ = π γ P / 4 or drag c = 3 π γ / (8 P); P is √2 times the RMS of the segments' start
// momenta, which sample the phase of the motion.
Candidate started_group(const Candidate& lib, Index d, DissipationKind kind, double share,
                        const Matrix& chain_z0) {
  const auto& map = dynamic_cast<const HamiltonianLibraryMap&>(*lib.inner.map);
  std::vector<DissipationTerm> next = map.dissipation();
  const std::size_t first = next.size();
  for (const DissipationTerm& t : dissipation_group(kind, d)) next.push_back(t);
  Candidate c = library_with(lib, d, map.terms(), next);
  const auto& nm = dynamic_cast<const HamiltonianLibraryMap&>(*c.inner.map);
  const Index bi = *nm.damping_param_index();
  const double beta = c.theta(bi);
  const double gamma = std::abs(beta);
  for (Index i = 0; i < d; ++i) {
    const double rms = std::sqrt(chain_z0.row(d + i).squaredNorm() /
                                 static_cast<double>(std::max<Index>(chain_z0.cols(), 1)));
    const double amplitude = std::max(std::sqrt(2.0) * rms, 1e-300);
    const double rate = kind == DissipationKind::kCoulomb
                            ? share * std::numbers::pi * gamma * amplitude / 4.0
                            : share * 3.0 * std::numbers::pi * gamma / (8.0 * amplitude);
    c.theta(nm.dissipation_index(static_cast<Index>(first) + i)) =
        std::max(rate, HamiltonianLibraryMap::kDissipationInit);
  }
  c.theta(bi) = (beta < 0.0 ? -1.0 : 1.0) * (1.0 - share) * gamma;
  return c;
}

// The group to offer: dry friction, when the core lacks it. Its cost is rough along the split
// between γ and μ (a trial that sticks early has no slope in the rest of the record), so it is
// started from three splits. Drag is not offered here: it acts at large amplitudes, where the
// velocity start sees it (the friction plan's drag records were all found there), and over the
// chain a drag group lowered the criterion by 17–24 on records without drag (a Coulomb record,
// and a softened central force the library cannot represent), absorbing misfit.
std::vector<FrictionTrial> offered_groups(const Candidate& lib, Index d, const Matrix& chain_z0) {
  const auto& map = dynamic_cast<const HamiltonianLibraryMap&>(*lib.inner.map);
  std::vector<FrictionTrial> out;
  for (const DissipationTerm& t : map.dissipation())
    if (t.kind == DissipationKind::kCoulomb) return out;
  for (const double share : {0.25, 0.5, 0.75}) {
    FrictionTrial t;
    t.name = "coulomb (started at " + std::to_string(static_cast<int>(std::lround(100 * share))) +
             "% of the damping)";
    t.candidate = started_group(lib, d, DissipationKind::kCoulomb, share, chain_z0);
    t.added = t.candidate.inner.n_params() - lib.inner.n_params();
    out.push_back(std::move(t));
  }
  return out;
}

// The reference the trials are judged against: the current core fitted on for as many steps as
// a trial. A trial starts from the linked fit and may lower the loss only by converging further;
// on a record with dry friction and no drag, that alone made drag look worth 17 units of the
// criterion. `at` and `at_z0` are the fit the score test is taken at: the linked fit, or the
// reference where it is lower.
struct Reference {
  ShootingReport report;
  Candidate at;
  Matrix at_z0;
};
Reference reference_fit(const Candidate& lib, Index d, const LinkedFit& linked,
                        const ShootingSegments& val, const Matrix& val_z0,
                        const ShootingOptions& options) {
  const auto& terms = dynamic_cast<const HamiltonianLibraryMap&>(*lib.inner.map).terms();
  Reference out{linked.report, library_with_terms(lib, d, terms), linked.chain.z0};
  Candidate current = library_with_terms(lib, d, terms);
  Matrix z0 = linked.chain.z0, vz = val_z0;
  ShootingOptions opt = options;
  opt.n_free = current.inner.n_params();
  opt.iterations = std::min(options.iterations, kTrialIterations);
  const ShootingReport r = fit_shooting(*current.inner.map, current.theta, z0, linked.chain.segs,
                                        vz, val, watching_damping(*current.inner.map, opt));
  if (r.stopped) throw_if_stop_requested("the friction and drag on the positions");
  if (r.final_loss < out.report.final_loss) {
    out.report = r;
    out.at = std::move(current);
    out.at_z0 = std::move(z0);
  }
  return out;
}

}  // namespace

bool add_dissipation_on_chain(Candidate& lib, Index d, LinkedFit& linked,
                              const ShootingSegments& val, Matrix& val_z0,
                              const ShootingOptions& options, std::vector<Matrix>& states,
                              nlohmann::json& rec) {
  if (dynamic_cast<const HamiltonianLibraryMap*>(lib.inner.map.get()) == nullptr ||
      linked.chain.segs.size() == 0)
    return false;
  const Index n = linked.chain.segs.n_residuals();
  nlohmann::json trials = nlohmann::json::array();
  Reference ref = reference_fit(lib, d, linked, val, val_z0, options);
  const ShootingReport& reference = ref.report;
  if (reference.final_loss <= kRoundingShare * mean_square(linked.chain.segs)) {
    rec["dissipation_added_on_positions"] = {
        {"residuals", n},
        {"added", nullptr},
        {"decision", "none offered: the current model fits the positions to rounding"}};
    return false;
  }
  std::vector<FrictionTrial> offered = offered_groups(lib, d, linked.chain.z0);
  if (offered.empty()) return false;
  // The score test first: where the Gauss–Newton model at zero rates cannot gain a quarter of
  // what the group must, the trials (each up to 25 steps over the whole chain) are not run.
  const double needed = kClearlyBetter + static_cast<double>(offered.front().added) *
                                             std::log(static_cast<double>(n));
  const double predicted =
      coulomb_score_gain(ref.at, d, ref.at_z0, linked.chain.segs, reference.final_loss, options);
  const nlohmann::json screen = {
      {"predicted_gain",
       std::isfinite(predicted) ? nlohmann::json(predicted) : nlohmann::json(nullptr)},
      {"needed_gain", needed},
      {"share_to_try", kScreenShare}};
  if (predicted < kScreenShare * needed) {
    rec["dissipation_added_on_positions"] = {
        {"residuals", n},
        {"added", nullptr},
        {"score_test", screen},
        {"decision",
         "none tried: the score test of Coulomb friction at zero rates predicts a gain in the "
         "criterion below a quarter of what the group must gain"}};
    return false;
  }
  std::optional<FrictionTrial> best;
  for (FrictionTrial& t : offered) {
    throw_if_stop_requested("the friction and drag offered on the linked positions");
    t.z0 = linked.chain.z0;
    t.val_z0 = val_z0;
    ShootingOptions opt = options;
    opt.n_free = t.candidate.inner.n_params();
    opt.iterations = std::min(options.iterations, kTrialIterations);
    // The trial watches the new group's first rate: its standard error says whether the group
    // is there or only lends the fit a few more steps of convergence (on a record with dry
    // friction and no drag, drag ended at 7e-5 ± 1e-3 after lowering the criterion by 17).
    const auto& tm = dynamic_cast<const HamiltonianLibraryMap&>(*t.candidate.inner.map);
    const Index rate = tm.dissipation_index(static_cast<Index>(tm.dissipation().size()) - d);
    opt.watch_index = rate;
    if (opt.converged_se <= 0.0) opt.converged_se = kDampingConvergedSe;
    const auto t0 = std::chrono::steady_clock::now();
    t.report = fit_shooting(*t.candidate.inner.map, t.candidate.theta, t.z0, linked.chain.segs,
                            t.val_z0, val, opt);
    const double rate_z = t.report.watch_se > 0.0
                              ? std::abs(t.candidate.theta(rate)) / t.report.watch_se
                              : std::numeric_limits<double>::infinity();
    if (t.report.stopped) throw_if_stop_requested("the friction and drag on the positions");
    t.delta_bic = bic_change_of_dropping(reference.final_loss, t.report.final_loss, n, -t.added);
    // The held-out segments are short: over them friction and viscous damping differ by little
    // (an encoder pendulum's linked fit halved its loss with friction, the held-out loss moved
    // by 0.2%). They must not speak against the group: a rise within the held-out loss's own
    // standard error, √(2/n) of it for n squared residuals, is no evidence either way.
    const double val_se =
        std::sqrt(2.0 / static_cast<double>(std::max<Index>(val.n_residuals(), 1)));
    const bool held_out_agrees =
        val.size() == 0 || t.report.val_loss <= reference.val_loss * (1.0 + val_se);
    trials.push_back(
        {{"group", t.name},
         {"parameters_added", t.added},
         {"loss_before", reference.final_loss},
         {"loss_after", t.report.final_loss},
         {"held_out_loss_before", reference.val_loss},
         {"held_out_loss_after", t.report.val_loss},
         {"bic_change", t.delta_bic},
         {"rate_over_standard_error",
          std::isfinite(rate_z) ? nlohmann::json(rate_z) : nlohmann::json(nullptr)},
         {"lm_iterations", t.report.iterations},
         {"seconds",
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()}});
    if (t.delta_bic < -kClearlyBetter && held_out_agrees && rate_z > kRateStandardErrors &&
        (!best || t.delta_bic < best->delta_bic))
      best = std::move(t);
  }
  if (!trials.empty())
    rec["dissipation_added_on_positions"] = {
        {"rule",
         "Coulomb friction on every coordinate, from three splits of the damping, is fitted "
         "over the linked chain; the best enters when it lowers the "
         "Bayesian information criterion, n log(loss) + parameters x log n, by more than 10 "
         "and the held-out loss does not rise by more than its standard error, both against "
         "the current core fitted on for as many steps as a trial, and its rate is more than "
         "3 standard errors from 0"},
        {"residuals", n},
        {"score_test", screen},
        {"trials", trials},
        {"added", best ? nlohmann::json(best->name) : nlohmann::json(nullptr)}};
  if (!best) return false;
  if (best->report.iterations >= kTrialIterations) {
    // Fitted on to convergence, still watching the rate, and judged again there: a rate that
    // a longer fit takes back to 0 was a passing state of the trial, not a group.
    const auto& bm = dynamic_cast<const HamiltonianLibraryMap&>(*best->candidate.inner.map);
    const Index rate = bm.dissipation_index(static_cast<Index>(bm.dissipation().size()) - d);
    ShootingOptions opt = options;
    opt.n_free = best->candidate.inner.n_params();
    opt.iterations = std::max<long>(1, options.iterations - kTrialIterations);
    opt.watch_index = rate;
    if (opt.converged_se <= 0.0) opt.converged_se = kDampingConvergedSe;
    best->report = fit_shooting(*best->candidate.inner.map, best->candidate.theta, best->z0,
                                linked.chain.segs, best->val_z0, val, opt);
    if (best->report.stopped) throw_if_stop_requested("the friction and drag on the positions");
    const double rate_z = best->report.watch_se > 0.0
                              ? std::abs(best->candidate.theta(rate)) / best->report.watch_se
                              : std::numeric_limits<double>::infinity();
    const double delta_bic =
        bic_change_of_dropping(reference.final_loss, best->report.final_loss, n, -best->added);
    nlohmann::json& r = rec["dissipation_added_on_positions"];
    r["fitted_on"] = {{"lm_iterations", best->report.iterations},
                      {"loss", best->report.final_loss},
                      {"bic_change", delta_bic},
                      {"rate_over_standard_error",
                       std::isfinite(rate_z) ? nlohmann::json(rate_z) : nlohmann::json(nullptr)}};
    if (!(delta_bic < -kClearlyBetter && rate_z > kRateStandardErrors)) {
      r["added"] = nullptr;
      r["fitted_on"]["decision"] = "not added: fitted to convergence it no longer passes";
      return false;
    }
  }
  lib = std::move(best->candidate);
  linked.chain.z0 = std::move(best->z0);
  val_z0 = std::move(best->val_z0);
  linked.report = best->report;
  write_chain_states(*lib.inner.map, lib.theta, linked.chain, states);
  return true;
}

}  // namespace csympnet::detail
