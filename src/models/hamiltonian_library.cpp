#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/core/dense.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <set>
#include <tuple>
#include <utility>

#include <Eigen/Cholesky>

#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"
#include "library_map_detail.hpp"
#include "shape_checks.hpp"

namespace csympnet {

namespace {

// Yoshida's triple jump applied to a symmetric method of order 2k gives one of order 2k + 2:
// stages x1, x0, x1 with x1 = 1/(2 − 2^{1/(2k+1)}), x0 = 1 − 2 x1.
std::vector<double> composition_weights(int order) {
  std::vector<double> w = {1.0};
  for (int k = 1; 2 * k < order; ++k) {
    const double x1 = 1.0 / (2.0 - std::pow(2.0, 1.0 / (2.0 * k + 1.0)));
    const double x0 = 1.0 - 2.0 * x1;
    std::vector<double> next;
    for (double x : {x1, x0, x1})
      for (double b : w) next.push_back(x * b);
    w = std::move(next);
  }
  return w;
}

using library_detail::abs_derivative;
using library_detail::kStagesPerPoll;

void poll_within_step(Index stage) {
  if (stage % kStagesPerPoll == kStagesPerPoll - 1)
    throw_if_stop_requested("hamiltonian library: a step of many substeps");
}

// A term as an ordered key (LibraryTerm has only ==).
using TermKey = std::tuple<Index, Index, int, int, double>;
TermKey key_of(const LibraryTerm& t) {
  return {t.i, t.j, static_cast<int>(t.shape), t.power, t.kappa_sign};
}

}  // namespace

HamiltonianLibraryMap::HamiltonianLibraryMap(Index d, std::vector<LibraryTerm> terms, int order,
                                             Index substeps, bool full_mass, double beta_init,
                                             Vector scales,
                                             std::vector<DissipationTerm> dissipation,
                                             InputSpec inputs, bool coulomb_in_kicks)
    : d_(d),
      terms_(std::move(terms)),
      order_(order),
      substeps_(substeps),
      full_mass_(full_mass),
      beta_init_(beta_init),
      dissipation_(std::move(dissipation)),
      coulomb_in_kicks_(coulomb_in_kicks),
      inputs_(inputs) {
  require(d >= 1, "hamiltonian library: d must be >= 1");
  require(!terms_.empty(), "hamiltonian library: at least one term is needed");
  require(order == 2 || order == 4 || order == 6, [&] {
    return "hamiltonian library: order " + std::to_string(order) + ", expected 2, 4 or 6";
  });
  require(substeps >= 1, "hamiltonian library: substeps must be >= 1");
  require(std::isfinite(beta_init) && beta_init != 0.0,
          "hamiltonian library: beta_init must be finite and nonzero");
  Index next = mass_size() + static_cast<Index>(terms_.size());
  // Repeats and shared wavenumbers by lookup, not by a search of the terms before: a file's
  // 141,000 terms took 13-31 s to load that way.
  std::set<TermKey> seen;
  std::map<std::pair<Index, Index>, Index> sinusoid_kappa;  // (i, j) of a sin or cos: its κ
  for (std::size_t k = 0; k < terms_.size(); ++k) {
    if (k % 4096 == 4095) throw_if_stop_requested("hamiltonian library: building the terms");
    const LibraryTerm& t = terms_[k];
    require(t.i >= 0 && t.i < d && t.j < d && t.j != t.i, [&] {
      return "hamiltonian library: term " + std::to_string(k) + " has a coordinate out of range";
    });
    require(seen.insert(key_of(t)).second,
            [&] { return "hamiltonian library: term '" + term_name(t) + "' appears twice"; });
    // sin and cos of one argument share their wavenumber: together they are a sinusoid of
    // any phase.
    Index kappa = -1;
    if (t.shape == TermShape::kSin || t.shape == TermShape::kCos) {
      const auto [at, added] = sinusoid_kappa.try_emplace({t.i, t.j}, next);
      kappa = at->second;
      if (added) ++next;
    } else if (t.has_wavenumber()) {
      kappa = next++;
    }
    kappa_index_.push_back(kappa);
  }
  beta_index_ = next;
  weights_ = composition_weights(order);
  scales_ = scales.size() == 0 ? Vector::Ones(d) : std::move(scales);
  require(scales_.size() == d && scales_.allFinite() && (scales_.array() > 0.0).all(), [&] {
    return "hamiltonian library: coordinate_scales must be " + std::to_string(d) +
           " positive finite numbers";
  });
  std::map<std::pair<Index, Index>, Index> group_at;  // (i, j) of an argument: its group
  for (const LibraryTerm& t : terms_) {
    wi_.push_back(t.j < 0 ? 1.0 : scales_(t.i));
    wj_.push_back(t.j < 0 ? 0.0 : scales_(t.j));
    const auto [at, added] = group_at.try_emplace({t.i, t.j}, static_cast<Index>(groups_.size()));
    if (added) groups_.push_back({t.i, t.j, wi_.back(), wj_.back()});
    group_of_.push_back(at->second);
  }
  require(inputs_.m >= 0, "hamiltonian library: the number of inputs must be >= 0");
  double within = 0.0;
  for (double w : weights_) {
    within += w;
    within_.push_back(within);
  }
  coulomb_of_.assign(static_cast<std::size_t>(d), -1);
  for (std::size_t k = 0; k < dissipation_.size(); ++k) {
    const DissipationTerm& t = dissipation_[k];
    require(t.i >= 0 && t.i < d, [&] {
      return "hamiltonian library: dissipation term " + std::to_string(k) +
             " has a coordinate out of range";
    });
    for (std::size_t l = 0; l < k; ++l)
      require(!(dissipation_[l] == t), [&] {
        return "hamiltonian library: dissipation term '" + dissipation_name(t) + "' appears twice";
      });
    if (t.kind == DissipationKind::kCoulomb && coulomb_in_kicks_)
      coulomb_of_[static_cast<std::size_t>(t.i)] = static_cast<Index>(k);
  }
}

double HamiltonianLibraryMap::sigma(Index s) const {
  const Index nw = static_cast<Index>(weights_.size());
  if (s <= 0) return 0.0;
  if (s >= substeps_ * nw) return 1.0;
  const Index i = (s - 1) / nw, j = (s - 1) % nw;
  return (static_cast<double>(i) + within_[static_cast<std::size_t>(j)]) /
         static_cast<double>(substeps_);
}

void HamiltonianLibraryMap::dissipate(ConstParams theta, double half_tau, bool closing, double* p,
                                      double* starts) const {
  const Index nk = static_cast<Index>(dissipation_.size());
  for (Index n = 0; n < nk; ++n) {
    const Index k = closing ? nk - 1 - n : n;
    const DissipationTerm& t = dissipation_[static_cast<std::size_t>(k)];
    if (starts != nullptr) starts[n] = p[t.i];
    if (in_kicks(k)) continue;
    p[t.i] = dissipation_flow(t.kind, p[t.i], std::abs(theta(dissipation_index(k))), half_tau).p;
  }
}

void HamiltonianLibraryMap::dissipate_backward(ConstParams theta, double half_tau, bool closing,
                                               const double* starts, double* pb,
                                               ParamsRef grad) const {
  const Index nk = static_cast<Index>(dissipation_.size());
  for (Index n = nk - 1; n >= 0; --n) {
    const Index k = closing ? nk - 1 - n : n;
    const DissipationTerm& t = dissipation_[static_cast<std::size_t>(k)];
    if (in_kicks(k)) continue;
    const double th = theta(dissipation_index(k));
    const FlowStep f = dissipation_flow(t.kind, starts[n], std::abs(th), half_tau);
    grad(dissipation_index(k)) += abs_derivative(th) * f.drate * pb[t.i];
    pb[t.i] *= f.dp;
  }
}

void HamiltonianLibraryMap::init_params(Rng& /*rng*/, ParamsRef theta) const {
  require(theta.size() == n_params(), "hamiltonian library: init_params: wrong size");
  theta.setZero();
  for (Index i = 0; i < d_; ++i) theta(full_mass_ ? i * (i + 1) / 2 + i : i) = 1.0;
  for (std::size_t k = 0; k < terms_.size(); ++k) {
    const LibraryTerm& t = terms_[k];
    const Index ki = static_cast<Index>(k);
    if (t.shape == TermShape::kPower && t.j < 0 && t.power == 2) theta(coefficient_index(ki)) = 0.5;
    if (t.has_wavenumber()) theta(wavenumber_index(ki)) = t.kappa_sign;
  }
  theta(beta_index_) = beta_init_;
  for (Index k = 0; k < static_cast<Index>(dissipation_.size()); ++k)
    theta(dissipation_index(k)) = kDissipationInit;
}

Matrix HamiltonianLibraryMap::input_matrix(ConstParams theta) const {
  Matrix b(d_, inputs_.m);
  for (Index r = 0; r < d_; ++r)
    for (Index j = 0; j < inputs_.m; ++j) b(r, j) = theta(input_index(r, j));
  return b;
}

void HamiltonianLibraryMap::add_force(ConstParams theta, const double* u, double sigma, double* g,
                                      double* work) const {
  input_at(inputs_.hold, inputs_.m, u, sigma, work);
  for (Index r = 0; r < d_; ++r) {
    double f = 0.0;
    for (Index j = 0; j < inputs_.m; ++j) f += theta(input_index(r, j)) * work[j];
    g[r] -= f;
  }
}

void HamiltonianLibraryMap::add_input_gradient(const double* u, double sigma, const double* v,
                                               double s, double* work, ParamsRef grad) const {
  input_at(inputs_.hold, inputs_.m, u, sigma, work);
  for (Index r = 0; r < d_; ++r)
    for (Index j = 0; j < inputs_.m; ++j) grad(input_index(r, j)) += s * v[r] * work[j];
}

void HamiltonianLibraryMap::check_inputs(const Matrix& U, Index n) const {
  if (U.rows() == 0) return;
  require(inputs_.m > 0, [&] {
    return "hamiltonian library forward: this map takes no inputs (U has " +
           std::to_string(U.rows()) +
           " rows); expected a core with \"inputs\": {\"m\": ...} for a driven record";
  });
  require(U.rows() == 2 * inputs_.m && U.cols() == n, [&] {
    return "hamiltonian library: inputs of " + std::to_string(U.rows()) + " x " +
           std::to_string(U.cols()) + " for a map of " + std::to_string(inputs_.m) +
           " inputs and " + std::to_string(n) + " steps; expected " +
           std::to_string(2 * inputs_.m) + " x " + std::to_string(n) +
           " (per step the input at its start, then at its end)";
  });
}

Matrix HamiltonianLibraryMap::inverse_mass(ConstParams theta) const {
  Matrix w = Matrix::Zero(d_, d_);
  for (Index r = 0; r < d_; ++r) {
    if (!full_mass_) {
      w(r, r) = theta(r);
      continue;
    }
    for (Index c = 0; c <= r; ++c) w(r, c) = w(c, r) = theta(r * (r + 1) / 2 + c);
  }
  return w;
}

void HamiltonianLibraryMap::check_inverse_mass(ConstParams theta, const std::string& where) const {
  check_theta(*this, theta, "check_inverse_mass");
  const auto mass_kind = [&] {
    return std::string(" (the inverse mass W = M^-1 of core 'mass': \"") +
           (full_mass_ ? "full" : "diagonal") + "\")";
  };
  for (Index r = 0; r < d_; ++r) {
    const Index k = full_mass_ ? r * (r + 1) / 2 + r : r;
    require(theta(k) > 0.0, [&] {
      char value[32];
      std::snprintf(value, sizeof value, "%.17g", theta(k));
      return where + ": params[" + std::to_string(k) + "] = " + value + " is W[" +
             std::to_string(r + 1) + "," + std::to_string(r + 1) + "]" + mass_kind() +
             "; expected a positive inverse mass (a positive kinetic energy)";
    });
  }
  if (!full_mass_ || d_ == 1) return;
  require(dense::Llt(inverse_mass(theta)).ok(), [&] {
    return where + ": params[0.." + std::to_string(mass_size() - 1) + "]" + mass_kind() +
           " are not positive definite; expected a positive-definite inverse mass (a positive "
           "kinetic energy 1/2 p^T W p for every p != 0)";
  });
}

void HamiltonianLibraryMap::mass_times(ConstParams theta, const double* x, double* out) const {
  if (!full_mass_) {
    for (Index r = 0; r < d_; ++r) out[r] = theta(r) * x[r];
    return;
  }
  for (Index r = 0; r < d_; ++r) out[r] = 0.0;
  for (Index r = 0; r < d_; ++r)
    for (Index c = 0; c <= r; ++c) {
      const double w = theta(r * (r + 1) / 2 + c);
      out[r] += w * x[c];
      if (c != r) out[c] += w * x[r];
    }
}

double HamiltonianLibraryMap::argument(Index k, const double* q) const {
  const LibraryTerm& t = terms_[static_cast<std::size_t>(k)];
  const auto kk = static_cast<std::size_t>(k);
  return t.j < 0 ? q[t.i] : wi_[kk] * q[t.i] - wj_[kk] * q[t.j];
}

double HamiltonianLibraryMap::potential(ConstParams theta, const double* q) const {
  double v = 0.0;
  for (std::size_t k = 0; k < terms_.size(); ++k) {
    const LibraryTerm& t = terms_[k];
    const Index ki = static_cast<Index>(k);
    const double kappa = t.has_wavenumber() ? theta(wavenumber_index(ki)) : 0.0;
    v += theta(coefficient_index(ki)) * term_values(t, argument(ki, q), kappa).phi;
  }
  return v;
}

void HamiltonianLibraryMap::gradient(ConstParams theta, const double* q, double* g) const {
  for (Index r = 0; r < d_; ++r) g[r] = 0.0;
  for (std::size_t k = 0; k < terms_.size(); ++k) {
    const LibraryTerm& t = terms_[k];
    const Index ki = static_cast<Index>(k);
    const double kappa = t.has_wavenumber() ? theta(wavenumber_index(ki)) : 0.0;
    const double f = theta(coefficient_index(ki)) * term_values(t, argument(ki, q), kappa).d1;
    g[t.i] += wi_[k] * f;
    if (t.j >= 0) g[t.j] -= wj_[k] * f;
  }
}

void HamiltonianLibraryMap::hessian_times(ConstParams theta, const double* q, const double* v,
                                          double* out) const {
  for (std::size_t k = 0; k < terms_.size(); ++k) {
    const LibraryTerm& t = terms_[k];
    const Index ki = static_cast<Index>(k);
    const double kappa = t.has_wavenumber() ? theta(wavenumber_index(ki)) : 0.0;
    const double ev = t.j < 0 ? v[t.i] : wi_[k] * v[t.i] - wj_[k] * v[t.j];
    const double f = theta(coefficient_index(ki)) * term_values(t, argument(ki, q), kappa).d2 * ev;
    out[t.i] += wi_[k] * f;
    if (t.j >= 0) out[t.j] -= wj_[k] * f;
  }
}

void HamiltonianLibraryMap::add_gradient_params(ConstParams theta, const double* q, const double* v,
                                                double s, ParamsRef grad) const {
  for (std::size_t k = 0; k < terms_.size(); ++k) {
    const LibraryTerm& t = terms_[k];
    const Index ki = static_cast<Index>(k);
    const double ev = t.j < 0 ? v[t.i] : wi_[k] * v[t.i] - wj_[k] * v[t.j];
    if (ev == 0.0) continue;
    const double kappa = t.has_wavenumber() ? theta(wavenumber_index(ki)) : 0.0;
    const TermValues tv = term_values(t, argument(ki, q), kappa);
    grad(coefficient_index(ki)) += s * tv.d1 * ev;
    if (t.has_wavenumber())
      grad(wavenumber_index(ki)) += s * theta(coefficient_index(ki)) * tv.d1_kappa * ev;
  }
}

std::optional<double> HamiltonianLibraryMap::damping_rate(ConstParams theta) const {
  return std::abs(theta(beta_index_));
}

Matrix HamiltonianLibraryMap::forward(ConstParams theta, const Matrix& Z, const Vector& h,
                                      ForwardCache* cache) const {
  return forward_driven(theta, Z, h, Matrix(), cache);
}

Matrix HamiltonianLibraryMap::forward_driven(ConstParams theta, const Matrix& Z, const Vector& h,
                                             const Matrix& U, ForwardCache* cache) const {
  check_forward_args(*this, theta, Z, h);
  check_inputs(U, Z.cols());
  const bool driven = U.rows() > 0;
  const Index n = Z.cols(), d = d_, stages = stages_per_step(), rs = record_size();
  const Index nk = static_cast<Index>(dissipation_.size());
  const double gamma = std::abs(theta(beta_index_));
  Context* ctx = nullptr;
  if (cache != nullptr) {
    ctx = &cache->make_context<Context>();
    ctx->h = h;
    ctx->u = U;
    ctx->states.resize(static_cast<std::size_t>(n * (stages + 1) * rs));
  }
  Matrix out(2 * d, n);
  std::vector<double> q(d), p(d), g(d), wp(d), work(static_cast<std::size_t>(inputs_.m));
  const Index nw = static_cast<Index>(weights_.size());
  // The momentum scalings e^{−γτ/2} of the stage weights at the current column's h: a record's
  // steps are mostly equal, and each stage would otherwise take an exp() (same expression, so
  // the same bits).
  std::vector<double> scaling(static_cast<std::size_t>(nw));
  double scaling_h = std::numeric_limits<double>::quiet_NaN();
  for (Index col = 0; col < n; ++col) {
    if (!(h(col) == scaling_h)) {
      for (Index s = 0; s < nw; ++s)
        scaling[static_cast<std::size_t>(s)] = std::exp(
            -0.5 * gamma *
            (weights_[static_cast<std::size_t>(s)] * h(col) / static_cast<double>(substeps_)));
      scaling_h = h(col);
    }
    for (Index r = 0; r < d; ++r) {
      q[r] = Z(r, col);
      p[r] = Z(d + r, col);
    }
    const double* ucol = driven ? U.col(col).data() : nullptr;
    gradient(theta, q.data(), g.data());
    if (driven) add_force(theta, ucol, sigma(0), g.data(), work.data());
    double* rec = ctx != nullptr ? ctx->states.data() + col * (stages + 1) * rs : nullptr;
    for (Index s = 0; s <= stages; ++s) {
      const double tau = s == stages ? 0.0
                                     : weights_[static_cast<std::size_t>(s % nw)] * h(col) /
                                           static_cast<double>(substeps_);
      double* starts = rec != nullptr ? rec + s * rs + 3 * d : nullptr;
      if (nk > 0 && s < stages) dissipate(theta, 0.5 * tau, false, p.data(), starts);
      if (rec != nullptr) {
        std::copy(q.begin(), q.end(), rec + s * rs);
        std::copy(p.begin(), p.end(), rec + s * rs + d);
        std::copy(g.begin(), g.end(), rec + s * rs + 2 * d);
      }
      if (s == stages) break;
      poll_within_step(s);
      const double a = scaling[static_cast<std::size_t>(s % nw)];
      for (Index r = 0; r < d; ++r) {
        const double mu = coulomb_rate(theta, r);
        p[r] =
            mu > 0.0 ? coulomb_kick(a * p[r], -g[r], mu, 0.5 * tau).p : a * p[r] - 0.5 * tau * g[r];
      }
      mass_times(theta, p.data(), wp.data());
      for (Index r = 0; r < d; ++r) q[r] += tau * wp[r];
      gradient(theta, q.data(), g.data());
      if (driven) add_force(theta, ucol, sigma(s + 1), g.data(), work.data());
      for (Index r = 0; r < d; ++r) {
        const double mu = coulomb_rate(theta, r);
        p[r] = mu > 0.0 ? a * coulomb_kick(p[r], -g[r], mu, 0.5 * tau).p
                        : a * (p[r] - 0.5 * tau * g[r]);
      }
      if (nk > 0)
        dissipate(theta, 0.5 * tau, true, p.data(), starts != nullptr ? starts + nk : nullptr);
    }
    for (Index r = 0; r < d; ++r) {
      out(r, col) = q[r];
      out(d + r, col) = p[r];
    }
  }
  return out;
}

void HamiltonianLibraryMap::kick_backward(ConstParams theta, const std::vector<KickStep>& kicks,
                                          bool fused, const double* q, double sigma,
                                          const double* ucol, double tau, double* pb, double* qb,
                                          KickScratch& w, ParamsRef grad) const {
  const Index d = d_;
  const double* plain = pb;
  if (fused) {
    // The coordinates with friction: their force's adjoint f̄ = ∂p/∂f · p̄ (ḡ = −f̄) and their
    // rate's, apart; the plain kick's path below sees them as 0.
    for (Index r = 0; r < d; ++r) {
      const KickStep& k = kicks[static_cast<std::size_t>(r)];
      const Index t = coulomb_of_[static_cast<std::size_t>(r)];
      if (t < 0 || coulomb_rate(theta, r) == 0.0) {
        w.plain[r] = pb[r];
        w.force[r] = 0.0;
        continue;
      }
      w.plain[r] = 0.0;
      w.force[r] = k.dforce * pb[r];
      const double th = theta(dissipation_index(t));
      grad(dissipation_index(t)) += abs_derivative(th) * k.drate * pb[r];
    }
    plain = w.plain.data();
  }
  const bool driven = ucol != nullptr;
  if (driven) add_input_gradient(ucol, sigma, plain, 0.5 * tau, w.work.data(), grad);
  add_gradient_params(theta, q, plain, -0.5 * tau, grad);
  for (Index r = 0; r < d; ++r) w.tmp[r] = 0.0;
  hessian_times(theta, q, plain, w.tmp.data());
  for (Index r = 0; r < d; ++r) qb[r] -= 0.5 * tau * w.tmp[r];
  if (!fused) return;
  if (driven) add_input_gradient(ucol, sigma, w.force.data(), 1.0, w.work.data(), grad);
  add_gradient_params(theta, q, w.force.data(), -1.0, grad);
  for (Index r = 0; r < d; ++r) w.tmp[r] = 0.0;
  hessian_times(theta, q, w.force.data(), w.tmp.data());
  for (Index r = 0; r < d; ++r) {
    qb[r] -= w.tmp[r];
    if (coulomb_of_[static_cast<std::size_t>(r)] >= 0 && coulomb_rate(theta, r) > 0.0)
      pb[r] *= kicks[static_cast<std::size_t>(r)].dp;
  }
}

void HamiltonianLibraryMap::backward(ConstParams theta, const ForwardCache& cache,
                                     const Matrix& dZout, ParamsRef grad, Matrix* dZin) const {
  const Context& ctx = cache.context<Context>("hamiltonian library backward");
  const Index n = ctx.h.size(), d = d_, stages = stages_per_step(), rs = record_size();
  const Index nk = static_cast<Index>(dissipation_.size());
  check_backward_args(*this, theta, n, dZout, grad);
  const double beta = theta(beta_index_), gamma = std::abs(beta);
  if (dZin != nullptr) dZin->resize(dim(), n);
  std::vector<double> qb(d), pb(d), p2(d), wq(d);
  std::vector<KickStep> k1(d), k2(d);
  KickScratch scratch(d, inputs_.m);
  const Index nw = static_cast<Index>(weights_.size());
  const bool driven = ctx.u.rows() > 0;
  double gamma_bar = 0.0;
  for (Index col = 0; col < n; ++col) {
    const double* ucol = driven ? ctx.u.col(col).data() : nullptr;
    for (Index r = 0; r < d; ++r) {
      qb[r] = dZout(r, col);
      pb[r] = dZout(d + r, col);
    }
    const double* rec = ctx.states.data() + col * (stages + 1) * rs;
    for (Index s = stages - 1; s >= 0; --s) {
      poll_within_step(s);
      const double* q0 = rec + s * rs;
      const double* p0 = q0 + d;
      const double* g0 = q0 + 2 * d;
      const double* starts = q0 + 3 * d;
      const double* q1 = rec + (s + 1) * rs;
      const double* g1 = q1 + 2 * d;
      const double tau =
          weights_[static_cast<std::size_t>(s % nw)] * ctx.h(col) / static_cast<double>(substeps_);
      const double a = std::exp(-0.5 * gamma * tau);
      if (nk > 0) dissipate_backward(theta, 0.5 * tau, true, starts + nk, pb.data(), grad);
      // p2 = a p0 − (τ/2) g0, p3 = p2 − (τ/2) g1, output p4 = a p3; on a coordinate with
      // Coulomb friction each kick is its exact flow with the friction (coulomb_kick).
      double a_bar = 0.0;
      bool fused = false;
      for (Index r = 0; r < d; ++r) {
        const double mu = coulomb_rate(theta, r);
        if (mu > 0.0) {
          k1[r] = coulomb_kick(a * p0[r], -g0[r], mu, 0.5 * tau);
          k2[r] = coulomb_kick(k1[r].p, -g1[r], mu, 0.5 * tau);
          p2[r] = k1[r].p;
          a_bar += pb[r] * k2[r].p;
          fused = true;
        } else {
          p2[r] = a * p0[r] - 0.5 * tau * g0[r];
          a_bar += pb[r] * (p2[r] - 0.5 * tau * g1[r]);
        }
        pb[r] *= a;  // now p̄3
      }
      // p3 = p2 − (τ/2)(∇V(q1) − B u(σ_{s+1})); p̄2 = p̄3 but through a friction kick.
      kick_backward(theta, k2, fused, q1, sigma(s + 1), ucol, tau, pb.data(), qb.data(), scratch,
                    grad);
      // q1 = q0 + τ W p2.
      mass_times(theta, qb.data(), wq.data());
      for (Index r = 0; r < d; ++r) pb[r] += tau * wq[r];
      if (full_mass_) {
        for (Index r = 0; r < d; ++r)
          for (Index c = 0; c <= r; ++c)
            grad(r * (r + 1) / 2 + c) +=
                tau * (c == r ? qb[r] * p2[r] : qb[r] * p2[c] + qb[c] * p2[r]);
      } else {
        for (Index r = 0; r < d; ++r) grad(r) += tau * qb[r] * p2[r];
      }
      // p2 = a p0 − (τ/2)(∇V(q0) − B u(σ_s)).
      kick_backward(theta, k1, fused, q0, sigma(s), ucol, tau, pb.data(), qb.data(), scratch, grad);
      for (Index r = 0; r < d; ++r) {
        a_bar += pb[r] * p0[r];
        pb[r] *= a;
      }
      gamma_bar += a_bar * a * (-0.5 * tau);
      if (nk > 0) dissipate_backward(theta, 0.5 * tau, false, starts, pb.data(), grad);
    }
    if (dZin != nullptr)
      for (Index r = 0; r < d; ++r) {
        (*dZin)(r, col) = qb[r];
        (*dZin)(d + r, col) = pb[r];
      }
  }
  grad(beta_index_) += abs_derivative(beta) * gamma_bar;
}

Matrix HamiltonianLibraryMap::jacobian(ConstParams theta, const Vector& z, double h) const {
  return jacobian_driven(theta, z, h, Vector());
}

Matrix HamiltonianLibraryMap::jacobian_driven(ConstParams theta, const Vector& z, double h,
                                              const Vector& u) const {
  check_theta(*this, theta, "jacobian");
  require(z.size() == dim(), "hamiltonian library jacobian: z has the wrong size");
  require(u.size() == 0 || (inputs_.m > 0 && u.size() == 2 * inputs_.m), [&] {
    return "hamiltonian library jacobian: " + std::to_string(u.size()) +
           " input values for a map of " + std::to_string(inputs_.m) + " inputs; expected " +
           std::to_string(2 * inputs_.m) + " (the input at the step's start, then at its end)";
  });
  const bool driven = u.size() > 0;
  std::vector<double> work(static_cast<std::size_t>(inputs_.m));
  const Index d = d_, stages = stages_per_step(), nw = static_cast<Index>(weights_.size());
  const Index nk = static_cast<Index>(dissipation_.size());
  const double gamma = std::abs(theta(beta_index_));
  std::vector<double> q(z.data(), z.data() + d), p(z.data() + d, z.data() + 2 * d), g(d), wp(d);
  std::vector<double> starts(static_cast<std::size_t>(nk));
  Matrix tq = Matrix::Zero(d, 2 * d), tp = Matrix::Zero(d, 2 * d);
  tq.leftCols(d).setIdentity();
  tp.rightCols(d).setIdentity();
  const Matrix w = inverse_mass(theta);
  std::vector<double> col(d), hv(d);
  // tp −= step H(q) tq; a row with Coulomb friction (kick[r] of its coulomb_kick) instead
  // tp_r ← ∂p/∂p tp_r − ∂p/∂f (H tq)_r, as f = −∇V.
  std::vector<KickStep> kick(d);
  std::vector<char> fused(d, 0);
  const auto kick_tangent = [&](double step) {
    for (Index c = 0; c < 2 * d; ++c) {
      for (Index r = 0; r < d; ++r) {
        col[r] = tq(r, c);
        hv[r] = 0.0;
      }
      hessian_times(theta, q.data(), col.data(), hv.data());
      for (Index r = 0; r < d; ++r)
        if (fused[r])
          tp(r, c) = kick[r].dp * tp(r, c) - kick[r].dforce * hv[r];
        else
          tp(r, c) -= step * hv[r];
    }
  };
  // The kick's friction flows from p (after the momentum scaling `scale`), at q's force g.
  const auto friction_kicks = [&](double scale, double half_tau) {
    for (Index r = 0; r < d; ++r) {
      const double mu = coulomb_rate(theta, r);
      fused[r] = mu > 0.0;
      if (fused[r]) kick[r] = coulomb_kick(scale * p[r], -g[r], mu, half_tau);
    }
  };
  // Each flow scales its momentum's row of the tangent by ∂p_new/∂p.
  const auto dissipate_tangent = [&](double half_tau, bool closing) {
    dissipate(theta, half_tau, closing, p.data(), starts.data());
    for (Index n = 0; n < nk; ++n) {
      const Index k = closing ? nk - 1 - n : n;
      const DissipationTerm& t = dissipation_[static_cast<std::size_t>(k)];
      if (in_kicks(k)) continue;
      tp.row(t.i) *= dissipation_flow(t.kind, starts[static_cast<std::size_t>(n)],
                                      std::abs(theta(dissipation_index(k))), half_tau)
                         .dp;
    }
  };
  gradient(theta, q.data(), g.data());
  if (driven) add_force(theta, u.data(), sigma(0), g.data(), work.data());
  for (Index s = 0; s < stages; ++s) {
    poll_within_step(s);
    const double tau =
        weights_[static_cast<std::size_t>(s % nw)] * h / static_cast<double>(substeps_);
    const double a = std::exp(-0.5 * gamma * tau);
    if (nk > 0) dissipate_tangent(0.5 * tau, false);
    friction_kicks(a, 0.5 * tau);
    tp *= a;
    kick_tangent(0.5 * tau);
    for (Index r = 0; r < d; ++r) p[r] = fused[r] ? kick[r].p : a * p[r] - 0.5 * tau * g[r];
    tq += tau * w * tp;
    mass_times(theta, p.data(), wp.data());
    for (Index r = 0; r < d; ++r) q[r] += tau * wp[r];
    gradient(theta, q.data(), g.data());
    if (driven) add_force(theta, u.data(), sigma(s + 1), g.data(), work.data());
    friction_kicks(1.0, 0.5 * tau);
    kick_tangent(0.5 * tau);
    tp *= a;
    for (Index r = 0; r < d; ++r) p[r] = fused[r] ? a * kick[r].p : a * (p[r] - 0.5 * tau * g[r]);
    if (nk > 0) dissipate_tangent(0.5 * tau, true);
  }
  Matrix jac(2 * d, 2 * d);
  jac.topRows(d) = tq;
  jac.bottomRows(d) = tp;
  return jac;
}

nlohmann::json HamiltonianLibraryMap::hyperparams() const {
  nlohmann::json names = nlohmann::json::array();
  for (const LibraryTerm& t : terms_) names.push_back(term_name(t));
  nlohmann::json core = {
      {"type", "library"},
      {"terms", names},
      {"order", order_},
      {"substeps", substeps_},
      {"mass", full_mass_ ? "full" : "diagonal"},
      {"coordinate_scales", std::vector<double>(scales_.data(), scales_.data() + d_)}};
  // Written only when present: a model without them keeps the spec (and file) it had before.
  set_dissipation_spec(core, dissipation_, coulomb_in_kicks_);
  if (inputs_.m > 0) core["inputs"] = input_spec_json(inputs_);
  return {{"type", "csympnet"}, {"d", d_}, {"core", core}, {"beta_init", beta_init_}};
}

void set_dissipation_spec(nlohmann::json& core, const std::vector<DissipationTerm>& terms,
                          bool coulomb_in_kicks) {
  core.erase("dissipation");
  core.erase("friction");
  if (terms.empty()) return;
  nlohmann::json names = nlohmann::json::array();
  for (const DissipationTerm& t : terms) names.push_back(dissipation_name(t));
  core["dissipation"] = names;
  if (std::any_of(terms.begin(), terms.end(),
                  [](const DissipationTerm& t) { return t.kind == DissipationKind::kCoulomb; }))
    core["friction"] = coulomb_in_kicks ? "in_kicks" : "split";
}

}  // namespace csympnet
