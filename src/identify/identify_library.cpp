// The Hamiltonian-library candidate (identify_stages.hpp, fit_library): terms chosen by forward
// selection on the training windows, kept by the held-out loss, pruned by their intervals, and
// integrated finely enough that the integrator's error stays below the residuals
// (docs/identification.md, "The Hamiltonian-library core").
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <functional>
#include <limits>
#include <map>
#include <optional>

#include "csympnet/core/dense.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/train/gamma_sandwich.hpp"
#include "identify_evaluators.hpp"
#include "identify_stages.hpp"

namespace csympnet::detail {

namespace {

constexpr int kOrder = 6;            // Yoshida's triple jump twice: nine stages per substep
constexpr double kStepPhase = 0.2;   // ω h / n at the start
constexpr Index kMaxSubsteps = 256;  // the integrator's error check doubles n up to this
constexpr long kRoundIterations = 12;
constexpr long kFinalIterations = 300;
// A group is fitted only where the Gauss–Newton step on every training window, from the fit
// with its coefficients at 0, is predicted to remove at least this share of the keep threshold
// from the training loss (the score test; the ranking's gain is taken on 400 windows, where a
// group's fit of the noise alone, about its size over their residuals, can pass it).
constexpr double kTryShareOfThreshold = 0.25;

const HamiltonianLibraryMap& library_of(const Candidate& x) {
  return dynamic_cast<const HamiltonianLibraryMap&>(*x.inner.map);
}

// A full M⁻¹ up to d = 4 (coupled masses); diagonal beyond (d(d+1)/2 parameters would
// dominate the count).
nlohmann::json library_core(const std::vector<LibraryTerm>& terms,
                            const std::vector<DissipationTerm>& dissipation, Index substeps,
                            const Vector& scales) {
  nlohmann::json names = nlohmann::json::array();
  for (const LibraryTerm& t : terms) names.push_back(term_name(t));
  nlohmann::json core = {
      {"type", "library"},
      {"terms", names},
      {"order", kOrder},
      {"substeps", substeps},
      {"mass", scales.size() <= 4 ? "full" : "diagonal"},
      {"coordinate_scales", std::vector<double>(scales.data(), scales.data() + scales.size())}};
  set_dissipation_spec(core, dissipation);
  return core;
}

// A candidate with these terms; θ carried over from `from` (W, β, and c, κ of shared terms,
// the rates of shared dissipation terms), else the map's documented start with β = beta_init.
// The dissipation terms are `from`'s unless given.
Candidate make_library_candidate(const std::vector<LibraryTerm>& terms, Index substeps,
                                 const Vector& scales, Index d, double beta_init,
                                 const Candidate* from,
                                 const std::vector<DissipationTerm>* dissipation = nullptr) {
  Candidate x;
  const std::vector<DissipationTerm> none;
  const std::vector<DissipationTerm>& dis = dissipation != nullptr ? *dissipation
                                            : from != nullptr      ? library_of(*from).dissipation()
                                                                   : none;
  x.core = library_core(terms, dis, substeps, scales);
  x.inner =
      make_model({{"type", "csympnet"}, {"d", d}, {"core", x.core}, {"beta_init", beta_init}});
  x.theta.resize(x.inner.n_params());
  Rng unused(0, "library-init");  // the map draws nothing
  x.inner.init_params(unused, x.theta);
  x.pretrained = true;
  if (from == nullptr) return x;
  const HamiltonianLibraryMap& a = library_of(*from);
  const HamiltonianLibraryMap& b = library_of(x);
  x.theta.head(b.mass_size()) = from->theta.head(a.mass_size());
  x.theta(*b.damping_param_index()) = from->theta(*a.damping_param_index());
  for (Index k = 0; k < static_cast<Index>(b.terms().size()); ++k)
    for (Index l = 0; l < static_cast<Index>(a.terms().size()); ++l) {
      if (!(a.terms()[static_cast<std::size_t>(l)] == b.terms()[static_cast<std::size_t>(k)]))
        continue;
      x.theta(b.coefficient_index(k)) = from->theta(a.coefficient_index(l));
      if (b.wavenumber_index(k) >= 0)
        x.theta(b.wavenumber_index(k)) = from->theta(a.wavenumber_index(l));
    }
  for (Index k = 0; k < static_cast<Index>(b.dissipation().size()); ++k)
    for (Index l = 0; l < static_cast<Index>(a.dissipation().size()); ++l)
      if (a.dissipation()[static_cast<std::size_t>(l)] ==
          b.dissipation()[static_cast<std::size_t>(k)])
        x.theta(b.dissipation_index(k)) = from->theta(a.dissipation_index(l));
  x.training = from->training;
  x.lm_seconds = from->lm_seconds;
  return x;
}

// A start for W, the coefficients and γ by linear least squares on the windows' difference
// quotients at their midpoints: (q₁ − q₀)/H ≈ W p̄ and (p₁ − p₀)/H ≈ −∇V(q̄) − γ p̄, linear in W,
// c and γ for the current wavenumbers. Without it LM can settle on an aliased frequency (a
// force too strong by the square of an integer). Polls `stop` every 64 windows: x is left as it
// was when a stop is requested (10 dof and 2,000 samples: 0.1 s, 1 s under the sanitizers).
void regression_start(Candidate& x, const WindowSet& w, const std::function<bool()>& stop) {
  const HamiltonianLibraryMap& map = library_of(x);
  const Index d = map.d(), n = w.size(), k_terms = static_cast<Index>(map.terms().size());
  const Vector span = w.span();
  Matrix qbar(d, n), pbar(d, n), qdot(d, n), pdot(d, n);
  for (Index i = 0; i < n; ++i) {
    qbar.col(i) = 0.5 * (w.z0.col(i).head(d) + w.zm.col(i).head(d));
    pbar.col(i) = 0.5 * (w.z0.col(i).tail(d) + w.zm.col(i).tail(d));
    qdot.col(i) = (w.zm.col(i).head(d) - w.z0.col(i).head(d)) / span(i);
    pdot.col(i) = (w.zm.col(i).tail(d) - w.z0.col(i).tail(d)) / span(i);
  }
  // W: each row of q̇ = W p̄ by least squares, then symmetrised.
  const Matrix ppt = pbar * pbar.transpose();
  const dense::Ldlt pl(ppt + 1e-12 * ppt.trace() * Matrix::Identity(d, d));
  Matrix wm = pl.solve(Matrix(pbar * qdot.transpose())).transpose();
  wm = 0.5 * (wm + wm.transpose());
  // ṗ = −Σ c_k ∇φ_k(q̄) − γ p̄: columns −∇φ_k and −p̄, stacked over coordinates and samples.
  Matrix a(n * d, k_terms + 1);
  Vector b(n * d);
  Vector probe = x.theta;
  for (Index k = 0; k < k_terms; ++k) probe(map.coefficient_index(k)) = 0.0;
  for (Index k = 0; k <= k_terms; ++k) {
    if (k < k_terms) probe(map.coefficient_index(k)) = 1.0;
    for (Index i = 0; i < n; ++i) {
      if (i % 64 == 63 && stop()) return;
      // ∇φ_k at q̄ as the force of the map with c_k = 1 alone: −(ṗ of one step) is not
      // needed; the potential's gradient is read by central differences of V.
      for (Index r = 0; r < d; ++r) {
        if (k == k_terms) {
          a(i * d + r, k) = -pbar(r, i);
          continue;
        }
        Vector qp = qbar.col(i), qm = qbar.col(i);
        const double step = 1e-6 * std::max(1.0, std::abs(qp(r)));
        qp(r) += step;
        qm(r) -= step;
        a(i * d + r, k) =
            -(map.potential(probe, qp.data()) - map.potential(probe, qm.data())) / (2.0 * step);
      }
    }
    if (k < k_terms) probe(map.coefficient_index(k)) = 0.0;
  }
  for (Index i = 0; i < n; ++i)
    for (Index r = 0; r < d; ++r) b(i * d + r) = pdot(r, i);
  const Matrix ata = a.transpose() * a;
  const dense::Ldlt al(ata + 1e-10 * ata.diagonal().maxCoeff() *
                                 Matrix::Identity(ata.rows(), ata.cols()));
  const Vector sol = al.solve(Vector(a.transpose() * b));
  if (!sol.allFinite() || !wm.allFinite()) return;
  for (Index r = 0; r < d; ++r)
    for (Index c = 0; c <= r; ++c)
      if (map.full_mass())
        x.theta(r * (r + 1) / 2 + c) = wm(r, c);
      else if (c == r)
        x.theta(r) = wm(r, r);
  for (Index k = 0; k < k_terms; ++k) x.theta(map.coefficient_index(k)) = sol(k);
  const double gamma = sol(k_terms);
  if (std::isfinite(gamma) && std::abs(gamma) > 1e-8) x.theta(*map.damping_param_index()) = gamma;
}

// The fastest rate of the data: per coordinate √(rms(Δq/H)/sd(q) · rms(Δp/H)/sd(p)) over the
// training windows (ω for an oscillator), the largest over coordinates.
double data_rate(const WindowSet& w) {
  const Index d = w.dim() / 2;
  const Vector span = w.span();
  double best = 0.0;
  for (Index i = 0; i < d; ++i) {
    double ratio = 1.0;
    for (Index row : {i, d + i}) {
      const double mean = w.z0.row(row).mean();
      double num = 0.0, den = 0.0;
      for (Index k = 0; k < w.size(); ++k) {
        const double rate = (w.zm(row, k) - w.z0(row, k)) / span(k);
        num += rate * rate;
        den += (w.z0(row, k) - mean) * (w.z0(row, k) - mean);
      }
      ratio *= den > 0.0 ? std::sqrt(num / den) : 0.0;
    }
    best = std::max(best, std::sqrt(ratio));
  }
  return best;
}

// The same map with twice the substeps moves the training windows' first steps by less than
// 5% of the residuals' rms (or by rounding alone): the integrator's error is below what the
// data can see.
bool integrator_fine_enough(const Candidate& x, const WindowSet& train, double train_loss, Index d,
                            double beta_init, const Vector& scales) {
  const HamiltonianLibraryMap& map = library_of(x);
  const Candidate finer = make_library_candidate(map.terms(), 2 * map.substeps(), scales, d,
                                                 beta_init, &x);  // same dissipation
  const Index n = std::min<Index>(train.size(), 400);
  Matrix z(train.dim(), n);
  Vector h(n);
  for (Index j = 0; j < n; ++j) {
    const Index i = j * train.size() / n;
    z.col(j) = train.z0.col(i);
    h(j) = train.h(0, i);
  }
  const Matrix a = x.inner.map->apply(x.theta, z, h);
  const Matrix b = finer.inner.map->apply(finer.theta, z, h);
  const double diff = (a - b).norm() / std::sqrt(static_cast<double>(a.size()));
  const double residual = std::sqrt(train_loss / static_cast<double>(train.dim()));
  const double rounding = 1e-13 * a.norm() / std::sqrt(static_cast<double>(a.size()));
  return diff <= std::max(0.05 * residual, rounding) || !std::isfinite(diff);
}

// The library's terms come in groups that a change of origin keeps together: the powers of
// one coordinate or difference (a shifted polynomial is a polynomial of the same degree), sin
// and cos of one argument (a shifted sine is a sum of both), and each exp alone. Selection adds
// a group at a time.
std::vector<std::vector<Index>> term_groups(const std::vector<LibraryTerm>& pool) {
  std::vector<std::vector<Index>> groups;
  std::vector<std::string> keys;
  for (std::size_t k = 0; k < pool.size(); ++k) {
    const LibraryTerm& t = pool[k];
    const std::string family = t.shape == TermShape::kPower ? "power"
                               : t.shape == TermShape::kExp ? term_name(t)
                                                            : "trig";
    const std::string key = family + ":" + std::to_string(t.i) + ":" + std::to_string(t.j);
    const auto at = std::find(keys.begin(), keys.end(), key);
    if (at == keys.end()) {
      keys.push_back(key);
      groups.push_back({static_cast<Index>(k)});
    } else {
      groups[static_cast<std::size_t>(at - keys.begin())].push_back(static_cast<Index>(k));
    }
  }
  return groups;
}

struct Addition {
  std::vector<Index> terms;    // pool indices added
  std::vector<double> steps;   // their Gauss–Newton coefficients
  double kappa = 1.0;          // the wavenumber they were scored at
  std::vector<double> kappas;  // per term (a joint addition of several groups)
  bool joint = false;          // several groups at once
  double gain = 0.0;           // predicted share of the training loss removed
  double criterion = 0.0;      // n log(1 − gain) + size log n: lower is better
};

// Gauss–Newton gains of adding each group's inactive terms to the active ones (the active
// parameters re-fitted), from the normal equations at c = 0 of the map holding every term, at
// each trial wavenumber; best first by a BIC-like criterion.
std::vector<Addition> ranked_additions(const Candidate& x, const std::vector<LibraryTerm>& pool,
                                       const std::vector<bool>& active,
                                       const std::vector<double>& kappas, CandidateFit& fit,
                                       const Communicator& comm, bool balanced, Index d,
                                       double beta_init, const Vector& scales) {
  std::vector<Addition> out;
  const HamiltonianLibraryMap& cur = library_of(x);
  std::vector<LibraryTerm> all = cur.terms();
  std::vector<Index> big_of(pool.size(), -1);  // index in the big map of each pool term
  for (std::size_t k = 0; k < pool.size(); ++k) {
    for (std::size_t l = 0; l < all.size(); ++l)
      if (all[l] == pool[k]) big_of[k] = static_cast<Index>(l);
    if (big_of[k] < 0) {
      big_of[k] = static_cast<Index>(all.size());
      all.push_back(pool[k]);
    }
  }
  if (all.size() == cur.terms().size()) return out;
  Candidate big = make_library_candidate(all, cur.substeps(), scales, d, beta_init, &x);
  const HamiltonianLibraryMap& map = library_of(big);
  // At most 400 training windows, evenly spread: the ranking needs no more.
  const WindowSet& all_train = fit.split().train;
  std::vector<Index> pick;
  const Index n_pick = std::min<Index>(all_train.size(), 400);
  for (Index j = 0; j < n_pick; ++j) pick.push_back(j * all_train.size() / n_pick);
  const WindowSet train = select_windows(all_train, pick);
  const double sc = 1.0 / std::sqrt(static_cast<double>(train.size()));
  const double n_res = static_cast<double>(all_train.size() * all_train.dim());
  const Index n_cur = static_cast<Index>(cur.terms().size());
  std::vector<Index> s;  // the active parameters: W, the current terms' c and κ, β
  for (Index k = 0; k < map.mass_size(); ++k) s.push_back(k);
  for (Index k = 0; k < n_cur; ++k) {
    s.push_back(map.coefficient_index(k));
    if (map.wavenumber_index(k) >= 0) s.push_back(map.wavenumber_index(k));
  }
  s.push_back(*map.damping_param_index());
  std::sort(s.begin(), s.end());
  s.erase(std::unique(s.begin(), s.end()), s.end());  // sin and cos share κ
  const Index ns = static_cast<Index>(s.size());
  const std::vector<std::vector<Index>> groups = term_groups(pool);
  for (std::size_t ki = 0; ki < kappas.size(); ++ki) {
    const double kappa = kappas[ki];
    for (Index k = n_cur; k < static_cast<Index>(all.size()); ++k)
      if (map.wavenumber_index(k) >= 0)
        big.theta(map.wavenumber_index(k)) = all[static_cast<std::size_t>(k)].kappa_sign * kappa;
    const NormalEquations ne = normal_equations_over_ranks(
        *big.inner.map, big.theta, train, balanced, sc, false,
        [&fit] { return fit.stop_requested(); }, comm);
    if (ne.stopped) return {};
    const Matrix a = ne.a.selfadjointView<Eigen::Lower>();
    Matrix ass(ns, ns);
    Vector gs(ns);
    for (Index r = 0; r < ns; ++r) {
      gs(r) = ne.g(s[static_cast<std::size_t>(r)]);
      for (Index c = 0; c < ns; ++c)
        ass(r, c) = a(s[static_cast<std::size_t>(r)], s[static_cast<std::size_t>(c)]);
    }
    ass.diagonal() += 1e-10 * ass.diagonal().cwiseMax(1e-300);
    const dense::Ldlt ldlt(ass);
    const Vector ags = ldlt.solve(gs);
    for (const std::vector<Index>& group : groups) {
      std::vector<Index> add;
      bool has_kappa = false;
      for (Index k : group)
        if (!active[static_cast<std::size_t>(k)]) {
          add.push_back(k);
          has_kappa = has_kappa || pool[static_cast<std::size_t>(k)].has_wavenumber();
        }
      if (add.empty() || (!has_kappa && ki > 0)) continue;
      const Index ng = static_cast<Index>(add.size());
      Matrix b(ns, ng), agg(ng, ng);
      Vector gg(ng);
      for (Index c = 0; c < ng; ++c) {
        const Index ci = map.coefficient_index(big_of[static_cast<std::size_t>(add[c])]);
        gg(c) = ne.g(ci);
        for (Index r = 0; r < ns; ++r) b(r, c) = a(s[static_cast<std::size_t>(r)], ci);
        for (Index r = 0; r < ng; ++r)
          agg(r, c) = a(map.coefficient_index(big_of[static_cast<std::size_t>(add[r])]), ci);
      }
      const Vector num = gg - b.transpose() * ags;
      Matrix den = agg - b.transpose() * ldlt.solve(b);
      den.diagonal() += 1e-12 * agg.diagonal().cwiseMax(1e-300);
      const dense::Ldlt dl(den);
      if (!dl.ok() || !num.allFinite()) continue;
      const Vector step = -dl.solve(num);
      const double gain = std::clamp(-0.5 * num.dot(step) / std::max(ne.cost, 1e-300), 0.0, 1.0);
      if (!std::isfinite(gain) || gain <= 0.0) continue;
      Addition ad;
      ad.terms = add;
      ad.steps.assign(step.data(), step.data() + ng);
      ad.kappa = kappa;
      ad.gain = gain;
      ad.criterion = n_res * std::log(std::max(1.0 - gain, 1e-300)) +
                     static_cast<double>(ng) * std::log(n_res);
      out.push_back(std::move(ad));
    }
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const Addition& u, const Addition& v) { return u.criterion < v.criterion; });
  // One entry per group: its best wavenumber.
  std::vector<Addition> unique;
  for (Addition& ad : out) {
    const bool seen = std::any_of(unique.begin(), unique.end(),
                                  [&](const Addition& u) { return u.terms == ad.terms; });
    if (!seen) unique.push_back(std::move(ad));
  }
  return unique;
}

// The selection as a class: the fit's context as members, one method per stage.
class LibrarySelection {
 public:
  LibrarySelection(CandidateFit& fit, const nlohmann::json& given_core, Index d, double beta_init,
                   const Normalization& units, bool balanced, const Communicator& comm,
                   nlohmann::json& rec)
      : fit_(&fit),
        split_(&fit.split()),
        d_(d),
        beta_init_(beta_init),
        balanced_(balanced),
        comm_(comm),
        rec_(rec) {
    // Differences weigh the coordinates by their units, so that q_i − q_j of the user's data
    // stays a difference (normalisation.hpp scales each coordinate on its own).
    scales_ = units.q_scale.size() == d ? units.q_scale : Vector::Ones(d);
    scales_ /= std::exp(scales_.array().log().mean());
    const Index n_val_residuals = split_->val.size() * split_->val.dim();
    // A term must lower the held-out loss by this share to be kept.
    threshold_ = std::max(2e-3, 10.0 / static_cast<double>(n_val_residuals));
    // Below this held-out loss the residuals are rounding: a change there is no change.
    floor_ = 1e-22 * split_->val.zm.squaredNorm() / static_cast<double>(split_->val.size());
    rec_["keep_threshold"] = threshold_;
    rec_["rounding_floor"] = floor_;
    pool_ = full_library(d);
    given_terms_ = given_core.contains("terms");
    given_dissipation_ = given_core.contains("dissipation");
    if (given_dissipation_) dissipation_ = read_library_spec(given_core, d, "core").dissipation;
    if (given_terms_) {
      pool_.clear();
      for (const auto& name : given_core.at("terms"))
        pool_.push_back(parse_term(name.get<std::string>(), d, "core.terms"));
      active_.assign(pool_.size(), true);
    } else {
      active_.assign(pool_.size(), false);
      for (std::size_t k = 0; k < pool_.size(); ++k)
        active_[k] = pool_[k].shape == TermShape::kPower && pool_[k].j < 0 && pool_[k].power <= 2;
    }
  }

