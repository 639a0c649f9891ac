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

#include <Eigen/Eigenvalues>

#include "csympnet/core/dense.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/train/shooting.hpp"
#include "identify_chain.hpp"

namespace csympnet::detail {

namespace {

struct Trial {
  std::string name, replaced_by;
  Candidate candidate;
  Matrix z0, val_z0;
  ShootingReport report;
  double delta_bic = std::numeric_limits<double>::infinity();
};

// A drop is refitted unless a quarter of the rise of the loss that the Wald test predicts
// already raises the criterion by more than kClearlyWorse: the margin of four covers the
// Gauss–Newton model's error where the loss is not quadratic in the dropped parameters.
constexpr double kWaldShare = 0.25;

// The Gauss–Newton model of the chain's loss per residual at the current fit, the start
// states eliminated: loss(θ + δ) ≈ L + 2gᵀδ + δᵀAδ (A = JᵀJ/n, g = Jᵀr/n).
struct WaldModel {
  Matrix a_pinv;              // A⁺ (eigenvalues below 1e-12 of the largest count as 0)
  Matrix null_space;          // the eigenvectors those eigenvalues belong to, as columns
  Vector optimum;             // θ* = θ − A⁺g, the model's optimum
  double optimum_loss = 0.0;  // L − gᵀA⁺g
  bool valid = false;
};

WaldModel wald_model(const Candidate& lib, const LinkedFit& linked,
                     const ShootingOptions& options) {
  const OneStepMap& map = *lib.inner.map;
  const ShootingSegments& segs = linked.chain.segs;
  const Index n = segs.n_residuals();
  const NormalEquations ne = shooting_normal_equations(
      map, lib.theta, linked.chain.z0, segs, map.n_params(),
      1.0 / std::sqrt(static_cast<double>(n)), false, options.should_stop);
  if (ne.stopped) throw_if_stop_requested("the Wald test of the library terms on the positions");
  const dense::SymmetricEigen e =
      dense::symmetric_eigen(Matrix(ne.a.selfadjointView<Eigen::Lower>()));
  const Vector& l = e.values;
  const double top = std::max(l.maxCoeff(), 0.0);
  Vector inv = Vector::Zero(l.size());
  std::vector<Index> null;
  for (Index k = 0; k < l.size(); ++k)
    if (l(k) > 1e-12 * top)
      inv(k) = 1.0 / l(k);
    else
      null.push_back(k);
  WaldModel m;
  m.a_pinv = e.vectors * inv.asDiagonal() * e.vectors.transpose();
  m.null_space = e.vectors(Eigen::all, null);
  const Vector step = -(m.a_pinv * ne.g);
  m.optimum = lib.theta + step;
  m.optimum_loss = 2.0 * ne.cost + ne.g.dot(step);
  m.valid =
      top > 0.0 && m.a_pinv.allFinite() && m.optimum.allFinite() && std::isfinite(m.optimum_loss);
  return m;
}

// The Wald test's rise of the loss over the model's optimum when the parameters `fixed` are
// held at 0 and the rest refitted: θ*_Dᵀ [(A⁺)_DD]⁻¹ θ*_D, A⁺ keeping the directions the
// positions do not fix where they are. Those are mostly symmetries: from positions alone the
// mass and the potential's scale, (W, c) → (sW, c/s), which keep every coefficient's share and
// cannot take one to 0. Empty where the model cannot tell: a direction not fixed that lies
// mostly (over a quarter of its square) on the dropped parameters, as two terms that are one
// function would (the other then takes over at no cost, which A⁺ does not see); or (A⁺)_DD
// near singular.
std::optional<double> wald_rise(const WaldModel& m, const std::vector<Index>& fixed) {
  if (!m.valid || fixed.empty()) return std::nullopt;
  for (Index v = 0; v < m.null_space.cols(); ++v) {
    double share = 0.0;
    for (const Index i : fixed) share += m.null_space(i, v) * m.null_space(i, v);
    if (share > 0.25) return std::nullopt;
  }
  const auto k = static_cast<Index>(fixed.size());
  Matrix w(k, k);
  Vector t(k);
  for (Index i = 0; i < k; ++i) {
    t(i) = m.optimum(fixed[static_cast<std::size_t>(i)]);
    for (Index j = 0; j < k; ++j)
      w(i, j) = m.a_pinv(fixed[static_cast<std::size_t>(i)], fixed[static_cast<std::size_t>(j)]);
  }
  const dense::SymmetricEigen e = dense::symmetric_eigen(w);
  const double largest = std::max(m.a_pinv.diagonal().maxCoeff(), 0.0);
  if (!(e.values.minCoeff() > 1e-9 * largest)) return std::nullopt;
  const Vector c = e.vectors.transpose() * t;
  const double rise = c.cwiseAbs2().cwiseQuotient(e.values).sum();
  return std::isfinite(rise) ? std::optional<double>(rise) : std::nullopt;
}

// A drop the Wald test settles without a refit: its loss at a quarter of the rise the test
// predicts (wald_rise) already raises the criterion by more than kClearlyWorse. Returns its
// trial record (the loss and criterion change predicted, and the criterion at that margin), or
// none: refit it. `wald`: the current core's model, built here once a drop asks for it.
std::optional<nlohmann::json> screened(const ChainChange& change, const Candidate& lib,
                                       const LinkedFit& linked, std::optional<WaldModel>& wald,
                                       const ShootingOptions& options) {
  if (change.fixed_at_zero.empty()) return std::nullopt;
  const Index n = linked.chain.segs.n_residuals();
  const double loss = linked.report.final_loss;
  if (!wald) wald = wald_model(lib, linked, options);
  const std::optional<double> rise = wald_rise(*wald, change.fixed_at_zero);
  if (!rise) return std::nullopt;
  const double predicted = wald->optimum_loss + *rise;
  const double at_the_margin =
      bic_change_of_dropping(loss, wald->optimum_loss + kWaldShare * *rise, n, change.parameters);
  if (!(at_the_margin > kClearlyWorse)) return std::nullopt;
  return nlohmann::json{
      {"term", change.name},
      {"parameters_removed", change.parameters},
      {"loss_before", loss},
      {"loss_after", predicted},
      {"bic_change", bic_change_of_dropping(loss, predicted, n, change.parameters)},
      {"not_refitted",
       "the Wald test at the current fit: a quarter of the predicted rise of the loss would "
       "raise the criterion by " +
           std::to_string(at_the_margin)},
      {"criterion_at_the_margin", at_the_margin},
      {"lm_iterations", 0}};
}

}  // namespace

bool change_while_the_criterion_falls(
    Candidate& lib, LinkedFit& linked, const ShootingSegments& val, Matrix& val_z0,
    const ShootingOptions& options, std::vector<Matrix>& states,
    const std::function<std::vector<ChainChange>(const Candidate&)>& drops,
    nlohmann::json& trials) {
  const Index n = linked.chain.segs.n_residuals();
  bool changed = false;
  // A fit at rounding level cannot tell two cores apart: its criterion would rank rounding.
  if (linked.report.final_loss <= rounding_loss(linked.chain.segs)) return false;
  // Each change's criterion in the round before: one that raised it by more than
  // kClearlyWorse is not tried again after another change was made (a lazy greedy search: the
  // rounds cost the changes that stood a chance, not all of them again; on a 4-dof chain the
  // full rounds took 60 s).
  std::map<std::string, double> last;
  for (;;) {
    std::optional<Trial> best;
    std::optional<WaldModel> wald;  // at this round's fit, once a drop asks for it
    for (ChainChange& drop : drops(lib)) {
      throw_if_stop_requested("the comparison of library terms on the linked positions");
      if (const auto was = last.find(drop.name); was != last.end() && was->second > kClearlyWorse)
        continue;
      if (std::optional<nlohmann::json> skip = screened(drop, lib, linked, wald, options)) {
        last[drop.name] = skip->at("criterion_at_the_margin").get<double>();
        trials.push_back(std::move(*skip));
        continue;
      }
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

std::optional<double> wald_loss_of_dropping(const Candidate& lib, const LinkedFit& linked,
                                            const std::vector<Index>& fixed,
                                            const ShootingOptions& options) {
  const WaldModel m = wald_model(lib, linked, options);
  const std::optional<double> rise = wald_rise(m, fixed);
  if (!rise) return std::nullopt;
  return m.optimum_loss + *rise;
}

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
      ChainChange drop{term_name(terms[k]), library_with_terms(c, d, next), 1, "", {}};
      drop.fixed_at_zero = {library_map(c).coefficient_index(static_cast<Index>(k))};
      out.push_back(std::move(drop));
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
      out.push_back({alt.replaced, std::move(alt.candidate), fewer, alt.by, {}});
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
            {dissipation_kind_name(kind), library_with(c, d, map.terms(), next), dropped, "", {}});
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
