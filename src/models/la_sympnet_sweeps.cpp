// LA-SympNet at d > 1 (la_sympnet.hpp): the forward sweep and the backward sweep on a range of
// batch columns, and the parameter sums over all columns. The serial flow() and
// flow_backward() and the column-split passes (column_split.hpp) are made of the same steps,
// so they agree to the bit: the split only changes where a unit's intermediates are kept
// (records in the cache, filled range by range) and when its parameter step runs.
#include <vector>

#include "../kernels/column_scaling.hpp"
#include "activation.hpp"
#include "core_product.hpp"
#include "csympnet/core/error.hpp"
#include "la_sympnet.hpp"

namespace csympnet {

using detail::symmetric_from;

struct LaSympNet::Unit {
  enum class Kind { kActivation, kBias, kShear };
  Kind kind;
  Index k;           // linear module
  Index i;           // shear within it (kShear)
  std::size_t step;  // its σ (kActivation) or its input (kShear) in FlowContext::steps
  // Whether the update it reverses is a kick (it changes p; its gradient flows into g_q).
  bool kick() const { return (kind == Kind::kShear ? i : k) % 2 == 0; }
};

// What a unit's parameter step reads: gh = g_dst ⊙ τ (activation, shear), and g1 = g_dst
// (with step polynomials) or g1, g2 = g_p, g_q (biases) as the sweep step found them. With
// `copy` these are records that the sweep step fills on its columns; without, g1 and g2 are
// the live gradients, read before any later unit changes them.
struct LaSympNet::UnitRecords {
  Matrix* gh = nullptr;
  Matrix* g1 = nullptr;
  Matrix* g2 = nullptr;
  bool copy = false;
};

void LaSympNet::require_batch_core(const char* what) const {
  if (d() == 1) throw Error(std::string("la::") + what + ": the column passes need d > 1");
}

std::vector<LaSympNet::Unit> LaSympNet::backward_units() const {
  std::vector<Unit> units;
  // The recorded steps are in application order; the units walk them back from the last.
  std::size_t step = recorded_steps();
  for (Index k = layers_ - 1; k >= 0; --k) {
    if (k + 1 < layers_) units.push_back({Unit::Kind::kActivation, k, 0, --step});
    units.push_back({Unit::Kind::kBias, k, 0, 0});
    for (Index i = sublayers_ - 1; i >= 0; --i) units.push_back({Unit::Kind::kShear, k, i, --step});
  }
  return units;
}

void LaSympNet::size_flow(ForwardCache& flow_cache, Index n, bool records) const {
  FlowContext& ctx = flow_context(flow_cache);
  for (Matrix& step : ctx.steps) step.resize(d(), n);
  if (records) {
    const std::vector<Unit> units = backward_units();
    ctx.records.resize(units.size());
    for (std::size_t r = 0; r < units.size(); ++r) {
      FlowContext::SweepRecords& rec = ctx.records[r];
      if (units[r].kind == Unit::Kind::kBias) {
        rec.gp.resize(d(), n);
        rec.gq.resize(d(), n);
      } else {
        rec.gh.resize(d(), n);
        if (step_terms_ == 2) rec.g_dst.resize(d(), n);
      }
    }
  }
}

bool LaSympNet::splits_columns(Index n, const std::vector<Columns>& ranges) const {
  if (d() == 1 || !ranges_tile(n, ranges)) return false;
  // The sweeps' only products with the columns as their n: S X (forward) and S G (backward).
  if (!kernels::product_kernel_covers(d(), d(), n)) return false;
  for (const Columns& c : ranges) {
    if (!kernels::product_kernel_covers(d(), d(), c.size())) return false;
  }
  return true;
}

const double* LaSympNet::unit_step_columns(ConstParams theta, Index coef, const Vector& h,
                                           Columns cols, Vector& buf) const {
  const auto hc = h.segment(cols.begin, cols.size());
  if (step_terms_ == 1) return hc.data();
  const double c = theta(coef);
  buf = hc.array() * (1.0 + c * hc.array());
  return buf.data();
}

void LaSympNet::flow_columns(ConstParams theta, Matrix& q, Matrix& p, const Vector& h,
                             ForwardCache* flow_cache, Columns cols) const {
  require_batch_core("flow_columns");
  // Sized by size_flow(): this only looks the context up (the ranges run in parallel).
  Matrix* step = flow_cache != nullptr
                     ? flow_cache->context<FlowContext>("la::flow_columns").steps.data()
                     : nullptr;
  const Index dd = d();
  const Index c0 = cols.begin;
  const Index n = cols.size();
  Matrix s(dd, dd);
  Matrix scratch;
  Matrix sig_local;
  Vector tau_buf;
  for (Index k = 0; k < layers_; ++k) {
    Index off = module_offset(k);
    for (Index i = 0; i < sublayers_; ++i, off += dd * dd) {
      const bool kick = i % 2 == 0;
      const auto src = (kick ? q : p).middleCols(c0, n);
      auto dst = (kick ? p : q).middleCols(c0, n);
      if (step != nullptr) kernels::copy_columns(src, (step++)->middleCols(c0, n));
      symmetric_from(theta, off, dd, s);
      const double* tau = unit_step_columns(theta, shear_coef(k, i), h, cols, tau_buf);
      detail::core_product_add_scaled(s, src, tau, dst,
                                      scratch);  // kick p += h S q / drift q += h S p
    }
    kernels::add_outer(theta.data() + off, h.data() + c0, p.middleCols(c0, n));  // p += h b_p
    kernels::add_outer(theta.data() + off + dd, h.data() + c0, q.middleCols(c0, n));
    if (k + 1 < layers_) {
      const bool kick = k % 2 == 0;
      const auto src = (kick ? q : p).middleCols(c0, n);
      auto dst = (kick ? p : q).middleCols(c0, n);
      const auto a = theta.segment(off + 2 * dd, dd).array();
      const double* tau = unit_step_columns(theta, act_coef(k), h, cols, tau_buf);
      // kick p += h a ⊙ σ(q)
      if (step != nullptr) {
        auto sig = (step++)->middleCols(c0, n);
        sigmoid_to(src, sig);
        kernels::add_columns_times_scaled(sig, a.data(), tau, dst);
      } else {
        sigmoid_into(src, sig_local);
        kernels::add_columns_times_scaled(sig_local, a.data(), tau, dst);
      }
    }
  }
}

void LaSympNet::sweep_unit(ConstParams theta, const Unit& u, const FlowContext& ctx,
                           const Vector& h, Matrix& gq, Matrix& gp, Columns cols,
                           const UnitRecords& out) const {
  const Index dd = d();
  const Index c0 = cols.begin;
  const Index n = cols.size();
  if (u.kind == Unit::Kind::kBias) {
    // p += h b_p, q += h b_q leave the input gradients as they are.
    if (out.copy) {
      out.g1->middleCols(c0, n) = gp.middleCols(c0, n);
      out.g2->middleCols(c0, n) = gq.middleCols(c0, n);
    }
    return;
  }
  auto gsrc = (u.kick() ? gq : gp).middleCols(c0, n);
  const auto gdst = (u.kick() ? gp : gq).middleCols(c0, n);
  if (out.copy && step_terms_ == 2) out.g1->middleCols(c0, n) = gdst;
  const bool act = u.kind == Unit::Kind::kActivation;
  Vector tau_buf;
  const Index coef = act ? act_coef(u.k) : shear_coef(u.k, u.i);
  auto gh = out.gh->middleCols(c0, n);
  kernels::columns_times(gdst, unit_step_columns(theta, coef, h, cols, tau_buf), gh);
  if (act) {
    // dst += h a ⊙ σ(src):  g_src += h a ⊙ σ' ⊙ g_dst.
    const auto sig = ctx.steps[u.step].middleCols(c0, n);
    const auto a = theta.segment(module_offset(u.k) + sublayers_ * dd * dd + 2 * dd, dd).array();
    gsrc.array() += (gh.array() * sig.array() * (1.0 - sig.array())).colwise() * a;
  } else {
    // dst += S src H:  g_src += S (G_dst H).
    Matrix s(dd, dd);
    Matrix scratch;
    symmetric_from(theta, module_offset(u.k) + u.i * dd * dd, dd, s);
    detail::core_product_add(s, gh, gsrc, scratch);
  }
}

void LaSympNet::params_unit(ConstParams theta, const Unit& u, const FlowContext& ctx,
                            const Vector& h, const Vector& h2, const UnitRecords& in,
                            ParamsRef grad) const {
  const Index dd = d();
  const Index bias = module_offset(u.k) + sublayers_ * dd * dd;
  const bool poly = step_terms_ == 2;
  switch (u.kind) {
    case Unit::Kind::kBias:
      // p += h b_p, q += h b_q:  db = G h.
      grad.segment(bias, dd).noalias() += *in.g1 * h;
      grad.segment(bias + dd, dd).noalias() += *in.g2 * h;
      return;
    case Unit::Kind::kActivation: {
      // da = Σ_j h_j g_dst ⊙ σ; with step polynomials dc = Σ_j h_j² g_dst,j · (a ⊙ σ_j).
      const Matrix& sig = ctx.steps[u.step];
      const auto a = theta.segment(bias + 2 * dd, dd).array();
      if (poly)
        grad(act_coef(u.k)) +=
            ((in.g1->array() * sig.array()).colwise() * a).colwise().sum().matrix().dot(h2);
      grad.segment(bias + 2 * dd, dd).array() += (in.gh->array() * sig.array()).rowwise().sum();
      return;
    }
    case Unit::Kind::kShear: {
      // dS = (G_dst H) srcᵀ, dA = dS + dSᵀ; with step polynomials dc = Σ_j h_j² g_dst,j · (S
      // src_j).
      const Matrix& src = ctx.steps[u.step];
      const Index off = module_offset(u.k) + u.i * dd * dd;
      if (poly) {
        Matrix s(dd, dd);
        symmetric_from(theta, off, dd, s);
        grad(shear_coef(u.k, u.i)) +=
            (in.g1->array() * (s * src).array()).colwise().sum().matrix().dot(h2);
      }
      Matrix outer(dd, dd);
      detail::core_product(*in.gh, src.transpose(), outer);
      Eigen::Map<Matrix> ga(grad.data() + off, dd, dd);
      ga += outer + outer.transpose();
      return;
    }
  }
}

namespace {

// What a unit's steps read and write among its records in the flow context.
template <typename Unit, typename Records>
auto records_of(const Unit& u, bool poly, Records& rec) {
  struct {
    Matrix* gh = nullptr;
    Matrix* g1 = nullptr;
    Matrix* g2 = nullptr;
  } out;
  if (u.kind == Unit::Kind::kBias) {
    out.g1 = &rec.gp;
    out.g2 = &rec.gq;
  } else {
    out.gh = &rec.gh;
    if (poly) out.g1 = &rec.g_dst;
  }
  return out;
}

}  // namespace

void LaSympNet::backward_columns(ConstParams theta, const ForwardCache& flow_cache, const Vector& h,
                                 Matrix& gq, Matrix& gp, Columns cols) const {
  require_batch_core("backward_columns");
  const FlowContext& ctx = recorded(flow_cache, "la::backward_columns");
  const std::vector<Unit> units = backward_units();
  for (std::size_t r = 0; r < units.size(); ++r) {
    const auto rec = records_of(units[r], step_terms_ == 2, ctx.records[r]);
    sweep_unit(theta, units[r], ctx, h, gq, gp, cols, {rec.gh, rec.g1, rec.g2, true});
  }
}

void LaSympNet::backward_params(ConstParams theta, const ForwardCache& flow_cache, const Vector& h,
                                ParamsRef grad, Share share) const {
  require_batch_core("backward_params");
  const FlowContext& ctx = recorded(flow_cache, "la::backward_params");
  const Vector h2 = step_terms_ == 2 ? Vector(h.array().square()) : Vector();
  // Shears are dealt to the shares in turn, and so, separately, are the cheap units.
  Index shears = 0;
  Index others = 0;
  const std::vector<Unit> units = backward_units();
  for (std::size_t r = 0; r < units.size(); ++r) {
    const Unit& u = units[r];
    const auto rec = records_of(u, step_terms_ == 2, ctx.records[r]);
    const bool mine = share.owns(u.kind == Unit::Kind::kShear ? shears++ : others++);
    if (mine) params_unit(theta, u, ctx, h, h2, {rec.gh, rec.g1, rec.g2, true}, grad);
  }
}

void LaSympNet::flow_backward_batch(ConstParams theta, const FlowContext& ctx, const Vector& h,
                                    Matrix& gq, Matrix& gp, ParamsRef grad) const {
  const Index n = gq.cols();
  const Vector h2 = step_terms_ == 2 ? Vector(h.array().square()) : Vector();
  Matrix gh(d(), n);
  for (const Unit& u : backward_units()) {
    UnitRecords live{&gh, &gp, &gq, false};
    if (u.kind != Unit::Kind::kBias) live.g1 = u.kick() ? &gp : &gq;  // g_dst
    sweep_unit(theta, u, ctx, h, gq, gp, {0, n}, live);
    params_unit(theta, u, ctx, h, h2, live, grad);
  }
}

}  // namespace csympnet