  // The fit (and its split) that the stages from here on use: the final fit switches from the
  // thinned selection windows to every training window.
  void use(CandidateFit& fit) {
    fit_ = &fit;
    split_ = &fit.split();
  }

  // The start: q_i and q_i² (or the given terms), least squares, LM, the integrator refined.
  Candidate start() {
    const double omega = data_rate(split_->train);
    const double h_max = split_->train.h.maxCoeff();
    const Index substeps =
        std::clamp<Index>(static_cast<Index>(std::ceil(omega * h_max / kStepPhase)), 1, 64);
    rec_["order"] = kOrder;
    rec_["data_rate"] = omega;
    rec_["substeps_start"] = substeps;
    Candidate x = make(active_terms(), substeps, nullptr);
    // After a stop request the candidate stays as made.
    regression_start(x, split_->train, [this] { return fit_->stop_requested(); });
    if (fit_->stop_requested()) return x;
    train_lm(x, kRoundIterations, "library: start");
    refine_integrator(x, "start");
    rec_["start"] = {{"terms", x.core["terms"]}, {"val_loss", x.val_loss}};
    return x;
  }

  // Forward selection: groups by Gauss–Newton gain, each kept when LM with it lowers the
  // held-out loss by the threshold.
  void forward(Candidate& x) {
    const Index max_terms = 6 * d_ + 6;
    const std::vector<double> kappas =
        d_ <= 3 ? std::vector<double>{0.5, 1.0, 2.0} : std::vector<double>{1.0};
    nlohmann::json steps = nlohmann::json::array();
    bool added = true;
    // At the rounding floor nothing can earn its place.
    while (added && !given_terms_ && !fit_->stop_requested() && x.val_loss > floor_ &&
           static_cast<Index>(active_terms().size()) < max_terms) {
      added = false;
      const std::vector<Addition> all = tries(ranked_additions(
          x, pool_, active_, kappas, *fit_, comm_, balanced_, d_, beta_init_, scales_));
      // The joint batch (d > 2) is kept as soon as it earns its place; of the single groups,
      // each of the best three is fitted (with, beside a sinusoid or an exponential, the powers
      // of the same argument, so that the polynomial is always tried), and the lowest held-out
      // loss is kept: the linearised gain ranks them, the fit decides. No margin for the
      // simpler family here: on measured momenta a pendulum's cos group beats its polynomial
      // by less than the keep threshold, and the polynomial biased γ̂ by 12% (identification
      // benchmark, coupled pendulums at 1% noise); on positions, prefer_polynomials_on_chain
      // judges the families on what was observed.
      std::optional<Candidate> best;
      std::vector<Index> best_terms;
      int best_family = 0;
      for (const Addition& ad : all) {
        if (ad.gain < 1e-6 || fit_->stop_requested()) break;
        Candidate y = with_terms(x, ad);
        const std::string name = names(ad.terms);
        const int family = family_rank(ad);
        nlohmann::json step = {{"terms", name},
                               {"family", family == 0   ? "power"
                                          : family == 1 ? "sin/cos"
                                                        : "exp"},
                               {"predicted_gain", ad.gain}};
        const double share = predicted_share(y, ad);
        if (fit_->stop_requested()) break;
        step["predicted_gain_all_windows"] = share;
        if (share < kTryShareOfThreshold * threshold_) {
          step["fitted"] = false;
          step["earns_its_place"] = false;
          step["why"] =
              "not fitted: on every training window the Gauss-Newton step is predicted "
              "to remove less than a quarter of the keep threshold from the loss";
          steps.push_back(step);
          continue;
        }
        train_lm(y, kRoundIterations, "library: with " + name);
        const bool earns = improves(x.val_loss, y.val_loss);
        step["val_loss_before"] = x.val_loss;
        step["val_loss_after"] = y.val_loss;
        step["earns_its_place"] = earns;
        steps.push_back(step);
        if (earns && (!best || preferred(y.val_loss, family, best->val_loss, best_family))) {
          best = std::move(y);
          best_terms = ad.terms;
          best_family = family;
        }
        if (best && ad.joint) break;
      }
      if (!best) break;
      for (Index k : best_terms) active_[static_cast<std::size_t>(k)] = true;
      x = std::move(*best);
      steps.push_back({{"kept", names(best_terms)}, {"val_loss", x.val_loss}});
      refine_integrator(x, "after " + names(best_terms));
      added = true;
    }
    rec_["forward"] = steps;
  }

