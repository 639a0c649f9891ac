// Forward-mode sensitivities of one step of the Hamiltonian-library map (models/
// hamiltonian_library.hpp; docs/derivations.md, "Forward-mode sensitivities").
//
// The step runs its stages as forward_driven() does, with the same expressions, so z ends with
// the same bits. Beside it a tangent block t = (t_q; t_p) (2d × c) is carried through each part
// of a stage, with ∂/∂θ_j added into column j < n_theta:
//
//   p ← a p − (τ/2) g(q):   t_p ← a t_p − (τ/2)(H(q) t_q + ∂g/∂θ);  t_p[:, β] += (∂a/∂β) p
//   q ← q + τ W p:          t_q ← t_q + τ W t_p;                    t_q[:, W_rc] += τ (∂W/∂W_rc) p
//   p ← a (p − (τ/2) g(q)): t_p ← a (t_p − (τ/2)(H(q) t_q + ∂g/∂θ)); t_p[:, β] += (∂a/∂β)(p − (τ/2)
//   g)
//
// with g = ∇V(q) − B u(t₀ + σh), H = ∇²V, a = e^{−γτ/2}, γ = |β|. ∂g/∂θ is nonzero in the
// columns of the coefficients (φ_k'), the wavenumbers (c_k ∂φ_k'/∂κ) and B (−u(σ)). The terms'
// values at q are computed once per position, not once per column. H(q) t_q takes one pass
// along the columns per argument (a coordinate or a difference), its terms' curvatures c_k φ_k''
// summed first: a chain's library has up to seven terms per argument.
//
// The block is carried row-major through the stages (copied in and out once per step): every
// update is a row of one state component against all columns, contiguous, so that the compiler
// runs it in SIMD packets (this file is compiled with gcc's "cheap" vectorisation cost model,
// CMakeLists.txt), each entry the same expression as a column at a time. Per step, not per
// stage: the stage lengths and scalings, the coefficients, wavenumbers and Coulomb rates. On a
// chain of 8 masses with momenta, a library fit took 0.72 of its CPU time column-major
// (docs/benchmarks.md, "A fit's cost against d"); the step itself is timed in "The library
// map's tangent step".
//
// Dissipation terms enter as in forward_driven(): a momentum with Coulomb friction inside the
// kicks takes its kick's exact flow (coulomb_kick: the tangent is ∂p/∂p times p's, plus ∂p/∂f
// times the force's, plus ∂p/∂μ in μ's column), and the flows beside the kicks (drag, and
// Coulomb in "split" files) scale their momentum's row by ∂p/∂p and add ∂p/∂r in their rate's
// column.
#include <algorithm>
#include <cmath>
#include <vector>

#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "library_map_detail.hpp"

