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
#include <limits>
#include <vector>

#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "library_map_detail.hpp"

namespace csympnet::library_detail {

// The work space of one step, kept per thread so that a step allocates nothing once its sizes
// have been seen.
struct TangentScratch {
  std::vector<double> q, p, g, wp, work, d1, d2, d1k, hv, gth, mass, coef, kappa, mu, curvature;
  // Per wavenumber: the κu its sinusoid was last evaluated at (NaN: never), sin and cos there.
  std::vector<double> sinusoid_at, sinusoid_sin, sinusoid_cos;
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

namespace {

// A block of columns of the tangents as one value (Eigen runs it in SIMD packets, each entry the
// same expression as alone).
constexpr Index kColumnBlock = 8;
using ColumnBlock = Eigen::Array<double, kColumnBlock, 1>;
using RowBlock = Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;

void fit_to(std::vector<double>& v, Index n) {
  if (static_cast<Index>(v.size()) < n) v.resize(static_cast<std::size_t>(n));
}

}  // namespace

// One call of step_tangents: the per-step state (θ's values in the forms a stage reads, q, p,
// the tangent rows) and a stage's parts as functions over it, in the order a stage runs them:
// the opening flows, the first kick, the drift, the terms at the new q, the second kick, the
// closing flows.
class TangentStep {
 public:
  TangentStep(const HamiltonianLibraryMap& map, ConstParams theta, double h, const double* u,
              const double* z, const Matrix& t, Index n_theta)
      : m_(map),
        theta_(theta),
        u_(u),
        d_(map.d_),
        c_(t.cols()),
        nt_(static_cast<Index>(map.terms_.size())),
        nk_(static_cast<Index>(map.dissipation_.size())),
        n_theta_(n_theta),
        driven_(u != nullptr),
        w_(scratch()) {
    size_scratch();
    RowBlock(w_.rows.data(), 2 * d_, c_) = t;
    for (Index r = 0; r < d_; ++r) {
      w_.q[r] = z[r];
      w_.p[r] = z[d_ + r];
    }
    beta_ = theta_(m_.beta_index_);
    beta_col_ = m_.beta_index_ < n_theta_;
    stage_constants(h);
    per_step_values();
  }

  // The stages; the end state into z, the tangents into t.
  void run(double* z, Matrix& t) {
    at_position(driven_ ? m_.sigma(0) : 0.0);
    const Index stages = m_.stages_per_step(), nw = static_cast<Index>(m_.weights_.size());
    // Stage s takes the weight s mod nw; the stop request is polled every kStagesPerPoll stages.
    Index weight = 0, since_poll = 0;
    for (Index s = 0; s < stages; ++s) {
      if (++since_poll == kStagesPerPoll) {
        since_poll = 0;
        throw_if_stop_requested("hamiltonian library: a step of many substeps");
      }
      const double tau = w_.tau[static_cast<std::size_t>(weight)];
      const double a = w_.scaling[static_cast<std::size_t>(weight)];
      if (++weight == nw) weight = 0;
      const double da = -0.5 * tau * a * abs_derivative(beta_);  // ∂a/∂β
      if (nk_ > 0) flows(0.5 * tau, false);
      kick(true, a, da, 0.5 * tau);
      drift(tau);
      at_position(driven_ ? m_.sigma(s + 1) : 0.0);
      kick(false, a, da, 0.5 * tau);
      if (nk_ > 0) flows(0.5 * tau, true);
    }
    for (Index r = 0; r < d_; ++r) {
      z[r] = w_.q[r];
      z[d_ + r] = w_.p[r];
    }
    t = RowBlock(w_.rows.data(), 2 * d_, c_);
  }

 private:
  static TangentScratch& scratch() {
    thread_local TangentScratch w;
    return w;
  }
  double* row(Index r) const { return w_.rows.data() + r * c_; }