  // Backward elimination: the two groups whose terms are least significant (by their largest
  // sandwich t-ratio), then the terms below t = 2 that are negligible together (their joint
  // Wald test, jointly_negligible) at once, then the least significant of them alone, each dropped
  // when the held-out loss stays within the threshold (or the rounding floor). A drop refused is
  // not tried again until the held-out loss has moved by the threshold since: the drops made in
  // between (terms at t below 2) leave the model as it was, and on a 20-mass chain the same two
  // refused groups were refitted in each of 40 rounds (200 of a fit's 580 CPU s). The joint drop
  // spares a refit per term: a 10-mass chain from positions dropped 20 terms below t = 2 one at a
  // time, 20 refits of about 0.4 CPU s each. A joint drop refused halves the number of terms the
  // next one may take (the least significant first), so at most log2 of them are refused in one
  // elimination; the single drop after it keeps the one-at-a-time path for terms only significant
  // together.
  void backward(Candidate& x) {
    nlohmann::json pruned = nlohmann::json::array();
    std::map<std::vector<Index>, double> refused_at;  // the held-out loss when it was refused
    long not_retried = 0;
    bool dropped_one = !given_terms_;
    std::size_t joint_cap = std::numeric_limits<std::size_t>::max();
    while (dropped_one && !fit_->stop_requested() && active_terms().size() > 1) {
      dropped_one = false;
      NormalEquations ne;
      const std::vector<double> t_of = t_ratios(x, ne);
      if (t_of.empty()) break;
      for (const auto& [t, terms, joint, wald, blocks] : drops(x, ne, t_of, joint_cap)) {
        if (fit_->stop_requested()) break;
        if (const auto was = refused_at.find(terms);
            was != refused_at.end() &&
            std::abs(x.val_loss - was->second) <= threshold_ * was->second) {
          ++not_retried;
          continue;
        }
        std::vector<bool> trial = active_;
        for (Index k : terms) trial[static_cast<std::size_t>(k)] = false;
        std::swap(active_, trial);
        Candidate y = make(active_terms(), library_of(x).substeps(), &x);
        const bool projected = start_projected(x, terms, ne, y);
        const std::string name = names(terms);
        train_lm(y, kRoundIterations, "library: without " + name);
        const bool drop = no_worse(x.val_loss, y.val_loss);
        pruned.push_back(
            {{"terms", name},
             {"t_ratio", t},
             {"joint", joint},
             {"joint_wald", joint ? nlohmann::json(wald) : nlohmann::json(nullptr)},
             {"joint_blocks", joint ? nlohmann::json(blocks) : nlohmann::json(nullptr)},
             {"start", projected ? "projected" : "the fit without the terms"},
             {"val_loss_before", x.val_loss},
             {"val_loss_after", y.val_loss},
             {"dropped", drop}});
        if (!drop) {
          std::swap(active_, trial);
          refused_at[terms] = x.val_loss;
          if (joint) joint_cap = terms.size() / 2;
          continue;
        }
        x = std::move(y);
        dropped_one = true;
        break;
      }
    }
    rec_["pruned_not_retried"] = not_retried;
    rec_["pruned"] = pruned;
  }