namespace csympnet {

namespace {

// The work space of one step, kept per thread so that a step allocates nothing once its sizes
// have been seen.
struct TangentScratch {
  std::vector<double> q, p, g, wp, work, d1, d2, d1k, hv, gth, mass, coef, kappa, mu, curvature;
  // The tangent block row-major (2d rows of c): a row is one state component's sensitivity
  // to every column, so each stage's updates run along contiguous rows.
  std::vector<double> rows;
  std::vector<KickStep> kick;
  std::vector<char> fused;
  // The stage lengths τ = b_s h / n and momentum scalings a = e^{−γτ/2} of the stage weights,
  // for the (γ, h, order, substeps) they were computed at: a record's steps are mostly equal,
  // and each stage would otherwise take a division and an exp().
  std::vector<double> tau, scaling;
  double scaling_gamma = -1.0, scaling_h = -1.0;
  int scaling_order = 0;
  Index scaling_substeps = 0;
};

using library_detail::abs_derivative;
using library_detail::kStagesPerPoll;

// A block of columns of the tangents as one value (Eigen runs it in SIMD packets, each entry the
// same expression as alone).
constexpr Index kColumnBlock = 8;
using ColumnBlock = Eigen::Array<double, kColumnBlock, 1>;

void fit_to(std::vector<double>& v, Index n) {
  if (static_cast<Index>(v.size()) < n) v.resize(static_cast<std::size_t>(n));
}

}  // namespace

void HamiltonianLibraryMap::step_tangents(ConstParams theta, double h, const double* u, double* z,
                                          Matrix& t, Index n_theta) const {
  require(theta.size() == n_params(),
          "hamiltonian library step_tangents: theta has the wrong size");
  const Index d = d_, c = t.cols(), nt = static_cast<Index>(terms_.size());
  require(t.rows() == 2 * d && n_theta >= 0 && n_theta <= c && n_theta <= n_params(),
          "hamiltonian library step_tangents: expected t of 2d rows and n_theta <= its columns");
  require(u == nullptr || inputs_.m > 0,
          "hamiltonian library step_tangents: inputs given to a map that takes none");
  const bool driven = u != nullptr;
  const Index m = inputs_.m;
  thread_local TangentScratch w;
  for (auto* v : {&w.q, &w.p, &w.g, &w.wp, &w.mu}) fit_to(*v, d);
  if (static_cast<Index>(w.kick.size()) < d) {
    w.kick.resize(static_cast<std::size_t>(d));
    w.fused.resize(static_cast<std::size_t>(d));
  }
  for (auto* v : {&w.d1, &w.d2, &w.d1k, &w.coef, &w.kappa}) fit_to(*v, nt);
  fit_to(w.work, std::max<Index>(m, 1));
  fit_to(w.hv, d * c);
  fit_to(w.curvature, static_cast<Index>(groups_.size()));
  fit_to(w.gth, d * n_theta);
  fit_to(w.mass, d * d);
  fit_to(w.rows, 2 * d * c);
  // T(r, col) = t(r, col), row-major; copied back at the end.
  double* tr = w.rows.data();
  using RowBlock =
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;
  RowBlock(tr, 2 * d, c) = t;
  const auto row = [tr, c](Index r) { return tr + r * c; };
  double* q = w.q.data();
  double* p = w.p.data();
  double* g = w.g.data();
  for (Index r = 0; r < d; ++r) {
    q[r] = z[r];
    p[r] = z[d + r];
  }
  const double beta = theta(beta_index_), gamma = std::abs(beta);
  const bool beta_col = beta_index_ < n_theta;
  const Index stages = stages_per_step(), nw = static_cast<Index>(weights_.size());
  if (w.scaling_gamma != gamma || w.scaling_h != h || w.scaling_order != order_ ||
      w.scaling_substeps != substeps_) {
    w.tau.resize(static_cast<std::size_t>(nw));
    w.scaling.resize(static_cast<std::size_t>(nw));
    for (Index s = 0; s < nw; ++s) {
      const auto ss = static_cast<std::size_t>(s);
      w.tau[ss] = weights_[ss] * h / static_cast<double>(substeps_);
      w.scaling[ss] = std::exp(-0.5 * gamma * w.tau[ss]);
    }
    w.scaling_gamma = gamma;
    w.scaling_h = h;
    w.scaling_order = order_;
    w.scaling_substeps = substeps_;
  }
  // Per step: each term's coefficient and wavenumber, and each momentum's Coulomb rate (θ
  // alone decides them).
  for (Index k = 0; k < nt; ++k) {
    w.coef[k] = theta(coefficient_index(k));
    w.kappa[k] =
        terms_[static_cast<std::size_t>(k)].has_wavenumber() ? theta(wavenumber_index(k)) : 0.0;
  }
  bool any_fused = false;
  for (Index r = 0; r < d; ++r) {
    w.mu[r] = coulomb_rate(theta, r);
    w.fused[r] = w.mu[r] > 0.0;
    any_fused = any_fused || w.fused[r];
  }
  // W dense (row-major), and x ↦ W x with each row summed in column order from 0: the bits of
  // mass_times().
  double* mass = w.mass.data();
  for (Index r = 0; r < d; ++r)
    for (Index cc = 0; cc < d; ++cc) {
      const bool on = full_mass_ || r == cc;
      const Index at = full_mass_ ? (r >= cc ? r * (r + 1) / 2 + cc : cc * (cc + 1) / 2 + r) : r;
      mass[r * d + cc] = on ? theta(at) : 0.0;
    }
  const auto mass_apply = [&](const double* x, double* out) {
    if (!full_mass_) {
      for (Index r = 0; r < d; ++r) out[r] = mass[r * d + r] * x[r];
      return;
    }
    for (Index r = 0; r < d; ++r) {
      double sum = 0.0;
      for (Index cc = 0; cc < d; ++cc) sum += mass[r * d + cc] * x[cc];
      out[r] = sum;
    }
  };

  // The terms at q: φ', φ'' and ∂φ'/∂κ per term, g = ∇V(q) − B u(σ) as gradient() and
  // add_force() compute it, and ∂g/∂θ (d × n_theta, row-major) into w.gth.
  const auto at_position = [&](double sigma) {
    for (Index r = 0; r < d; ++r) g[r] = 0.0;
    for (Index k = 0; k < nt; ++k) {
      const LibraryTerm& term = terms_[static_cast<std::size_t>(k)];
      const auto kk = static_cast<std::size_t>(k);
      const double arg = term.j < 0 ? q[term.i] : wi_[kk] * q[term.i] - wj_[kk] * q[term.j];
      const TermValues tv = term_values(term, arg, w.kappa[k]);
      w.d1[k] = tv.d1;
      w.d2[k] = tv.d2;
      w.d1k[k] = tv.d1_kappa;
      const double f = w.coef[k] * tv.d1;
      g[term.i] += wi_[kk] * f;
      if (term.j >= 0) g[term.j] -= wj_[kk] * f;
    }
    if (driven) add_force(theta, u, sigma, g, w.work.data());
    if (n_theta == 0) return;
    double* gth = w.gth.data();
    std::fill(gth, gth + d * n_theta, 0.0);
    for (Index k = 0; k < nt; ++k) {
      const LibraryTerm& term = terms_[static_cast<std::size_t>(k)];
      const auto kk = static_cast<std::size_t>(k);
      const auto add = [&](Index col, double f) {
        if (col >= n_theta) return;
        gth[term.i * n_theta + col] += wi_[kk] * f;
        if (term.j >= 0) gth[term.j * n_theta + col] -= wj_[kk] * f;
      };
      add(coefficient_index(k), w.d1[k]);
      if (term.has_wavenumber()) add(wavenumber_index(k), w.coef[k] * w.d1k[k]);
    }
    if (driven) {
      input_at(inputs_.hold, m, u, sigma, w.work.data());
      for (Index r = 0; r < d; ++r)
        for (Index j = 0; j < m; ++j) {
          const Index col = input_index(r, j);
          if (col < n_theta) gth[r * n_theta + col] -= w.work[j];
        }
    }
  };
  // hv = H(q) t_q (d × c, row-major): per argument group g, its curvature s_g = Σ c_k φ_k'' over
  // the group's terms in their order, then one pass along the columns (each entry sums the
  // groups in their order).
  const Index ng = static_cast<Index>(groups_.size());
  const auto hessian_tangent = [&] {
    if (c == 0) return;
    double* hv = w.hv.data();
    std::fill(hv, hv + d * c, 0.0);
    double* curvature = w.curvature.data();
    std::fill(curvature, curvature + ng, 0.0);
    for (Index k = 0; k < nt; ++k)
      curvature[group_of_[static_cast<std::size_t>(k)]] += w.coef[k] * w.d2[k];
    for (Index gi = 0; gi < ng; ++gi) {
      const ArgumentGroup& group = groups_[static_cast<std::size_t>(gi)];
      const double s2 = curvature[gi];
      if (s2 == 0.0) continue;
      const double wi = group.wi, wj = group.wj;
      const double* ti = row(group.i);
      double* hi = hv + group.i * c;
      if (group.j < 0) {
        for (Index col = 0; col < c; ++col) hi[col] += wi * (s2 * ti[col]);
        continue;
      }
      const double* tj = row(group.j);
      double* hj = hv + group.j * c;
      for (Index col = 0; col < c; ++col) {
        const double f = s2 * (wi * ti[col] - wj * tj[col]);
        hi[col] += wi * f;
        hj[col] -= wj * f;
      }
    }
  };
  // A kick on every momentum at the current q, its tangent first (it needs p before the kick):
  //   first:  p ← a p − (τ/2) g,    or the friction kick of a p with force −g;
  //   second: p ← a (p − (τ/2) g),  or a times the friction kick of p.
  // A friction kick's tangent is ∂p/∂p · (its p's tangent) + ∂p/∂f · (−(H t_q + ∂g/∂θ)) plus
  // ∂p/∂μ in its rate's column.
  const auto kick = [&](bool first, double a, double da, double half_tau) {
    if (any_fused)
      for (Index r = 0; r < d; ++r)
        if (w.fused[r]) w.kick[r] = coulomb_kick(first ? a * p[r] : p[r], -g[r], w.mu[r], half_tau);
    hessian_tangent();
    for (Index r = 0; r < d && c > 0; ++r) {
      double* tp = row(d + r);
      const double* hv = w.hv.data() + r * c;
      const double* gth = w.gth.data() + r * n_theta;
      if (!w.fused[r]) {
        // Without friction on this momentum: the same expressions as below, the columns of θ
        // (with ∂g/∂θ) and the rest in loops of their own, β's column after them from its
        // value before.
        const double before_beta = beta_col ? tp[beta_index_] : 0.0;
        if (first) {
          for (Index col = 0; col < n_theta; ++col)
            tp[col] = a * tp[col] - half_tau * (hv[col] + gth[col]);
          for (Index col = n_theta; col < c; ++col) tp[col] = a * tp[col] - half_tau * hv[col];
        } else {
          for (Index col = 0; col < n_theta; ++col)
            tp[col] = (tp[col] - half_tau * (hv[col] + gth[col])) * a;
          for (Index col = n_theta; col < c; ++col) tp[col] = (tp[col] - half_tau * hv[col]) * a;
        }
        if (beta_col) {
          const Index col = beta_index_;
          const double force = hv[col] + gth[col];
          if (first) {
            tp[col] = (a * before_beta + da * p[r]) - half_tau * force;
          } else {
            tp[col] = (before_beta - half_tau * force) * a + da * (p[r] - half_tau * g[r]);
          }
        }
        continue;
      }
      // A momentum with Coulomb friction takes its kick's exact flow.
      const KickStep& k = w.kick[r];
      const Index rate = dissipation_index(coulomb_of_[static_cast<std::size_t>(r)]);
      for (Index col = 0; col < c; ++col) {
        const double force = col < n_theta ? hv[col] + gth[col] : hv[col];
        const bool is_beta = beta_col && col == beta_index_;
        double in = first ? a * tp[col] : tp[col];
        if (first && is_beta) in += da * p[r];
        double out = k.dp * in - k.dforce * force;
        if (col == rate && rate < n_theta) out += abs_derivative(theta(rate)) * k.drate;
        if (!first) {
          out *= a;
          if (is_beta) out += da * k.p;
        }
        tp[col] = out;
      }
    }
    for (Index r = 0; r < d; ++r) {
      if (first)
        p[r] = w.fused[r] ? w.kick[r].p : a * p[r] - half_tau * g[r];
      else
        p[r] = w.fused[r] ? a * w.kick[r].p : a * (p[r] - half_tau * g[r]);
    }
  };
  // q ← q + τ W p: row r of t_q gains τ (W t_p)_r, each (W t_p)_r summed over W's row in
  // column order from 0 as mass_times() does; W's own columns gain τ ∂W/∂W_rc p.
  const auto drift = [&](double tau) {
    for (Index r = 0; r < d && c > 0; ++r) {
      double* tq = row(r);
      if (!full_mass_) {
        const double wr = mass[r * d + r];
        const double* tp = row(d + r);
        for (Index col = 0; col < c; ++col) tq[col] += tau * (wr * tp[col]);
        continue;
      }
      // Eight columns at a time in registers, the sum over W's row for each in column order
      // from 0 (the d² c products are most of a stage's work on a chain).
      const double* wr = mass + r * d;
      const double* tp0 = row(d);
      Index col = 0;
      for (; col + kColumnBlock <= c; col += kColumnBlock) {
        ColumnBlock acc = ColumnBlock::Zero();
        for (Index cc = 0; cc < d; ++cc)
          acc += wr[cc] * Eigen::Map<const ColumnBlock>(tp0 + cc * c + col);
        Eigen::Map<ColumnBlock>(tq + col) += tau * acc;
      }
      for (; col < c; ++col) {
        double acc = 0.0;
        for (Index cc = 0; cc < d; ++cc) acc += wr[cc] * tp0[cc * c + col];
        tq[col] += tau * acc;
      }
    }
    if (full_mass_)
      for (Index r = 0; r < d; ++r)
        for (Index cc = 0; cc <= r; ++cc) {
          const Index col = r * (r + 1) / 2 + cc;
          if (col >= n_theta) continue;
          row(r)[col] += tau * p[cc];
          if (cc != r) row(cc)[col] += tau * p[r];
        }
    else
      for (Index r = 0; r < std::min(d, n_theta); ++r) row(r)[r] += tau * p[r];
    mass_apply(p, w.wp.data());
    for (Index r = 0; r < d; ++r) q[r] += tau * w.wp[r];
  };
  // The dissipation flows beside the kicks over τ/2 (opening: in term order; closing: the
  // reverse), as dissipate(): each scales its momentum's tangent row by ∂p/∂p and adds ∂p/∂r in
  // its rate's column.
  const Index nk = static_cast<Index>(dissipation_.size());
  const auto flows = [&](double half_tau, bool closing) {
    for (Index n = 0; n < nk; ++n) {
      const Index k = closing ? nk - 1 - n : n;
      if (in_kicks(k)) continue;
      const DissipationTerm& term = dissipation_[static_cast<std::size_t>(k)];
      const Index col = dissipation_index(k);
      const FlowStep f = dissipation_flow(term.kind, p[term.i], std::abs(theta(col)), half_tau);
      double* tp = row(d + term.i);
      for (Index cc = 0; cc < c; ++cc) tp[cc] *= f.dp;
      if (col < n_theta) tp[col] += abs_derivative(theta(col)) * f.drate;
      p[term.i] = f.p;
    }
  };

  at_position(driven ? sigma(0) : 0.0);
  // Stage s takes the weight s mod nw; the stop request is polled every kStagesPerPoll stages.
  Index weight = 0, since_poll = 0;
  for (Index s = 0; s < stages; ++s) {
    if (++since_poll == kStagesPerPoll) {
      since_poll = 0;
      throw_if_stop_requested("hamiltonian library: a step of many substeps");
    }
    const double tau = w.tau[static_cast<std::size_t>(weight)];
    const double a = w.scaling[static_cast<std::size_t>(weight)];
    if (++weight == nw) weight = 0;
    const double da = -0.5 * tau * a * abs_derivative(beta);  // ∂a/∂β
    if (nk > 0) flows(0.5 * tau, false);
    kick(true, a, da, 0.5 * tau);
    drift(tau);
    at_position(driven ? sigma(s + 1) : 0.0);
    kick(false, a, da, 0.5 * tau);
    if (nk > 0) flows(0.5 * tau, true);
  }
  for (Index r = 0; r < d; ++r) {
    z[r] = q[r];
    z[d + r] = p[r];
  }
  t = RowBlock(tr, 2 * d, c);
}

}  // namespace csympnet