  void size_scratch() {
    for (auto* v : {&w_.q, &w_.p, &w_.g, &w_.wp, &w_.mu}) fit_to(*v, d_);
    if (static_cast<Index>(w_.kick.size()) < d_) {
      w_.kick.resize(static_cast<std::size_t>(d_));
      w_.fused.resize(static_cast<std::size_t>(d_));
    }
    for (auto* v : {&w_.d1, &w_.d2, &w_.d1k, &w_.coef, &w_.kappa}) fit_to(*v, nt_);
    fit_to(w_.work, std::max<Index>(m_.inputs_.m, 1));
    fit_to(w_.hv, d_ * c_);
    fit_to(w_.curvature, static_cast<Index>(m_.groups_.size()));
    fit_to(w_.gth, d_ * n_theta_);
    fit_to(w_.mass, d_ * d_);
    fit_to(w_.rows, 2 * d_ * c_);
    const auto np = static_cast<std::size_t>(m_.n_params());
    if (w_.sinusoid_at.size() < np) {
      w_.sinusoid_at.resize(np, std::numeric_limits<double>::quiet_NaN());
      w_.sinusoid_sin.resize(np);
      w_.sinusoid_cos.resize(np);
    }
  }

  // τ and a per stage weight, kept while (γ, h, order, substeps) stay.
  void stage_constants(double h) {
    const double gamma = std::abs(beta_);
    if (w_.scaling_gamma == gamma && w_.scaling_h == h && w_.scaling_order == m_.order_ &&
        w_.scaling_substeps == m_.substeps_)
      return;
    const Index nw = static_cast<Index>(m_.weights_.size());
    w_.tau.resize(static_cast<std::size_t>(nw));
    w_.scaling.resize(static_cast<std::size_t>(nw));
    for (Index s = 0; s < nw; ++s) {
      const auto ss = static_cast<std::size_t>(s);
      w_.tau[ss] = m_.weights_[ss] * h / static_cast<double>(m_.substeps_);
      w_.scaling[ss] = std::exp(-0.5 * gamma * w_.tau[ss]);
    }
    w_.scaling_gamma = gamma;
    w_.scaling_h = h;
    w_.scaling_order = m_.order_;
    w_.scaling_substeps = m_.substeps_;
  }

  // What θ alone decides, once per step: each term's coefficient and wavenumber, each
  // momentum's Coulomb rate, W dense (row-major).
  void per_step_values() {
    for (Index k = 0; k < nt_; ++k) {
      w_.coef[k] = theta_(m_.coefficient_index(k));
      w_.kappa[k] = m_.terms_[static_cast<std::size_t>(k)].has_wavenumber()
                        ? theta_(m_.wavenumber_index(k))
                        : 0.0;
    }
    any_fused_ = false;
    for (Index r = 0; r < d_; ++r) {
      w_.mu[r] = m_.coulomb_rate(theta_, r);
      w_.fused[r] = w_.mu[r] > 0.0;
      any_fused_ = any_fused_ || w_.fused[r];
    }
    const bool full = m_.full_mass_;
    for (Index r = 0; r < d_; ++r)
      for (Index cc = 0; cc < d_; ++cc) {
        const bool on = full || r == cc;
        const Index at = full ? (r >= cc ? r * (r + 1) / 2 + cc : cc * (cc + 1) / 2 + r) : r;
        w_.mass[r * d_ + cc] = on ? theta_(at) : 0.0;
      }
  }

  // x ↦ W x, each row summed in column order from 0: the bits of mass_times().
  void mass_apply(const double* x, double* out) const {
    const double* mass = w_.mass.data();
    if (!m_.full_mass_) {
      for (Index r = 0; r < d_; ++r) out[r] = mass[r * d_ + r] * x[r];
      return;
    }
    for (Index r = 0; r < d_; ++r) {
      double sum = 0.0;
      for (Index cc = 0; cc < d_; ++cc) sum += mass[r * d_ + cc] * x[cc];
      out[r] = sum;
    }
  }