  // The dissipation beyond γ (docs/identification.md, "Dry friction and drag"). The viscous
  // model is the null: a group of terms (Coulomb friction on every coordinate, or drag)
  // enters when the amplitude check of the current model finds its rate changing with the
  // amplitude (significant, p below the check's alpha) in the direction of that term (falling
  // with the amplitude: Coulomb; rising: drag), and the model with it lowers the held-out loss
  // by the keep threshold. Two rounds at most, so that both kinds can enter. It runs after the
  // start, before the potential's terms are selected (a friction misfit would otherwise be
  // taken up by spurious potential terms), and again after them (prune_dissipation first). A
  // choice other than "auto" fits what it names, as given.
  void dissipation(Candidate& x, const std::string& choice, const std::string& when) {
    nlohmann::json& rec = rec_["dissipation"];
    rec["choice"] = given_dissipation_ ? "given in the core" : choice;
    if (!rec.contains("rounds")) rec["rounds"] = nlohmann::json::array();
    std::vector<DissipationKind> forced;
    if (!given_dissipation_ && choice == "viscous+coulomb") forced = {DissipationKind::kCoulomb};
    if (!given_dissipation_ && choice == "viscous+drag") forced = {DissipationKind::kDrag};
    for (DissipationKind kind : forced) {
      if (has(kind)) continue;
      x = with_dissipation(x, kind);
      refine_integrator(x, "after " + dissipation_kind_name(kind));
      rec["rounds"].push_back({{"added", dissipation_kind_name(kind)}, {"given", true}});
    }
    for (int round = 0;
         choice == "auto" && !given_dissipation_ && round < 2 && !fit_->stop_requested(); ++round) {
      const ModelCheck amp = amplitude_of(x, *split_, [this] { return fit_->stop_requested(); });
      nlohmann::json step = {
          {"when", when}, {"amplitude_check", amp}, {"val_loss_before", x.val_loss}};
      const bool significant = amp.applicable && amp.p_value < amp.alpha;
      if (!significant) {
        step["decision"] = "the rate does not change significantly with amplitude: none added";
        rec["rounds"].push_back(step);
        break;
      }
      const DissipationKind kind =
          amp.statistic < 0.0 ? DissipationKind::kCoulomb : DissipationKind::kDrag;
      if (has(kind)) {
        step["decision"] = "the amplitude check still calls for " + dissipation_kind_name(kind) +
                           ", which the model has: nothing further to add";
        rec["rounds"].push_back(step);
        break;
      }
      Candidate y = with_dissipation(x, kind);
      const bool earns = improves(x.val_loss, y.val_loss);
      step["tried"] = dissipation_kind_name(kind);
      step["val_loss_after"] = y.val_loss;
      step["earns_its_place"] = earns;
      step["decision"] = earns ? "added" : "not added: the held-out loss does not fall enough";
      rec["rounds"].push_back(step);
      if (!earns) {
        dissipation_ = library_of(x).dissipation();
        break;
      }
      x = std::move(y);
      refine_integrator(x, "after " + dissipation_kind_name(kind));
    }
    nlohmann::json names = nlohmann::json::array();
    for (const DissipationTerm& t : library_of(x).dissipation())
      names.push_back(dissipation_name(t));
    rec["terms"] = names;
  }

