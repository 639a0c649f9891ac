#include "la_sympnet.hpp"

#include <vector>

#include "../kernels/d1_sweeps.hpp"
#include "../kernels/registry.hpp"
#include "activation.hpp"
#include "csympnet/core/error.hpp"

namespace csympnet {

namespace {

// The d = 1 sweep kernels reproduce this model's own d = 1 loops, so their self-check comes from
// here (la_d1_check.cpp), supplied to the registry before main().
[[maybe_unused]] const bool kD1CheckSupplied =
    kernels::supply_check(kernels::Family::kD1Sweeps, &detail::la_d1_kernels_agree);
[[maybe_unused]] const bool kD1Avx2CheckSupplied =
    kernels::supply_check(kernels::Family::kD1SweepsAvx2, &detail::la_d1_avx2_kernels_agree);

using MatrixMap = Eigen::Map<Matrix>;

using detail::symmetric_from;

using RowMap = Eigen::Map<RowVector>;
using ConstRowMap = Eigen::Map<const RowVector>;

// Σ_j x_j y_j summed left to right from x_0 y_0: the order Eigen uses for the inner product of
// two 1 x N rows (and for the row sums of a 1 x N array), so d = 1 gradients keep their bits.
double sequential_dot(const double* x, const double* y, Index n) {
  if (n == 0) return 0.0;
  double acc = x[0] * y[0];
  for (Index j = 1; j < n; ++j) acc += x[j] * y[j];
  return acc;
}

// Four independent sequential_dot()s at once: the same sums in the same order, but four
// dependency chains in flight instead of one.
void sequential_dot4(const double* const x[4], const double* const y[4], Index n, double out[4]) {
  if (n == 0) {
    out[0] = out[1] = out[2] = out[3] = 0.0;
    return;
  }
  double a0 = x[0][0] * y[0][0], a1 = x[1][0] * y[1][0];
  double a2 = x[2][0] * y[2][0], a3 = x[3][0] * y[3][0];
  for (Index j = 1; j < n; ++j) {
    a0 += x[0][j] * y[0][j];
    a1 += x[1][j] * y[1][j];
    a2 += x[2][j] * y[2][j];
    a3 += x[3][j] * y[3][j];
  }
  out[0] = a0;
  out[1] = a1;
  out[2] = a2;
  out[3] = a3;
}

}  // namespace

LaSympNet::LaSympNet(Index d, Index layers, Index sublayers, Index step_terms)
    : SymplecticCore(d), layers_(layers), sublayers_(sublayers), step_terms_(step_terms) {
  require(layers >= 1,
          [&] { return "la core: layers = " + std::to_string(layers) + ", expected >= 1"; });
  require(sublayers >= 1,
          [&] { return "la core: sublayers = " + std::to_string(sublayers) + ", expected >= 1"; });
  require(step_terms == 1 || step_terms == 2, [&] {
    return "la core: step_terms = " + std::to_string(step_terms) + ", expected 1 or 2";
  });
}

Index LaSympNet::n_layer_params() const {
  const Index dd = d();
  return layers_ * (sublayers_ * dd * dd + 2 * dd) + (layers_ - 1) * dd;
}

Index LaSympNet::n_params() const {
  return n_layer_params() + (step_terms_ == 2 ? layers_ * sublayers_ + layers_ - 1 : 0);
}

const Vector& LaSympNet::unit_step(ConstParams theta, Index coef, const Vector& h,
                                   Vector& buf) const {
  if (step_terms_ == 1) return h;
  const double c = theta(coef);
  buf = h.array() * (1.0 + c * h.array());
  return buf;
}

double LaSympNet::unit_step(ConstParams theta, Index coef, double h) const {
  return step_terms_ == 1 ? h : h * (1.0 + theta(coef) * h);
}

void LaSympNet::init_params(Rng& rng, ParamsRef theta) const {
  require(theta.size() == n_params(), [&] {
    return "la::init_params: theta has " + std::to_string(theta.size()) + " entries, expected " +
           std::to_string(n_params());
  });
  const Index dd = d();
  Index off = 0;
  for (Index k = 0; k < layers_; ++k) {
    for (Index i = 0; i < sublayers_ * dd * dd; ++i) theta(off++) = kInitStddev * rng.normal();
    theta.segment(off, 2 * dd).setZero();
    off += 2 * dd;
    if (k + 1 < layers_) {
      for (Index i = 0; i < dd; ++i) theta(off++) = kInitStddev * rng.normal();
    }
  }
  theta.tail(n_params() - n_layer_params()).setZero();  // step coefficients: τ = h
}

nlohmann::json LaSympNet::core_spec() const {
  nlohmann::json spec = {{"type", "la"}, {"layers", layers_}, {"sublayers", sublayers_}};
  if (step_terms_ != 1) spec["step_terms"] = step_terms_;  // absent: the paper's core
  return spec;
}

std::size_t LaSympNet::recorded_steps() const {
  // One input per linear sublayer, one σ value per activation module.
  return static_cast<std::size_t>(layers_ * sublayers_ + layers_ - 1);
}

LaSympNet::FlowContext& LaSympNet::flow_context(ForwardCache& flow_cache) const {
  auto& ctx = flow_cache.make_context<FlowContext>();
  ctx.steps.resize(recorded_steps());
  return ctx;
}

const LaSympNet::FlowContext& LaSympNet::recorded(const ForwardCache& flow_cache,
                                                  const char* reader) const {
  const auto& ctx = flow_cache.context<FlowContext>(reader);
  require(ctx.steps.size() == recorded_steps(), [&] {
    return std::string(reader) + ": the cache holds a flow of " + std::to_string(ctx.steps.size()) +
           " recorded steps, this core records " + std::to_string(recorded_steps());
  });
  return ctx;
}

void LaSympNet::flow(ConstParams theta, Matrix& q, Matrix& p, const Vector& h,
                     ForwardCache* flow_cache) const {
  if (d() == 1) {
    flow_d1(theta, q, p, h, flow_cache);
  } else {
    SymplecticCore::flow(theta, q, p, h, flow_cache);
  }
}

void LaSympNet::flow_backward(ConstParams theta, const ForwardCache& flow_cache, const Vector& h,
                              Matrix& gq, Matrix& gp, ParamsRef grad) const {
  const FlowContext& ctx = recorded(flow_cache, "la::flow_backward");
  if (d() == 1) {
    flow_backward_d1(theta, ctx, h, gq, gp, grad);
  } else {
    flow_backward_batch(theta, ctx, h, gq, gp, grad);
  }
}

kernels::D1Core LaSympNet::d1_core() const {
  return {layers_, sublayers_, step_terms_ == 2, n_layer_params()};
}

void LaSympNet::flow_d1(ConstParams theta, Matrix& q, Matrix& p, const Vector& h,
                        ForwardCache* flow_cache) const {
  FlowContext* ctx = flow_cache != nullptr ? &flow_context(*flow_cache) : nullptr;
  if (kernels::d1_flow_simd(d1_core(), theta.data(), q.data(), p.data(), h.data(), q.cols(),
                            ctx != nullptr ? ctx->steps.data() : nullptr)) {
    return;
  }
  flow_d1_rows(theta, q, p, h, ctx);
}

void LaSympNet::flow_backward_d1(ConstParams theta, const FlowContext& ctx, const Vector& h,
                                 Matrix& gq, Matrix& gp, ParamsRef grad) const {
  if (kernels::d1_backward_simd(d1_core(), theta.data(), ctx.steps.data(), h.data(), gq.cols(),
                                gq.data(), gp.data(), grad.data())) {
    return;
  }
  flow_backward_d1_rows(theta, ctx, h, gq, gp, grad);
}

// d = 1: each S is the scalar 2A and q, p are single rows of N values. The general path's
// operations, per element and in the same order, without its d x d products and temporaries,
// so the results are bit-identical to it.
void LaSympNet::flow_d1_rows(ConstParams theta, Matrix& q, Matrix& p, const Vector& h,
                             FlowContext* ctx) const {
  if (d() != 1) throw Error("la::flow_d1_rows: d = " + std::to_string(d()) + ", expected 1");
  const Index n = q.cols();
  const auto hrow = ConstRowMap(h.data(), n).array();
  // The recorded steps in application order (sized by the caller).
  Matrix* step = ctx != nullptr ? ctx->steps.data() : nullptr;
  Matrix sig_local;
  Vector tau_buf;
  for (Index k = 0; k < layers_; ++k) {
    Index off = module_offset(k);
    for (Index i = 0; i < sublayers_; ++i, ++off) {
      const bool kick = i % 2 == 0;
      const Matrix& src = kick ? q : p;
      Matrix& dst = kick ? p : q;
      if (step != nullptr) *step++ = src;
      const double s = theta(off) + theta(off);
      const auto trow =
          ConstRowMap(unit_step(theta, shear_coef(k, i), h, tau_buf).data(), n).array();
      // kick p += h S q / drift q += h S p
      RowMap(dst.data(), n).array() += (s * ConstRowMap(src.data(), n).array()) * trow;
    }
    RowMap(p.data(), n).array() += hrow * theta(off);
    RowMap(q.data(), n).array() += hrow * theta(off + 1);
    if (k + 1 < layers_) {
      const bool kick = k % 2 == 0;
      const Matrix& src = kick ? q : p;
      Matrix& dst = kick ? p : q;
      Matrix& sig = step != nullptr ? *step++ : sig_local;
      sigmoid_into(src, sig);
      const double a = theta(off + 2);
      const auto trow = ConstRowMap(unit_step(theta, act_coef(k), h, tau_buf).data(), n).array();
      // kick p += h a σ(q)
      RowMap(dst.data(), n).array() += (ConstRowMap(sig.data(), n).array() * a) * trow;
    }
  }
}

void LaSympNet::flow_backward_d1_rows(ConstParams theta, const FlowContext& ctx, const Vector& h,
                                      Matrix& gq, Matrix& gp, ParamsRef grad) const {
  if (d() != 1) {
    throw Error("la::flow_backward_d1_rows: d = " + std::to_string(d()) + ", expected 1");
  }
  const Index n = gq.cols();
  const Index n_shears = layers_ * sublayers_;
  Vector tau_buf;
  const bool poly = step_terms_ == 2;
  const Vector h2 = poly ? Vector(h.array().square()) : Vector();
  // The shear gradients ∂A = 2 Σ_j (g_dst,j h_j) src_j feed nothing else in the sweep, so the
  // sweep only records g_dst h per shear (column `t` of gh) and the sums run at the end, four
  // at a time.
  Matrix gh(n, n_shears + 1);  // the last column is scratch for the activation modules
  std::vector<const double*> shear_src(static_cast<std::size_t>(n_shears));
  std::vector<Index> shear_off(static_cast<std::size_t>(n_shears));
  // The recorded steps, walked back from the last.
  const Matrix* step = ctx.steps.data() + ctx.steps.size();
  Index t = n_shears;
  for (Index k = layers_ - 1; k >= 0; --k) {
    const Index base = module_offset(k);
    const Index bias = base + sublayers_;
    if (k + 1 < layers_) {
      const bool kick = k % 2 == 0;
      Matrix& gsrc = kick ? gq : gp;
      const Matrix& gdst = kick ? gp : gq;
      const Matrix& sig = *--step;
      const double a = theta(bias + 2);
      if (poly) {
        const auto gd = ConstRowMap(gdst.data(), n).array();
        grad(act_coef(k)) +=
            a * (gd * ConstRowMap(sig.data(), n).array() * ConstRowMap(h2.data(), n).array()).sum();
      }
      RowMap g(gh.col(n_shears).data(), n);
      g.array() = ConstRowMap(gdst.data(), n).array() *
                  ConstRowMap(unit_step(theta, act_coef(k), h, tau_buf).data(), n).array();
      grad(bias + 2) += sequential_dot(g.data(), sig.data(), n);
      const auto s = ConstRowMap(sig.data(), n).array();
      RowMap(gsrc.data(), n).array() += ((g.array() * s) * (1.0 - s)) * a;
    }
    grad(bias) += sequential_dot(gp.data(), h.data(), n);
    grad(bias + 1) += sequential_dot(gq.data(), h.data(), n);
    for (Index i = sublayers_ - 1; i >= 0; --i) {
      const bool kick = i % 2 == 0;
      Matrix& gsrc = kick ? gq : gp;
      const Matrix& gdst = kick ? gp : gq;
      --t;
      shear_src[static_cast<std::size_t>(t)] = (--step)->data();
      shear_off[static_cast<std::size_t>(t)] = base + i;
      const double s = theta(base + i) + theta(base + i);
      if (poly) {
        const auto gd = ConstRowMap(gdst.data(), n).array();
        grad(shear_coef(k, i)) +=
            s * (gd * ConstRowMap(shear_src[static_cast<std::size_t>(t)], n).array() *
                 ConstRowMap(h2.data(), n).array())
                    .sum();
      }
      RowMap g(gh.col(t).data(), n);
      g.array() = ConstRowMap(gdst.data(), n).array() *
                  ConstRowMap(unit_step(theta, shear_coef(k, i), h, tau_buf).data(), n).array();
      RowMap(gsrc.data(), n).array() += s * g.array();
    }
  }
  // ∂A += M + Mᵀ with M = Σ_j (g_dst h)_j src_j.
  auto add_shear = [&](Index u, double m) {
    grad(shear_off[static_cast<std::size_t>(u)]) += m + m;
  };
  Index u = 0;
  for (; u + 4 <= n_shears; u += 4) {
    const double* x[4] = {gh.col(u).data(), gh.col(u + 1).data(), gh.col(u + 2).data(),
                          gh.col(u + 3).data()};
    const double* y[4];
    for (int r = 0; r < 4; ++r) y[r] = shear_src[static_cast<std::size_t>(u + r)];
    double m[4];
    sequential_dot4(x, y, n, m);
    for (int r = 0; r < 4; ++r) add_shear(u + r, m[r]);
  }
  for (; u < n_shears; ++u) {
    add_shear(u, sequential_dot(gh.col(u).data(), shear_src[static_cast<std::size_t>(u)], n));
  }
}

void LaSympNet::flow_tangent(ConstParams theta, Vector& q, Vector& p, Matrix& tq, Matrix& tp,
                             double h) const {
  const Index dd = d();
  Matrix s(dd, dd);
  for (Index k = 0; k < layers_; ++k) {
    Index off = module_offset(k);
    for (Index i = 0; i < sublayers_; ++i, off += dd * dd) {
      symmetric_from(theta, off, dd, s);
      const double tau = unit_step(theta, shear_coef(k, i), h);
      if (i % 2 == 0) {
        p.noalias() += tau * (s * q);
        tp.noalias() += tau * (s * tq);
      } else {
        q.noalias() += tau * (s * p);
        tq.noalias() += tau * (s * tp);
      }
    }
    p += h * theta.segment(off, dd);
    q += h * theta.segment(off + dd, dd);
    if (k + 1 < layers_) {
      // D(h a ⊙ σ(x)) = h diag(a ⊙ σ'(x)).
      const bool kick = k % 2 == 0;
      const Vector& src = kick ? q : p;
      Vector& dst = kick ? p : q;
      const Matrix& tsrc = kick ? tq : tp;
      Matrix& tdst = kick ? tp : tq;
      const auto a = theta.segment(off + 2 * dd, dd).array();
      const double tau = unit_step(theta, act_coef(k), h);
      const Vector sig = src.unaryExpr([](double v) { return sigmoid(v); });
      const Vector slope = tau * a * sig.array() * (1.0 - sig.array());
      tdst += slope.asDiagonal() * tsrc;
      dst.array() += tau * a * sig.array();
    }
  }
}

}  // namespace csympnet
