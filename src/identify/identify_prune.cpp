// Parsimony on the linked positions: the library core's higher powers (degree 3 and 4) dropped
// while the Bayesian information criterion of the linked fit says they do not earn their
// parameter (docs/identification.md, "Positions only").
//
// The terms were selected on velocities from local fits (identify_library.cpp), where a
// quartic absorbs the local fits' bias at about the gain of a real force term; the linked fit
// over whole stretches of the record is where the positions judge them. On a linear record of
// two carts in pixels (0.2% noise) the velocity stage kept (q1-q2)^3 and (q1-q2)^4; over the
// linked chain they lowered the loss by 0.1%, n log(L₁/L₀) = 4.9 against log n = 8.5.
// Friction and drag selected on the velocity start are judged the same way, a kind at a time.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "csympnet/core/stop.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "identify_chain.hpp"

namespace csympnet::detail {

namespace {

const HamiltonianLibraryMap& library_map(const Candidate& c) {
  return dynamic_cast<const HamiltonianLibraryMap&>(*c.inner.map);
}

struct Trial {
  std::string name, replaced_by;
  Candidate candidate;
  Matrix z0, val_z0;
  ShootingReport report;
  double delta_bic = std::numeric_limits<double>::infinity();
};

// A change of the information criterion above this is very strong evidence against the change
// (Kass and Raftery's scale: a Bayes factor beyond e^5).
constexpr double kClearlyWorse = 10.0;
// A trial change's fit is judged after at most this many Levenberg–Marquardt steps (most end
// on their convergence rules well before); the change made is then fitted on to convergence.
// On a record of 10^5 samples a step costs about a second, and a trial that crept on for 100
// steps cost 95 s of a fit's 350.
constexpr long kTrialIterations = 25;

}  // namespace

bool change_while_the_criterion_falls(
    Candidate& lib, LinkedFit& linked, const ShootingSegments& val, Matrix& val_z0,
    const ShootingOptions& options, std::vector<Matrix>& states,
    const std::function<std::vector<ChainChange>(const Candidate&)>& drops,
    nlohmann::json& trials) {
  const Index n = linked.chain.segs.n_residuals();
  bool changed = false;
  // Each change's criterion in the round before: one that raised it by more than
  // kClearlyWorse is not tried again after another change was made (a lazy greedy search: the
  // rounds cost the changes that stood a chance, not all of them again; on a 4-dof chain the
  // full rounds took 60 s).
  std::map<std::string, double> last;
  for (;;) {
    std::optional<Trial> best;
    for (ChainChange& drop : drops(lib)) {
      throw_if_stop_requested("the comparison of library terms on the linked positions");
      if (const auto was = last.find(drop.name); was != last.end() && was->second > kClearlyWorse)
        continue;
      Trial t{drop.name, drop.replaced_by, std::move(drop.candidate), linked.chain.z0, val_z0, {},
              0.0};
      ShootingOptions opt = options;
      opt.n_free = t.candidate.inner.n_params();
      opt.iterations = std::min(options.iterations, kTrialIterations);
      const auto t0 = std::chrono::steady_clock::now();
      t.report = fit_shooting(*t.candidate.inner.map, t.candidate.theta, t.z0, linked.chain.segs,
                              t.val_z0, val, watching_damping(*t.candidate.inner.map, opt));
      t.delta_bic =
          bic_change_of_dropping(linked.report.final_loss, t.report.final_loss, n, drop.parameters);
      trials.push_back(
          {{"term", t.name},
           {"parameters_removed", drop.parameters},
           {"loss_before", linked.report.final_loss},
           {"loss_after", t.report.final_loss},
           {"bic_change", t.delta_bic},
           {"lm_iterations", t.report.iterations},
           {"seconds",
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()}});
      if (!t.replaced_by.empty()) trials.back()["replaced_by"] = t.replaced_by;
      last[t.name] = t.delta_bic;
      if (t.report.stopped) throw_if_stop_requested("the comparison of library terms");
      if (t.delta_bic < 0.0 && (!best || t.delta_bic < best->delta_bic)) best = std::move(t);
    }
    if (!best) break;
    trials.push_back({{"dropped", best->name}, {"bic_change", best->delta_bic}});
    if (best->report.iterations >= kTrialIterations && !best->report.stopped) {
      // Fitted on from where the trial ended, with the rest of the budget.
      ShootingOptions opt = options;
      opt.n_free = best->candidate.inner.n_params();
      opt.iterations = std::max<long>(1, options.iterations - kTrialIterations);
      best->report = fit_shooting(*best->candidate.inner.map, best->candidate.theta, best->z0,
                                  linked.chain.segs, best->val_z0, val,
                                  watching_damping(*best->candidate.inner.map, opt));
      trials.back()["fitted_on"] = {{"lm_iterations", best->report.iterations},
                                    {"loss", best->report.final_loss}};
      if (best->report.stopped) throw_if_stop_requested("the comparison of library terms");
    }
    lib = std::move(best->candidate);
    linked.chain.z0 = std::move(best->z0);
    val_z0 = std::move(best->val_z0);
    linked.report = best->report;
    changed = true;
  }
  if (changed) write_chain_states(*lib.inner.map, lib.theta, linked.chain, states);
  return changed;
}

namespace {

bool applies(const Candidate& lib, const LinkedFit& linked) {
  return dynamic_cast<const HamiltonianLibraryMap*>(lib.inner.map.get()) != nullptr &&
         linked.chain.segs.size() > 0;
}

}  // namespace

double bic_change_of_dropping(double loss_with, double loss_without, Index n_residuals,
                              Index dropped) {
  const double n = static_cast<double>(n_residuals);
  if (!(loss_with > 0.0) || !std::isfinite(loss_without) || n_residuals <= 0)
    return std::numeric_limits<double>::infinity();
  return n * std::log(loss_without / loss_with) - static_cast<double>(dropped) * std::log(n);
}

bool prune_library_terms(Candidate& lib, Index d, LinkedFit& linked, const ShootingSegments& val,
                         Matrix& val_z0, const ShootingOptions& options,
                         std::vector<Matrix>& states, nlohmann::json& rec) {
  if (!applies(lib, linked)) return false;
  // The powers of degree 3 and 4, one at a time (the quadratics are the springs, the linear
  // terms the rest position; a sin/cos or exp group was judged against the powers of its
  // argument already).
  const auto drops = [d](const Candidate& c) {
    std::vector<ChainChange> out;
    const std::vector<LibraryTerm>& terms = library_map(c).terms();
    for (std::size_t k = 0; k < terms.size(); ++k) {
      if (terms[k].shape != TermShape::kPower || terms[k].power < 3) continue;
      std::vector<LibraryTerm> next = terms;
      next.erase(next.begin() + static_cast<long>(k));
      out.push_back({term_name(terms[k]), library_with_terms(c, d, next), 1, ""});
    }
    return out;
  };
  nlohmann::json trials = nlohmann::json::array();
  const bool changed =
      change_while_the_criterion_falls(lib, linked, val, val_z0, options, states, drops, trials);
  if (!trials.empty())
    rec["terms_pruned"] = {
        {"rule",
         "a power of degree 3 or 4 is dropped when the linked positions fit without it has the "
         "lower Bayesian information criterion, n log(loss) + parameters x log n"},
        {"residuals", linked.chain.segs.n_residuals()},
        {"trials", trials}};
  return changed;
}

bool prefer_polynomials_on_chain(Candidate& lib, Index d, const Matrix& q, LinkedFit& linked,
                                 const ShootingSegments& val, Matrix& val_z0,
                                 const ShootingOptions& options, std::vector<Matrix>& states,
                                 nlohmann::json& rec) {
  if (!applies(lib, linked)) return false;
  // Each sin/cos or exp group against the powers of its argument, started from their fit to
  // the group's potential; the swap's parameter count is what the two models differ by.
  const auto swaps = [d, &q](const Candidate& c) {
    std::vector<ChainChange> out;
    for (PolynomialAlternative& alt : polynomial_alternatives(c, d, q)) {
      const Index fewer = c.inner.n_params() - alt.candidate.inner.n_params();
      out.push_back({alt.replaced, std::move(alt.candidate), fewer, alt.by});
    }
    return out;
  };
  nlohmann::json trials = nlohmann::json::array();
  const bool changed =
      change_while_the_criterion_falls(lib, linked, val, val_z0, options, states, swaps, trials);
  if (!trials.empty())
    rec["polynomial_preferred"] = {
        {"rule",
         "a sin/cos or exp group is replaced by the powers of its argument when the linked "
         "positions fit with the powers has the lower Bayesian information criterion, n "
         "log(loss) + parameters x log n: the group stays only when it earns its extra "
         "parameters over whole stretches of the record"},
        {"residuals", linked.chain.segs.n_residuals()},
        {"trials", trials}};
  return changed;
}

bool drop_dissipation_on_chain(Candidate& lib, Index d, LinkedFit& linked,
                               const ShootingSegments& val, Matrix& val_z0,
                               const ShootingOptions& options, std::vector<Matrix>& states,
                               nlohmann::json& rec) {
  if (!applies(lib, linked)) return false;
  // Coulomb friction, or drag, on every coordinate at once (as they were selected).
  const auto drops = [d](const Candidate& c) {
    std::vector<ChainChange> out;
    const HamiltonianLibraryMap& map = library_map(c);
    for (const DissipationKind kind : {DissipationKind::kCoulomb, DissipationKind::kDrag}) {
      std::vector<DissipationTerm> next;
      Index dropped = 0;
      for (const DissipationTerm& t : map.dissipation())
        if (t.kind == kind)
          ++dropped;
        else
          next.push_back(t);
      if (dropped > 0)
        out.push_back(
            {dissipation_kind_name(kind), library_with(c, d, map.terms(), next), dropped, ""});
    }
    return out;
  };
  nlohmann::json trials = nlohmann::json::array();
  const bool changed =
      change_while_the_criterion_falls(lib, linked, val, val_z0, options, states, drops, trials);
  if (!trials.empty())
    rec["dissipation_on_positions"] = {
        {"rule",
         "Coulomb friction or drag selected on the velocity start is dropped when the linked "
         "positions fit without it has the lower Bayesian information criterion, n log(loss) + "
         "parameters x log n"},
        {"residuals", linked.chain.segs.n_residuals()},
        {"trials", trials}};
  return changed;
}

}  // namespace csympnet::detail