  // Each kind of dissipation selected ("auto" only) dropped when the held-out loss without it
  // stays within the keep threshold: the potential's terms chosen since may explain what it
  // took up.
  void prune_dissipation(Candidate& x, const std::string& choice) {
    if (choice != "auto" || given_dissipation_) return;
    nlohmann::json& rec = rec_["dissipation"];
    for (DissipationKind kind : {DissipationKind::kCoulomb, DissipationKind::kDrag}) {
      if (!has(kind) || fit_->stop_requested()) continue;
      const std::vector<DissipationTerm> kept = dissipation_;
      std::erase_if(dissipation_, [&](const DissipationTerm& t) { return t.kind == kind; });
      Candidate y = make(active_terms(), library_of(x).substeps(), &x);
      train_lm(y, kRoundIterations, "library: without " + dissipation_kind_name(kind));
      const bool drop = no_worse(x.val_loss, y.val_loss);
      rec["rounds"].push_back({{"when", "pruning"},
                               {"tried_without", dissipation_kind_name(kind)},
                               {"val_loss_before", x.val_loss},
                               {"val_loss_after", y.val_loss},
                               {"dropped", drop}});
      if (drop)
        x = std::move(y);
      else
        dissipation_ = kept;
    }
  }

  // The chosen terms to convergence, the integrator checked once more, and how far γ̂ moves
  // at twice the substeps (the interval's integrator term, identify_assess).
  void finish(Candidate& x) {
    train_lm(x, kFinalIterations, "library: final");
    refine_integrator(x, "final");
    if (!fit_->stop_requested()) {
      // One Gauss–Newton step at twice the substeps from the fit, less the step at the fit's
      // own substeps: the change is small, so their difference is where the finer integrator
      // moves the fit, without what the fit's own optimisation left undone (an LM kept to the
      // best validation loss stays put whenever the held-out windows cannot see the change,
      // and would report no move at all).
      Candidate finer = make(library_of(x).terms(), 2 * library_of(x).substeps(), &x);
      const Vector step = fit_->gauss_newton_step(finer);
      const Vector own = fit_->gauss_newton_step(x);
      if (step.size() == finer.theta.size() && own.size() == step.size()) finer.theta += step - own;
      const double g0 = *x.inner.map->damping_rate(x.theta);
      const double g1 = *finer.inner.map->damping_rate(finer.theta);
      rec_["gamma_change_at_twice_the_substeps"] = std::isfinite(g1) ? std::abs(g1 - g0) : 0.0;
      // The same for each dissipation term, relative (its value in the user's units is a fixed
      // multiple of W_ii μ or c / W_ii): the integrator's error in it is the integrator's
      // share of its interval (docs/derivations.md, "Dry friction and drag").
      nlohmann::json changes = nlohmann::json::array();
      const HamiltonianLibraryMap& a = library_of(x);
      const HamiltonianLibraryMap& b = library_of(finer);
      for (Index k = 0; k < static_cast<Index>(a.dissipation().size()); ++k) {
        const auto value = [k](const HamiltonianLibraryMap& m, const Vector& th) {
          const DissipationTerm& t = m.dissipation()[static_cast<std::size_t>(k)];
          const double w = th(m.full_mass() ? t.i * (t.i + 1) / 2 + t.i : t.i);
          const double r = std::abs(th(m.dissipation_index(k)));
          return t.kind == DissipationKind::kCoulomb ? w * r : r / w;
        };
        const double v0 = value(a, x.theta), v1 = value(b, finer.theta);
        const double rel = std::abs(v1 - v0) / std::max(std::abs(v0), 1e-300);
        changes.push_back(std::isfinite(rel) ? rel : 0.0);
      }
      rec_["dissipation_change_at_twice_the_substeps"] = changes;
    }
    rec_["terms"] = x.core["terms"];
    rec_["substeps"] = library_of(x).substeps();
    rec_["val_loss"] = x.val_loss;
  }

