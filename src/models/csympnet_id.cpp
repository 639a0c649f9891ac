#include "csympnet_id.hpp"

#include <cmath>
#include <vector>

#include "../kernels/column_scaling.hpp"
#include "../kernels/conformal_rows.hpp"
#include "../kernels/scaled_exp.hpp"
#include "csympnet/core/error.hpp"
#include "library_map_detail.hpp"
#include "shape_checks.hpp"

namespace csympnet {

namespace {

using library_detail::abs_derivative;

// The state and gradient rows are split and joined here column by column: Eigen's loops over
// a block of rows of a column-major matrix (a 1 x N row of a 2 x N matrix above all) are
// slow, and copies and single products give the same IEEE values in any order. kD = d when
// fixed at compile time (d = 1, the hot case), else 0.

// q = the top d rows of the 2d x n matrix z; p = its bottom rows, times a_j in column j when
// kScale; when kRaw, p_raw = the bottom rows unscaled.
template <int kD, bool kScale, bool kRaw>
void split_rows_impl(const double* z, Index n, Index d, const double* a, double* q, double* p,
                     double* p_raw) {
  const Index dd = kD > 0 ? kD : d;
  for (Index j = 0; j < n; ++j) {
    const double* zj = z + 2 * dd * j;
    for (Index i = 0; i < dd; ++i) {
      const double bottom = zj[dd + i];
      q[dd * j + i] = zj[i];
      p[dd * j + i] = kScale ? bottom * a[j] : bottom;
      if (kRaw) p_raw[dd * j + i] = bottom;
    }
  }
}

template <int kD>
void split_rows_d(const double* z, Index n, Index d, const double* a, double* q, double* p,
                  double* p_raw) {
  if (a != nullptr && p_raw != nullptr) {
    split_rows_impl<kD, true, true>(z, n, d, a, q, p, p_raw);
  } else if (a != nullptr) {
    split_rows_impl<kD, true, false>(z, n, d, a, q, p, p_raw);
  } else if (p_raw != nullptr) {
    split_rows_impl<kD, false, true>(z, n, d, a, q, p, p_raw);
  } else {
    split_rows_impl<kD, false, false>(z, n, d, a, q, p, p_raw);
  }
}

// q, p (d x n, sized by the caller) from z (2d x n): q = top rows, p = a ⊙ bottom rows (the
// rows' `.rowwise() *= aᵀ`; unscaled when a is null); p_raw, if not null, = bottom rows.
void split_rows(const Matrix& z, const Vector* a, Matrix& q, Matrix& p, Matrix* p_raw) {
  const Index d = q.rows();
  const double* av = a != nullptr ? a->data() : nullptr;
  double* raw = p_raw != nullptr ? p_raw->data() : nullptr;
  if (d == 1) {
    if (av != nullptr &&
        kernels::split_scaled_rows_simd(z.data(), z.cols(), av, q.data(), p.data(), raw)) {
      return;
    }
    split_rows_d<1>(z.data(), z.cols(), d, av, q.data(), p.data(), raw);
  } else {
    split_rows_d<0>(z.data(), z.cols(), d, av, q.data(), p.data(), raw);
  }
}

template <int kD>
void join_rows_impl(const double* q, const double* p, const double* a, Index n, Index d,
                    double* out) {
  const Index dd = kD > 0 ? kD : d;
  for (Index j = 0; j < n; ++j) {
    double* oj = out + 2 * dd * j;
    for (Index i = 0; i < dd; ++i) {
      oj[i] = q[dd * j + i];
      oj[dd + i] = p[dd * j + i] * a[j];
    }
  }
}

// out (2d x n) = [q; p ⊙ a] (the rows' `p.array().rowwise() * aᵀ`).
void join_rows(const Matrix& q, const Matrix& p, const Vector& a, Matrix& out) {
  const Index d = q.rows();
  out.resize(2 * d, q.cols());
  if (d == 1) {
    if (kernels::join_scaled_rows_simd(q.data(), p.data(), a.data(), q.cols(), out.data())) return;
    join_rows_impl<1>(q.data(), p.data(), a.data(), q.cols(), d, out.data());
  } else {
    join_rows_impl<0>(q.data(), p.data(), a.data(), q.cols(), d, out.data());
  }
}

// a_j = exp(c h_j), c = −γ̂/2: the values of the Eigen expression `(c * h.array()).exp()`,
// through the AVX-512 or AVX2 kernel where one runs (src/kernels/scaled_exp.hpp).
void conformal_factors(double gamma, const Vector& h, Vector& a) {
  const double c = -0.5 * gamma;
  a.resize(h.size());
  if (kernels::scaled_exp_simd(c, h.data(), a.data(), h.size())) return;
  a = (c * h.array()).exp().matrix();
}

// conformal_factors() on columns cols of a sized vector a. The kernel and Eigen both treat
// elements in pairs from the first; ranges start at even columns, so every element is
// computed as in one call on the whole vector.
void conformal_factors(double gamma, const Vector& h, Vector& a, Columns cols) {
  const double c = -0.5 * gamma;
  const Index n = cols.size();
  double* out = a.data() + cols.begin;
  const double* hs = h.data() + cols.begin;
  if (kernels::scaled_exp_simd(c, hs, out, n)) return;
  Eigen::Map<Vector>(out, n) = (c * Eigen::Map<const Vector>(hs, n).array()).exp().matrix();
}

// d = 1: Σ_j (dL/da_j) h_j a_j with dL/da_j = G_j p_core,j + G̃_j p_in,j, where G is the p row
// of dZout and G̃ the core's input gradient gp. The column sums of the general path are single
// products here; the terms go to `terms` (n doubles, 16-byte aligned storage of an Eigen
// object) and are summed by Eigen's reduction, in the order of the expression
// `(grad_a.array() * h.array() * a.array()).sum()` of the general path (both start their packets
// at element 0).
double scalar_damping_sum(const Matrix& dZout, const Matrix& p_core, const Matrix& gp,
                          const Matrix& p_in, const Vector& h, const Vector& a, double* terms) {
  const Index n = dZout.cols();
  const double* g = dZout.data() + 1;
  if (kernels::damping_terms_simd(dZout.data(), p_core.data(), gp.data(), p_in.data(), h.data(),
                                  a.data(), n, terms)) {
    return Eigen::Map<const Vector>(terms, n).sum();
  }
  for (Index j = 0; j < n; ++j) {
    const double grad_a = g[2 * j] * p_core(0, j) + gp(0, j) * p_in(0, j);
    terms[j] = grad_a * h(j) * a(j);
  }
  return Eigen::Map<const Vector>(terms, n).sum();
}

}  // namespace

CSympNetId::CSympNetId(std::unique_ptr<SymplecticCore> core, double beta_init, InputSpec inputs)
    : core_(std::move(core)), beta_init_(beta_init), inputs_(inputs) {
  require(core_ != nullptr, "csympnet: the symplectic core must not be null");
  require(inputs_.m >= 0, "csympnet: the number of inputs must be >= 0");
  require(std::isfinite(beta_init) && beta_init != 0.0, [&] {
    return "csympnet: beta_init = " + std::to_string(beta_init) +
           ", expected a finite nonzero value (d|beta|/dbeta vanishes at 0, so beta would "
           "never train)";
  });
}

void CSympNetId::init_params(Rng& rng, ParamsRef theta) const {
  check_theta(*this, theta, "init_params");
  const Index nc = core_->n_params();
  core_->init_params(rng, theta.head(nc));
  theta.segment(nc, core_->d() * inputs_.m).setZero();
  theta(n_params() - 1) = beta_init_;
}

Matrix CSympNetId::forward(ConstParams theta, const Matrix& Z, const Vector& h,
                           ForwardCache* cache) const {
  // The checks build their messages before testing; run them only when something is wrong.
  if (theta.size() != n_params() || Z.rows() != dim() || h.size() != Z.cols()) {
    check_forward_args(*this, theta, Z, h);
  }
  if (cache != nullptr && core_->d() > 1) {
    // The column pass on all columns: what the column-split epoch runs range by range.
    size_forward(h, *cache);
    Matrix out(Z.rows(), Z.cols());
    forward_columns(theta, Z, *cache, out, {0, Z.cols()});
    return out;
  }
  const Index d = core_->d();
  const Index nc = core_->n_params();
  const Index n = Z.cols();
  // Working rows: with a cache, the context's own (so that an epoch allocates only the returned
  // matrix); without, locals.
  Vector a_local;
  Matrix q_local, p_local;
  Vector* a = &a_local;
  Matrix* q = &q_local;
  Matrix* p = &p_local;
  Matrix* p_in = nullptr;
  ForwardCache* core_cache = nullptr;
  if (cache != nullptr) {
    Context& ctx = cache->make_context<Context>();
    ctx.h = h;
    ctx.u.resize(0, 0);
    a = &ctx.a;
    q = &ctx.q;
    p = &ctx.p_core;
    p_in = &ctx.p_in;
    p_in->resize(d, n);
    core_cache = &ctx.core;
  }
  // a_j = exp(−γ̂ h_j / 2), the conformal factor of S_a for sample j.
  conformal_factors(std::abs(theta(n_params() - 1)), h, *a);
  q->resize(d, n);
  p->resize(d, n);
  split_rows(Z, a, *q, *p, p_in);
  core_->flow(theta.head(nc), *q, *p, h, core_cache);
  Matrix out;
  join_rows(*q, *p, *a, out);
  return out;
}

const CSympNetId::Context& CSympNetId::recorded(const ForwardCache& cache,
                                                const char* reader) const {
  const auto& ctx = cache.context<Context>(reader);
  require(ctx.p_in.rows() == core_->d(), [&] {
    return std::string(reader) +
           ": the cache holds a forward pass at d = " + std::to_string(ctx.p_in.rows()) +
           ", this model has d = " + std::to_string(core_->d());
  });
  return ctx;
}

void CSympNetId::backward(ConstParams theta, const ForwardCache& cache, const Matrix& dZout,
                          ParamsRef grad, Matrix* dZin) const {
  const Context& ctx = recorded(cache, "csympnet::backward");
  const Index batch = ctx.h.size();
  if (theta.size() != n_params() || dZout.rows() != dim() || dZout.cols() != batch ||
      grad.size() != n_params()) {
    check_backward_args(*this, theta, batch, dZout, grad);
  }
  const Index d = core_->d();
  const Index nc = core_->n_params();
  const Index n = dZout.cols();
  const Vector& h = ctx.h;
  const Vector& a = ctx.a;
  const Matrix& p_in = ctx.p_in;
  const Matrix& p_core = ctx.p_core;
  Matrix gq(d, n), gp(d, n);
  // Outer scaling p_out = a ⊙ p_core:  dL/da_j = Σ_i G_ij p_core,ij,  dL/dp_core = a G.
  // (For d = 1 the column sums are single products, formed after the core below.)
  Vector grad_a;
  if (d == 1) {
    split_rows(dZout, &a, gq, gp, nullptr);
  } else {
    split_rows(dZout, nullptr, gq, gp, nullptr);
    grad_a = (gp.array() * p_core.array()).colwise().sum().transpose();
    kernels::scale_columns(gp, a.data());
  }
  const bool driven = ctx.u.rows() > 0;
  // The second kick p += (h/2) B u(t₀ + h): gp passes unchanged, B takes its share.
  if (driven) kick_backward(gp, h, ctx.u, 1.0, grad);
  core_->flow_backward(theta.head(nc), ctx.core, h, gq, gp, grad.head(nc));
  if (driven) kick_backward(gp, h, ctx.u, 0.0, grad);
  // Inner scaling p̃ = a ⊙ p_in:  dL/da_j += Σ_i G̃_ij p_in,ij,  dL/dp_in = a G̃.
  // a_j = exp(−|β| h_j / 2):  da_j/dβ = −(h_j / 2) a_j sign(β).
  double sum;
  if (d == 1) {
    // gq's storage is spare from here unless dZin needs it.
    Vector spare(dZin != nullptr ? n : 0);
    sum = scalar_damping_sum(dZout, p_core, gp, p_in, h, a,
                             dZin != nullptr ? spare.data() : gq.data());
  } else {
    grad_a.array() += (gp.array() * p_in.array()).colwise().sum().transpose();
    sum = (grad_a.array() * h.array() * a.array()).sum();
  }
  const Index bi = n_params() - 1;
  grad(bi) += -0.5 * abs_derivative(theta(bi)) * sum;
  if (dZin != nullptr) join_rows(gq, gp, a, *dZin);
}

CSympNetId::Context& CSympNetId::size_forward(const Vector& h, ForwardCache& cache) const {
  const Index d = core_->d();
  const Index n = h.size();
  Context& ctx = cache.make_context<Context>();
  ctx.h = h;
  ctx.u.resize(0, 0);
  ctx.a.resize(n);
  ctx.p_in.resize(d, n);
  ctx.p_core.resize(d, n);
  ctx.q.resize(d, n);
  core_->size_flow(ctx.core, n, false);
  return ctx;
}

bool CSympNetId::splits(Index n, const std::vector<Columns>& ranges) const {
  return inputs_.m == 0 && core_->d() > 1 && core_->splits_columns(n, ranges);
}

void CSympNetId::prepare(ConstParams theta, const Vector& h, ForwardCache& cache) const {
  check_theta(*this, theta, "prepare");
  require(core_->d() > 1, "csympnet: the column-split passes need d > 1");
  const Index n = h.size();
  Context& ctx = size_forward(h, cache);
  core_->size_flow(ctx.core, n, true);
  ctx.gq.resize(core_->d(), n);
  ctx.gp.resize(core_->d(), n);
  ctx.grad_a.resize(n);
}

void CSympNetId::forward_columns(ConstParams theta, const Matrix& Z, ForwardCache& cache,
                                 Matrix& out, Columns cols) const {
  const Index d = core_->d();
  const Index nc = core_->n_params();
  const Index c0 = cols.begin;
  const Index n = cols.size();
  // Sized by prepare() or size_forward(): only looked up here (the ranges run in parallel).
  Context& ctx = cache.context<Context>("csympnet::forward_columns");
  const Vector& h = ctx.h;
  Vector& a = ctx.a;
  Matrix& p = ctx.p_core;  // the core's p, in place: it ends as the core output
  Matrix& q = ctx.q;
  // a_j = exp(−γ̂ h_j / 2), the conformal factor of S_a for sample j.
  conformal_factors(std::abs(theta(n_params() - 1)), h, a, cols);
  split_rows_d<0>(Z.data() + 2 * d * c0, n, d, a.data() + c0, q.data() + d * c0, p.data() + d * c0,
                  ctx.p_in.data() + d * c0);
  core_->flow_columns(theta.head(nc), q, p, h, &ctx.core, cols);
  join_rows_impl<0>(q.data() + d * c0, p.data() + d * c0, a.data() + c0, n, d,
                    out.data() + 2 * d * c0);
}

void CSympNetId::backward_columns(ConstParams theta, const ForwardCache& cache, const Matrix& dZout,
                                  Columns cols) const {
  const Index d = core_->d();
  const Index nc = core_->n_params();
  const Index c0 = cols.begin;
  const Index n = cols.size();
  const Context& ctx = recorded(cache, "csympnet::backward_columns");
  const Vector& h = ctx.h;
  const Vector& a = ctx.a;
  Matrix& gq = ctx.gq;
  Matrix& gp = ctx.gp;
  auto grad_a = ctx.grad_a.segment(c0, n);
  const auto gpc = gp.middleCols(c0, n);
  // As backward(): dL/da_j from the outer scaling, then the core, then the inner scaling.
  split_rows_d<0>(dZout.data() + 2 * d * c0, n, d, nullptr, gq.data() + d * c0, gp.data() + d * c0,
                  nullptr);
  grad_a = (gpc.array() * ctx.p_core.middleCols(c0, n).array()).colwise().sum().transpose();
  kernels::scale_columns(gp.middleCols(c0, n), a.data() + c0);
  core_->backward_columns(theta.head(nc), ctx.core, h, gq, gp, cols);
  grad_a.array() += (gpc.array() * ctx.p_in.middleCols(c0, n).array()).colwise().sum().transpose();
}

void CSympNetId::backward_params(ConstParams theta, const ForwardCache& cache, ParamsRef grad,
                                 Share share) const {
  const Index nc = core_->n_params();
  const Context& ctx = recorded(cache, "csympnet::backward_params");
  core_->backward_params(theta.head(nc), ctx.core, ctx.h, grad.head(nc), share);
}

void CSympNetId::backward_finish(ConstParams theta, const ForwardCache& cache,
                                 ParamsRef grad) const {
  const Index bi = n_params() - 1;
  const Context& ctx = recorded(cache, "csympnet::backward_finish");
  const double sum = (ctx.grad_a.array() * ctx.h.array() * ctx.a.array()).sum();
  grad(bi) += -0.5 * abs_derivative(theta(bi)) * sum;
}

Matrix CSympNetId::jacobian(ConstParams theta, const Vector& z, double h) const {
  return jacobian_driven(theta, z, h, Vector());
}

Matrix CSympNetId::jacobian_driven(ConstParams theta, const Vector& z, double h,
                                   const Vector& u) const {
  check_jacobian_args(*this, theta, z);
  if (u.size() != 0) check_inputs(Matrix(u), 1);
  const Index d = core_->d();
  const Index nc = core_->n_params();
  const double a = std::exp(-0.5 * std::abs(theta(n_params() - 1)) * h);
  // DΦ̂ = diag(I, aI) DΨ(K S_a z) diag(I, aI): start the tangents at diag(I, aI); the kicks
  // move the state, not the tangents.
  Vector q = z.head(d);
  Matrix p = a * z.tail(d);
  const Vector hv = Vector::Constant(1, h);
  if (u.size() != 0) kick(theta, p, hv, Matrix(u), 0.0);
  Vector pv = p.col(0);
  Matrix tq = Matrix::Zero(d, 2 * d);
  Matrix tp = Matrix::Zero(d, 2 * d);
  tq.leftCols(d).setIdentity();
  tp.rightCols(d).diagonal().setConstant(a);
  core_->flow_tangent(theta.head(nc), q, pv, tq, tp, h);
  Matrix jac(2 * d, 2 * d);
  jac.topRows(d) = tq;
  jac.bottomRows(d) = a * tp;
  return jac;
}

void CSympNetId::check_inputs(const Matrix& U, Index n) const {
  require(inputs_.m > 0, [&] {
    return "csympnet forward: this map takes no inputs (U has " + std::to_string(U.rows()) +
           " rows); expected a spec with \"inputs\": {\"m\": ...} for a driven record";
  });
  require(U.rows() == 2 * inputs_.m && U.cols() == n, [&] {
    return "csympnet: inputs of " + std::to_string(U.rows()) + " x " + std::to_string(U.cols()) +
           " for a map of " + std::to_string(inputs_.m) + " inputs and " + std::to_string(n) +
           " steps; expected " + std::to_string(2 * inputs_.m) + " x " + std::to_string(n) +
           " (per step the input at its start, then at its end)";
  });
}

void CSympNetId::kick(ConstParams theta, Matrix& p, const Vector& h, const Matrix& U,
                      double sigma) const {
  const Index d = core_->d(), m = inputs_.m;
  std::vector<double> u(static_cast<std::size_t>(m));
  for (Index j = 0; j < p.cols(); ++j) {
    input_at(inputs_.hold, m, U.col(j).data(), sigma, u.data());
    const double half = 0.5 * h(j);
    for (Index r = 0; r < d; ++r) {
      double f = 0.0;
      for (Index c = 0; c < m; ++c) f += theta(input_index(r, c)) * u[static_cast<std::size_t>(c)];
      p(r, j) += half * f;
    }
  }
}

void CSympNetId::kick_backward(const Matrix& gp, const Vector& h, const Matrix& U, double sigma,
                               ParamsRef grad) const {
  const Index d = core_->d(), m = inputs_.m;
  std::vector<double> u(static_cast<std::size_t>(m));
  for (Index j = 0; j < gp.cols(); ++j) {
    input_at(inputs_.hold, m, U.col(j).data(), sigma, u.data());
    const double half = 0.5 * h(j);
    for (Index r = 0; r < d; ++r)
      for (Index c = 0; c < m; ++c)
        grad(input_index(r, c)) += half * gp(r, j) * u[static_cast<std::size_t>(c)];
  }
}

Matrix CSympNetId::forward_driven(ConstParams theta, const Matrix& Z, const Vector& h,
                                  const Matrix& U, ForwardCache* cache) const {
  if (U.rows() == 0) return forward(theta, Z, h, cache);
  check_forward_args(*this, theta, Z, h);
  check_inputs(U, Z.cols());
  const Index d = core_->d();
  const Index nc = core_->n_params();
  const Index n = Z.cols();
  Vector a_local;
  Matrix q_local, p_local, p_in_local;
  Vector* a = &a_local;
  Matrix* q = &q_local;
  Matrix* p = &p_local;
  Matrix* p_in = &p_in_local;
  ForwardCache* core_cache = nullptr;
  if (cache != nullptr) {
    Context& ctx = cache->make_context<Context>();
    ctx.h = h;
    ctx.u = U;
    a = &ctx.a;
    q = &ctx.q;
    p = &ctx.p_core;
    p_in = &ctx.p_in;
    core_cache = &ctx.core;
  }
  conformal_factors(std::abs(theta(n_params() - 1)), h, *a);
  q->resize(d, n);
  p->resize(d, n);
  p_in->resize(d, n);
  split_rows(Z, a, *q, *p, p_in);
  kick(theta, *p, h, U, 0.0);
  core_->flow(theta.head(nc), *q, *p, h, core_cache);
  kick(theta, *p, h, U, 1.0);
  Matrix out;
  join_rows(*q, *p, *a, out);
  return out;
}

std::optional<double> CSympNetId::damping_rate(ConstParams theta) const {
  check_theta(*this, theta, "damping_rate");
  return std::abs(theta(n_params() - 1));
}

nlohmann::json CSympNetId::hyperparams() const {
  nlohmann::json spec = {{"type", "csympnet"},
                         {"d", core_->d()},
                         {"core", core_->core_spec()},
                         {"beta_init", beta_init_}};
  if (inputs_.m > 0) spec["inputs"] = input_spec_json(inputs_);
  return spec;
}

}  // namespace csympnet