  // The terms at q: φ', φ'' and ∂φ'/∂κ per term, g = ∇V(q) − B u(σ) as gradient() and
  // add_force() compute it, and ∂g/∂θ (d × n_theta, row-major) into w_.gth.
  void at_position(double sigma) {
    const double* q = w_.q.data();
    double* g = w_.g.data();
    for (Index r = 0; r < d_; ++r) g[r] = 0.0;
    for (Index k = 0; k < nt_; ++k) {
      const LibraryTerm& term = m_.terms_[static_cast<std::size_t>(k)];
      const auto kk = static_cast<std::size_t>(k);
      const double arg = term.j < 0 ? q[term.i] : m_.wi_[kk] * q[term.i] - m_.wj_[kk] * q[term.j];
      const TermValues tv = values_of(k, term, arg);
      w_.d1[k] = tv.d1;
      w_.d2[k] = tv.d2;
      w_.d1k[k] = tv.d1_kappa;
      const double f = w_.coef[k] * tv.d1;
      g[term.i] += m_.wi_[kk] * f;
      if (term.j >= 0) g[term.j] -= m_.wj_[kk] * f;
    }
    if (driven_) m_.add_force(theta_, u_, sigma, g, w_.work.data());
    if (n_theta_ == 0) return;
    force_parameters(sigma);
  }

  // Term k's values at its argument; a sin and a cos of one argument share their wavenumber, so
  // the pair's sin(κu) and cos(κu) are computed once (kept by wavenumber, with the κu they were
  // computed at: a value kept from any earlier κu is recomputed).
  TermValues values_of(Index k, const LibraryTerm& term, double arg) {
    const double kappa = w_.kappa[k];
    if (term.shape != TermShape::kSin && term.shape != TermShape::kCos)
      return term_values(term, arg, kappa);
    const auto at = static_cast<std::size_t>(m_.wavenumber_index(k));
    const double x = kappa * arg;
    if (!(w_.sinusoid_at[at] == x)) {
      w_.sinusoid_at[at] = x;
      w_.sinusoid_sin[at] = std::sin(x);
      w_.sinusoid_cos[at] = std::cos(x);
    }
    return sinusoid_values(term.shape, arg, kappa, w_.sinusoid_sin[at], w_.sinusoid_cos[at]);
  }

  // ∂g/∂θ at the terms' current values: the coefficients' columns (φ_k'), the wavenumbers'
  // (c_k ∂φ_k'/∂κ) and B's (−u(σ)).
  void force_parameters(double sigma) {
    const Index n = n_theta_;
    double* gth = w_.gth.data();
    std::fill(gth, gth + d_ * n, 0.0);
    for (Index k = 0; k < nt_; ++k) {
      const LibraryTerm& term = m_.terms_[static_cast<std::size_t>(k)];
      const auto kk = static_cast<std::size_t>(k);
      const auto add = [&](Index col, double f) {
        if (col >= n) return;
        gth[term.i * n + col] += m_.wi_[kk] * f;
        if (term.j >= 0) gth[term.j * n + col] -= m_.wj_[kk] * f;
      };
      add(m_.coefficient_index(k), w_.d1[k]);
      if (term.has_wavenumber()) add(m_.wavenumber_index(k), w_.coef[k] * w_.d1k[k]);
    }
    if (!driven_) return;
    const Index inputs = m_.inputs_.m;
    input_at(m_.inputs_.hold, inputs, u_, sigma, w_.work.data());
    for (Index r = 0; r < d_; ++r)
      for (Index j = 0; j < inputs; ++j) {
        const Index col = m_.input_index(r, j);
        if (col < n) gth[r * n + col] -= w_.work[j];
      }
  }