 private:
  std::vector<LibraryTerm> active_terms() const {
    std::vector<LibraryTerm> t;
    for (std::size_t k = 0; k < pool_.size(); ++k)
      if (active_[k]) t.push_back(pool_[k]);
    return t;
  }
  std::string names(const std::vector<Index>& terms) const {
    std::string name;
    for (Index k : terms)
      name += (name.empty() ? "" : ", ") + term_name(pool_[static_cast<std::size_t>(k)]);
    return name;
  }
  bool has(DissipationKind kind) const {
    return std::any_of(dissipation_.begin(), dissipation_.end(),
                       [&](const DissipationTerm& t) { return t.kind == kind; });
  }
  Candidate make(const std::vector<LibraryTerm>& terms, Index substeps, const Candidate* from) {
    return make_library_candidate(terms, substeps, scales_, d_, beta_init_, from, &dissipation_);
  }
  // x with a kind of dissipation on every coordinate, started by least squares on x's
  // residuals and trained by LM.
  Candidate with_dissipation(const Candidate& x, DissipationKind kind) {
    for (const DissipationTerm& t : dissipation_group(kind, d_)) dissipation_.push_back(t);
    Candidate y = make(active_terms(), library_of(x).substeps(), &x);
    dissipation_start(y, library_of(x).dissipation().size(), split_->train);
    train_lm(y, 2 * kRoundIterations, "library: with " + dissipation_kind_name(kind));
    return y;
  }
  // x with the addition's terms, coefficients 0 (so LM starts from x's fit; its first step is
  // the joint Gauss–Newton step the ranking predicted) and wavenumbers as ranked.
  Candidate with_terms(const Candidate& x, const Addition& ad) {
    std::vector<bool> trial = active_;
    for (Index k : ad.terms) trial[static_cast<std::size_t>(k)] = true;
    std::vector<LibraryTerm> terms;
    for (std::size_t k = 0; k < pool_.size(); ++k)
      if (trial[k]) terms.push_back(pool_[k]);
    Candidate y = make(terms, library_of(x).substeps(), &x);
    const HamiltonianLibraryMap& ym = library_of(y);
    for (std::size_t a = 0; a < ad.terms.size(); ++a)
      for (Index k = 0; k < static_cast<Index>(ym.terms().size()); ++k)
        if (ym.terms()[static_cast<std::size_t>(k)] ==
                pool_[static_cast<std::size_t>(ad.terms[a])] &&
            ym.wavenumber_index(k) >= 0)
          y.theta(ym.wavenumber_index(k)) =
              ym.terms()[static_cast<std::size_t>(k)].kappa_sign * ad.kappas[a];
    return y;
  }
  // The share of y's training loss (on every training window) that the Gauss–Newton step from
  // y as made is predicted to remove, the added terms' wavenumbers held (at coefficients 0 the
  // loss does not depend on them): ½ gᵀA⁻¹g over the loss, A with a 1e-10 ridge as the ranking
  // takes it. Infinite where it cannot be computed (the group is then fitted).
  double predicted_share(const Candidate& y, const Addition& ad) {
    const HamiltonianLibraryMap& ym = library_of(y);
    const WindowSet& train = split_->train;
    const NormalEquations ne = normal_equations_over_ranks(
        *y.inner.map, y.theta, train, balanced_, 1.0 / std::sqrt(static_cast<double>(train.size())),
        false, [this] { return fit_->stop_requested(); }, comm_);
    if (ne.stopped || !(ne.cost > 0.0)) return std::numeric_limits<double>::infinity();
    std::vector<char> held(static_cast<std::size_t>(ym.n_params()), 0);
    for (Index k = 0; k < static_cast<Index>(ym.terms().size()); ++k)
      for (Index t : ad.terms)
        if (ym.terms()[static_cast<std::size_t>(k)] == pool_[static_cast<std::size_t>(t)] &&
            ym.wavenumber_index(k) >= 0)
          held[static_cast<std::size_t>(ym.wavenumber_index(k))] = 1;
    std::vector<Index> free;
    for (Index j = 0; j < ym.n_params(); ++j)
      if (!held[static_cast<std::size_t>(j)]) free.push_back(j);
    const Matrix a = ne.a.selfadjointView<Eigen::Lower>();
    Matrix af = a(free, free);
    const Vector gf = ne.g(free);
    af.diagonal() += 1e-10 * af.diagonal().cwiseMax(1e-300);
    const dense::Ldlt f(af);
    if (!f.ok()) return std::numeric_limits<double>::infinity();
    const double share = 0.5 * gf.dot(f.solve(gf)) / ne.cost;
    return std::isfinite(share) ? share : std::numeric_limits<double>::infinity();
  }
  bool improves(double before, double after) const {
    return before > floor_ && after < before * (1.0 - threshold_);
  }
  bool no_worse(double before, double after) const {
    return after <= std::max(before * (1.0 + threshold_), floor_);
  }
  void train_lm(Candidate& c, long budget, const std::string& label) {
    fit_->lm(c, budget, label);
    c.val_loss = fit_->loss(c, split_->val);
    if (!std::isfinite(c.val_loss)) c.val_loss = std::numeric_limits<double>::infinity();
  }

  // Twice the substeps until the integrator's error is below what the data can see, then LM
  // (which lowers the residuals, so the check is made again). Once the residuals are at the
  // rounding floor the data can see nothing finer: the doubling ends there (a finer
  // integrator's move of γ̂ still enters the interval, finish()).
  void refine_integrator(Candidate& c, const std::string& when) {
    for (int pass = 0; pass < 4 && !fit_->stop_requested(); ++pass) {
      bool changed = false;
      while (library_of(c).substeps() < kMaxSubsteps) {
        if (fit_->loss(c, split_->val) <= floor_) {  // the floor is the held-out loss's
          rec_["integrator_at_floor"] = {{"when", when}, {"substeps", library_of(c).substeps()}};
          break;
        }
        if (integrator_fine_enough(c, split_->train, fit_->loss(c, split_->train), d_, beta_init_,
                                   scales_))
          break;
        c = make(library_of(c).terms(), 2 * library_of(c).substeps(), &c);
        changed = true;
      }
      if (!changed) break;
      train_lm(c, kRoundIterations, "library: finer integrator");
      rec_["integrator_steps"].push_back(
          {{"when", when}, {"substeps", library_of(c).substeps()}, {"val_loss", c.val_loss}});
    }
  }

  // With d > 2 the best ⌈d/2⌉ groups together first (a chain needs many alike), then the best
  // three groups one at a time.
  std::vector<Addition> tries(const std::vector<Addition>& ranked) const {
    std::vector<Addition> out;
    const std::size_t batch = d_ > 2 ? static_cast<std::size_t>((d_ + 1) / 2) : 1;
    if (batch > 1 && ranked.size() > 1) {
      Addition joint;
      joint.joint = true;
      // Groups of the best group's family only (a chain's bonds are alike; a sinusoid beside a
      // polynomial is not the same kind of step).
      const auto family = [this](const Addition& ad) {
        const LibraryTerm& t = pool_[static_cast<std::size_t>(ad.terms.front())];
        return std::make_pair(t.shape == TermShape::kPower ? 0
                              : t.shape == TermShape::kExp ? 2
                                                           : 1,
                              t.j >= 0);
      };
      std::size_t taken = 0;
      for (std::size_t r = 0; r < ranked.size() && taken < batch; ++r) {
        if (ranked[r].gain < 1e-6) break;
        if (family(ranked[r]) != family(ranked.front())) continue;
        ++taken;
        for (Index k : ranked[r].terms) {
          joint.terms.push_back(k);
          joint.kappas.push_back(ranked[r].kappa);
        }
        joint.gain = std::max(joint.gain, ranked[r].gain);
      }
      if (taken >= 2) out.push_back(joint);
    }
    const std::size_t singles = out.size();
    for (std::size_t r = 0; r < std::min<std::size_t>(ranked.size(), 3); ++r) {
      out.push_back(ranked[r]);
      out.back().kappas.assign(ranked[r].terms.size(), ranked[r].kappa);
    }
    // Beside a sinusoid or an exponential, the powers of the same argument, so that the
    // simpler family is always fitted before the other can win.
    for (std::size_t r = singles; r < std::min(out.size(), singles + 3); ++r) {
      if (family_rank(out[r]) == 0) continue;
      const LibraryTerm& t = pool_[static_cast<std::size_t>(out[r].terms.front())];
      for (const Addition& ad : ranked) {
        const LibraryTerm& u = pool_[static_cast<std::size_t>(ad.terms.front())];
        const bool same_argument =
            (u.i == t.i && u.j == t.j) || (t.j >= 0 && u.i == t.j && u.j == t.i);
        if (u.shape != TermShape::kPower || !same_argument) continue;
        const bool listed = std::any_of(out.begin(), out.end(),
                                        [&](const Addition& o) { return o.terms == ad.terms; });
        if (!listed) {
          out.push_back(ad);
          out.back().kappas.assign(ad.terms.size(), ad.kappa);
        }
        break;
      }
    }
    return out;
  }

  // 0 for powers, 1 for sin/cos, 2 for exp: the order in which a physicist would try them.
  int family_rank(const Addition& ad) const {
    const LibraryTerm& t = pool_[static_cast<std::size_t>(ad.terms.front())];
    if (ad.joint) return 0;  // a joint batch is of one family, kept as soon as it earns
    return t.shape == TermShape::kPower ? 0 : t.shape == TermShape::kExp ? 2 : 1;
  }

  // Whether an addition with held-out loss `vy` is preferred to the best so far (`vb`): the
  // lower loss, whatever the families; on an exact tie the simpler family (lower rank).
  static bool preferred(double vy, int fy, double vb, int fb) {
    return vy < vb || (vy == vb && fy < fb);
  }

  // Each active pool term's t-ratio (coefficient over its sandwich standard error); empty when
  // interrupted.
  std::vector<double> t_ratios(const Candidate& x, NormalEquations& ne) const {
    const HamiltonianLibraryMap& map = library_of(x);
    const WindowSet& train = split_->train;
    const double sc = 1.0 / std::sqrt(static_cast<double>(train.size()));
    ne = normal_equations_over_ranks(
        map, x.theta, train, balanced_, sc, true, [this] { return fit_->stop_requested(); }, comm_);
    if (ne.stopped) return {};
    std::vector<double> t_of(pool_.size(), 0.0);
    for (Index k = 0; k < static_cast<Index>(map.terms().size()); ++k) {
      Vector grad = Vector::Zero(map.n_params());
      grad(map.coefficient_index(k)) = 1.0;
      const SandwichInterval iv =
          sandwich_interval_of(ne.a, ne.g, ne.scores, grad, x.theta(map.coefficient_index(k)),
                               train.size() * train.dim(), ne.cost, sc, 0.0, 0.95);
      const double t = iv.std_error > 0.0 ? std::abs(iv.gamma) / iv.std_error : 1e300;
      for (std::size_t q = 0; q < pool_.size(); ++q)
        if (pool_[q] == map.terms()[static_cast<std::size_t>(k)]) t_of[q] = t;
    }
    return t_of;
  }

  // A drop's LM starts where the Gauss–Newton model of x's fit puts the rest with the dropped
  // terms' parameters at 0 (the other coefficients take over what the dropped ones carried):
  // gauss_newton_with_zeros, D the dropped terms' coefficients and the wavenumbers only they
  // use, A and g x's normal equations (those of its t-ratios). y (x without the terms) takes
  // that start when its training loss is the lower; returns whether it did. Without it the LM
  // starts from x's values as they are and spends its iterations walking the others over.
  bool start_projected(Candidate& x, const std::vector<Index>& dropped_pool,
                       const NormalEquations& ne, Candidate& y) {
    const HamiltonianLibraryMap& map = library_of(x);
    const Index n = map.n_params();
    if (ne.a.rows() != n || ne.g.size() != n || fit_->stop_requested()) return false;
    std::vector<char> drop(static_cast<std::size_t>(n), 0);
    std::vector<char> kept_wavenumber(static_cast<std::size_t>(n), 0);
    for (Index k = 0; k < static_cast<Index>(map.terms().size()); ++k) {
      const LibraryTerm& term = map.terms()[static_cast<std::size_t>(k)];
      bool dropped = false;
      for (Index q : dropped_pool) dropped = dropped || pool_[static_cast<std::size_t>(q)] == term;
      if (dropped) drop[static_cast<std::size_t>(map.coefficient_index(k))] = 1;
      if (!dropped && map.wavenumber_index(k) >= 0)
        kept_wavenumber[static_cast<std::size_t>(map.wavenumber_index(k))] = 1;
    }
    for (Index k = 0; k < static_cast<Index>(map.terms().size()); ++k) {
      const Index w = map.wavenumber_index(k);
      if (w >= 0 && !kept_wavenumber[static_cast<std::size_t>(w)] &&
          drop[static_cast<std::size_t>(map.coefficient_index(k))])
        drop[static_cast<std::size_t>(w)] = 1;
    }
    std::vector<Index> gone;
    for (Index j = 0; j < n; ++j)
      if (drop[static_cast<std::size_t>(j)]) gone.push_back(j);
    Vector start = gauss_newton_with_zeros(ne, x.theta, gone);
    if (start.size() != n) return false;
    std::swap(x.theta, start);
    Candidate p = make(active_terms(), library_of(x).substeps(), &x);
    std::swap(x.theta, start);
    const double plain = fit_->loss(y, split_->train), moved = fit_->loss(p, split_->train);
    if (!(moved < plain)) return false;
    y = std::move(p);
    return true;
  }

  // A drop to try: its terms (pool indices), their largest t-ratio, whether it is the joint
  // drop of terms below t = 2 (and then their joint Wald statistic, and the blocks its
  // covariance was estimated from).
  struct Drop {
    double t = 0.0;
    std::vector<Index> terms;
    bool joint = false;
    double wald = 0.0;
    Index blocks = 0;
  };

  // How many of `weak` (active pool terms, the least significant first) are negligible
  // together, and their joint Wald statistic (negligible_together at x's fit: the sandwich
  // covariance against χ²'s 95% point); 0 when none is. Terms each below t = 2 can be needed
  // together: on a pendulum's differenced momenta q, sin q, cos q and exp(−q) each had t ≈ 0,
  // dropped together the held-out loss rose 5%, inside a short record's keep threshold, and the
  // cosine was lost. χ²'s point, stricter than the test's level with few blocks, is chosen on
  // purpose: against Hotelling's (16.3 for those 4 terms over 16 blocks) their statistic, 12.7,
  // let them go again; a refused drop costs refits, a wrong one the force law.
  JointWald jointly_negligible(const Candidate& x, const NormalEquations& ne,
                               const std::vector<Index>& weak) const {
    const HamiltonianLibraryMap& map = library_of(x);
    const Index np = map.n_params();
    if (weak.size() < 2 || ne.a.rows() != np || ne.scores.rows() != np) return {};
    std::vector<Index> at;  // θ's index of each weak term's coefficient
    for (Index q : weak)
      for (Index k = 0; k < static_cast<Index>(map.terms().size()); ++k)
        if (map.terms()[static_cast<std::size_t>(k)] == pool_[static_cast<std::size_t>(q)])
          at.push_back(map.coefficient_index(k));
    if (at.size() != weak.size()) return {};
    return negligible_together(ne.a, ne.scores, x.theta, at, 0.95, WaldReference::kChiSquare);
  }