  // hv = H(q) t_q (d × c, row-major): per argument group, its curvature s = Σ c_k φ_k'' over the
  // group's terms in their order, then one pass along the columns (each entry sums the groups
  // in their order). A stage's second kick and the next stage's first see the same q and t_q
  // (kicks and flows move p and t_p only), so hv is computed once for both: kept until the
  // drift moves q and t_q.
  void hessian_tangent() {
    const Index c = c_;
    if (c == 0 || hv_current_) return;
    hv_current_ = true;
    double* hv = w_.hv.data();
    std::fill(hv, hv + d_ * c, 0.0);
    const Index ng = static_cast<Index>(m_.groups_.size());
    double* curvature = w_.curvature.data();
    std::fill(curvature, curvature + ng, 0.0);
    for (Index k = 0; k < nt_; ++k)
      curvature[m_.group_of_[static_cast<std::size_t>(k)]] += w_.coef[k] * w_.d2[k];
    for (Index gi = 0; gi < ng; ++gi) {
      const HamiltonianLibraryMap::ArgumentGroup& group = m_.groups_[static_cast<std::size_t>(gi)];
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
  }

  // A kick on every momentum at the current q, its tangent first (it needs p before the kick):
  //   first:  p ← a p − (τ/2) g,    or the friction kick of a p with force −g;
  //   second: p ← a (p − (τ/2) g),  or a times the friction kick of p.
  void kick(bool first, double a, double da, double half_tau) {
    double* p = w_.p.data();
    const double* g = w_.g.data();
    if (any_fused_)
      for (Index r = 0; r < d_; ++r)
        if (w_.fused[r])
          w_.kick[r] = coulomb_kick(first ? a * p[r] : p[r], -g[r], w_.mu[r], half_tau);
    hessian_tangent();
    for (Index r = 0; r < d_ && c_ > 0; ++r) {
      if (w_.fused[r])
        friction_kick_row(r, first, a, da);
      else
        kick_row(r, first, a, da, half_tau);
    }
    for (Index r = 0; r < d_; ++r) {
      if (first)
        p[r] = w_.fused[r] ? w_.kick[r].p : a * p[r] - half_tau * g[r];
      else
        p[r] = w_.fused[r] ? a * w_.kick[r].p : a * (p[r] - half_tau * g[r]);
    }
  }

  // The tangent of momentum r without friction: the columns of θ (with ∂g/∂θ) and the rest in
  // loops of their own, β's column after them from its value before.
  void kick_row(Index r, bool first, double a, double da, double half_tau) {
    const Index c = c_, n = n_theta_;
    double* tp = row(d_ + r);
    const double* hv = w_.hv.data() + r * c;
    const double* gth = w_.gth.data() + r * n;
    const Index beta_at = m_.beta_index_;
    const double before_beta = beta_col_ ? tp[beta_at] : 0.0;
    if (first) {
      for (Index col = 0; col < n; ++col) tp[col] = a * tp[col] - half_tau * (hv[col] + gth[col]);
      for (Index col = n; col < c; ++col) tp[col] = a * tp[col] - half_tau * hv[col];
    } else {
      for (Index col = 0; col < n; ++col) tp[col] = (tp[col] - half_tau * (hv[col] + gth[col])) * a;
      for (Index col = n; col < c; ++col) tp[col] = (tp[col] - half_tau * hv[col]) * a;
    }
    if (!beta_col_) return;
    const double force = hv[beta_at] + gth[beta_at];
    const double p = w_.p[r];
    if (first)
      tp[beta_at] = (a * before_beta + da * p) - half_tau * force;
    else
      tp[beta_at] = (before_beta - half_tau * force) * a + da * (p - half_tau * w_.g[r]);
  }

  // The tangent of momentum r with Coulomb friction, its kick's exact flow: ∂p/∂p · (its p's
  // tangent) + ∂p/∂f · (−(H t_q + ∂g/∂θ)), plus ∂p/∂μ in its rate's column.
  void friction_kick_row(Index r, bool first, double a, double da) {
    const Index c = c_, n = n_theta_;
    double* tp = row(d_ + r);
    const double* hv = w_.hv.data() + r * c;
    const double* gth = w_.gth.data() + r * n;
    const KickStep& k = w_.kick[r];
    const Index rate = m_.dissipation_index(m_.coulomb_of_[static_cast<std::size_t>(r)]);
    const double p = w_.p[r];
    for (Index col = 0; col < c; ++col) {
      const double force = col < n ? hv[col] + gth[col] : hv[col];
      const bool is_beta = beta_col_ && col == m_.beta_index_;
      double in = first ? a * tp[col] : tp[col];
      if (first && is_beta) in += da * p;
      double out = k.dp * in - k.dforce * force;
      if (col == rate && rate < n) out += abs_derivative(theta_(rate)) * k.drate;
      if (!first) {
        out *= a;
        if (is_beta) out += da * k.p;
      }
      tp[col] = out;
    }
  }

  // q ← q + τ W p: row r of t_q gains τ (W t_p)_r, each (W t_p)_r summed over W's row in
  // column order from 0 as mass_times() does; W's own columns gain τ ∂W/∂W_rc p.
  void drift(double tau) {
    hv_current_ = false;
    const Index d = d_, c = c_;
    const double* mass = w_.mass.data();
    const double* p = w_.p.data();
    for (Index r = 0; r < d && c > 0; ++r) {
      double* tq = row(r);
      if (!m_.full_mass_) {
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
    mass_columns(tau);
    mass_apply(p, w_.wp.data());
    for (Index r = 0; r < d; ++r) w_.q[r] += tau * w_.wp[r];
  }

  // W's own columns of t_q: τ ∂W/∂W_rc p.
  void mass_columns(double tau) {
    const double* p = w_.p.data();
    if (m_.full_mass_) {
      for (Index r = 0; r < d_; ++r)
        for (Index cc = 0; cc <= r; ++cc) {
          const Index col = r * (r + 1) / 2 + cc;
          if (col >= n_theta_) continue;
          row(r)[col] += tau * p[cc];
          if (cc != r) row(cc)[col] += tau * p[r];
        }
      return;
    }
    for (Index r = 0; r < std::min(d_, n_theta_); ++r) row(r)[r] += tau * p[r];
  }

  // The dissipation flows beside the kicks over τ/2 (opening: in term order; closing: the
  // reverse), as dissipate(): each scales its momentum's tangent row by ∂p/∂p and adds ∂p/∂r in
  // its rate's column.
  void flows(double half_tau, bool closing) {
    for (Index n = 0; n < nk_; ++n) {
      const Index k = closing ? nk_ - 1 - n : n;
      if (m_.in_kicks(k)) continue;
      const DissipationTerm& term = m_.dissipation_[static_cast<std::size_t>(k)];
      const Index col = m_.dissipation_index(k);
      const FlowStep f = dissipation_flow(term.kind, w_.p[term.i], std::abs(theta_(col)), half_tau);
      double* tp = row(d_ + term.i);
      for (Index cc = 0; cc < c_; ++cc) tp[cc] *= f.dp;
      if (col < n_theta_) tp[col] += abs_derivative(theta_(col)) * f.drate;
      w_.p[term.i] = f.p;
    }
  }

  const HamiltonianLibraryMap& m_;
  ConstParams theta_;
  const double* u_;
  Index d_, c_, nt_, nk_, n_theta_;
  bool driven_;
  TangentScratch& w_;
  double beta_ = 0.0;
  bool beta_col_ = false;
  bool any_fused_ = false;
  bool hv_current_ = false;  // w_.hv is H(q) t_q at the current q and t_q
};

}  // namespace csympnet::library_detail

namespace csympnet {

void HamiltonianLibraryMap::step_tangents(ConstParams theta, double h, const double* u, double* z,
                                          Matrix& t, Index n_theta) const {
  require(theta.size() == n_params(),
          "hamiltonian library step_tangents: theta has the wrong size");
  require(t.rows() == 2 * d_ && n_theta >= 0 && n_theta <= t.cols() && n_theta <= n_params(),
          "hamiltonian library step_tangents: expected t of 2d rows and n_theta <= its columns");
  require(u == nullptr || inputs_.m > 0,
          "hamiltonian library step_tangents: inputs given to a map that takes none");
  library_detail::TangentStep step(*this, theta, h, u, z, t, n_theta);
  step.run(z, t);
}

}  // namespace csympnet