  // The drops to try: the two least significant groups, then the terms below t = 2 together
  // (the least significant of them that are negligible together, at most `joint_cap`, when
  // more than one), then the least significant term below t = 2 alone.
  std::vector<Drop> drops(const Candidate& x, const NormalEquations& ne,
                          const std::vector<double>& t_of, std::size_t joint_cap) const {
    std::vector<Drop> out;
    const std::size_t n_active = active_terms().size();
    for (const std::vector<Index>& g : term_groups(pool_)) {
      std::vector<Index> on;
      double t = 0.0;
      for (Index k : g)
        if (active_[static_cast<std::size_t>(k)]) {
          on.push_back(k);
          t = std::max(t, t_of[static_cast<std::size_t>(k)]);
        }
      if (!on.empty() && on.size() < n_active) out.push_back({t, on, false, 0.0});
    }
    std::stable_sort(out.begin(), out.end(),
                     [](const Drop& u, const Drop& v) { return u.t < v.t; });
    if (out.size() > 2) out.resize(2);
    std::vector<Index> weak;  // the active terms below t = 2, the least significant first
    for (std::size_t q = 0; q < pool_.size(); ++q)
      if (active_[q] && t_of[q] < 2.0) weak.push_back(static_cast<Index>(q));
    std::stable_sort(weak.begin(), weak.end(), [&t_of](Index u, Index v) {
      return t_of[static_cast<std::size_t>(u)] < t_of[static_cast<std::size_t>(v)];
    });
    if (weak.empty()) return out;
    std::vector<Index> candidates(
        weak.begin(), weak.begin() + static_cast<std::ptrdiff_t>(
                                         std::min({weak.size(), joint_cap, n_active - 1})));
    const JointWald together = jointly_negligible(x, ne, candidates);
    if (together.count >= 2) {
      std::vector<Index> terms(weak.begin(), weak.begin() + together.count);
      const double t = t_of[static_cast<std::size_t>(terms.back())];
      std::sort(terms.begin(), terms.end());
      out.push_back({t, std::move(terms), true, together.statistic, ne.scores.cols()});
    }
    out.push_back({t_of[static_cast<std::size_t>(weak.front())], {weak.front()}, false, 0.0, 0});
    return out;
  }

  CandidateFit* fit_;
  const BlockSplit* split_;
  Index d_;
  double beta_init_;
  bool balanced_;
  const Communicator& comm_;
  nlohmann::json& rec_;
  Vector scales_;
  double threshold_ = 0.0, floor_ = 0.0;
  std::vector<LibraryTerm> pool_;
  std::vector<bool> active_;
  bool given_terms_ = false;
  bool given_dissipation_ = false;
  std::vector<DissipationTerm> dissipation_;  // the terms of every candidate made
};

// At most `cap` of `w`'s windows, evenly spread over it (all of them when it has no more).
WindowSet evenly_spread(const WindowSet& w, Index cap) {
  const Index n = w.size();
  if (n <= cap) return w;
  std::vector<Index> pick;
  pick.reserve(static_cast<std::size_t>(cap));
  for (Index j = 0; j < cap; ++j) pick.push_back(j * n / cap);
  return select_windows(w, pick);
}

}  // namespace

BlockSplit selection_split(const BlockSplit& split, Index cap) {
  BlockSplit out = split;
  out.train = evenly_spread(split.train, cap);
  out.val = evenly_spread(split.val, cap);
  return out;
}

LibraryFit fit_library(CandidateFit& fit, const nlohmann::json& given_core, Index d,
                       double beta_init, const Normalization& units, bool balanced,
                       const Communicator& comm, const std::string& dissipation, bool start_only) {
  const auto t0 = std::chrono::steady_clock::now();
  LibraryFit out;
  const BlockSplit& all = fit.split();
  const bool thinned = all.train.size() > kSelectionWindows || all.val.size() > kSelectionWindows;
  const BlockSplit thin = thinned ? selection_split(all, kSelectionWindows) : BlockSplit{};
  CandidateFit thin_fit = fit.on(thin);
  LibrarySelection sel(thinned ? thin_fit : fit, given_core, d, beta_init, units, balanced, comm,
                       out.record);
  if (thinned)
    out.record["selection_windows"] = {
        {"windows", thin.train.size()},
        {"of", all.train.size()},
        {"held_out", thin.val.size()},
        {"held_out_of", all.val.size()},
        {"why", "the terms were chosen on " + std::to_string(thin.train.size()) + " of " +
                    std::to_string(all.train.size()) + " training windows and " +
                    std::to_string(thin.val.size()) + " of " + std::to_string(all.val.size()) +
                    " held-out windows, evenly spread over the record; " +
                    (start_only ? "the final fit too, as a start: a later fit of the record "
                                  "refits theta"
                                : "the final fit was made on all")},
        {"final_fit_on_these", start_only}};
  Candidate x = sel.start();
  // The stages in turn; a stop request ends the selection between them (each stage's LM ends
  // at once, but its rankings, checks and integrator comparison run on): the candidate as it
  // stands, which the caller reports as stopped.
  const std::function<void()> stages[] = {
      [&] { sel.dissipation(x, dissipation, "after the start"); },
      [&] { sel.forward(x); },
      [&] { sel.backward(x); },
      [&] { sel.prune_dissipation(x, dissipation); },
      [&] { sel.dissipation(x, dissipation, "after the potential's terms"); },
      [&] {
        if (!start_only) sel.use(fit);
        if (thinned && !start_only) x.val_loss = fit.loss(x, all.val);
        sel.finish(x);
        if (thinned && start_only) {
          x.val_loss = fit.loss(x, all.val);
          out.record["val_loss"] = x.val_loss;
          out.thinned = true;
        }
      }};
  for (const std::function<void()>& stage : stages) {
    if (fit.stop_requested()) {
      fit.note_stop();
      out.record["stopped"] = "a stop was requested: the selection ended here";
      break;
    }
    stage();
  }
  out.record["seconds"] =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.cand = std::move(x);
  return out;
}

bool at_noise_floor(const Candidate& x, const BlockSplit& split, bool balanced, std::string& why) {
  const WindowSet& val = split.val;
  const Vector res = window_residuals(*x.inner.map, x.theta, val, balanced);
  const double rel = relative_residual(res, val);
  const double rho = lag_one_correlation(res, val);
  if (rel <= kCleanRelativeResidual) {
    why = "the library core predicts the held-out windows to a relative residual of " +
          significant(rel, 3) + " (clean data explained): the neural cores were not trained";
    return true;
  }
  // Noise at the ends of a window does not grow with its length; a misfit does (about
  // twice the residual over two steps): both must say noise.
  double growth = std::numeric_limits<double>::infinity();
  try {
    const WindowSet two = windows_from_trajectories(split.val_blocks, 2);
    const Vector r2 = window_residuals(*x.inner.map, x.theta, two, balanced);
    if (res.size() > 0 && r2.size() > 0)
      growth = (r2.squaredNorm() / static_cast<double>(r2.size())) /
               (res.squaredNorm() / static_cast<double>(res.size()));
  } catch (const Error&) {
    // no block has two steps: the rule does not apply
  }
  if (val.m == 1 && rho < -0.25 && growth < 1.5) {
    why = "the library core's held-out one-step residuals are noise (lag-one correlation " +
          significant(rho, 3) + ", pure measurement noise gives -0.5; two-step residuals " +
          significant(growth, 3) + " times the one-step ones in mean square, a misfit gives " +
          "about 4): the neural cores were not trained";
    return true;
  }
  why = "the library core leaves structure in the held-out residuals (relative residual " +
        significant(rel, 3) + ", lag-one correlation " + significant(rho, 3) +
        ", two-step over one-step mean square " + significant(growth, 3) +
        "): the neural cores were trained too";
  return false;
}

}  // namespace csympnet::detail
