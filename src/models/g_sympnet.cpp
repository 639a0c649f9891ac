#include "g_sympnet.hpp"

#include "../kernels/column_scaling.hpp"
#include "activation.hpp"
#include "core_product.hpp"
#include "csympnet/core/error.hpp"

namespace csympnet {

GSympNet::GSympNet(Index d, Index layers, Index width)
    : SymplecticCore(d), layers_(layers), width_(width) {
  require(layers >= 1,
          [&] { return "g core: layers = " + std::to_string(layers) + ", expected >= 1"; });
  require(width >= 1,
          [&] { return "g core: width = " + std::to_string(width) + ", expected >= 1"; });
}

void GSympNet::init_params(Rng& rng, ParamsRef theta) const {
  require(theta.size() == n_params(), [&] {
    return "g::init_params: theta has " + std::to_string(theta.size()) + " entries, expected " +
           std::to_string(n_params());
  });
  Index off = 0;
  for (Index k = 0; k < layers_; ++k) {
    for (Index i = 0; i < width_ * (d() + 1); ++i) theta(off++) = kInitStddev * rng.normal();
    theta.segment(off, width_).setZero();
    off += width_;
  }
}

nlohmann::json GSympNet::core_spec() const {
  return {{"type", "g"}, {"layers", layers_}, {"width", width_}};
}

// The forward and backward sweeps work on a range of columns (the whole batch when serial);
// the parameter sums run over all columns, module by module (column_split.hpp).

void GSympNet::size_flow(ForwardCache& flow_cache, Index n, bool records) const {
  auto& ctx = flow_cache.make_context<FlowContext>();
  ctx.modules.resize(static_cast<std::size_t>(layers_));
  for (FlowContext::Module& m : ctx.modules) {
    m.input.resize(d(), n);
    m.sigma.resize(width_, n);
  }
  if (records) {
    ctx.records.resize(static_cast<std::size_t>(layers_));
    for (FlowContext::ModuleRecords& r : ctx.records) {
      r.g_dst_h.resize(d(), n);
      r.gy.resize(width_, n);
      r.gu.resize(width_, n);
    }
  }
}

const GSympNet::FlowContext& GSympNet::recorded(const ForwardCache& flow_cache,
                                                const char* reader) const {
  const auto& ctx = flow_cache.context<FlowContext>(reader);
  require(ctx.modules.size() == static_cast<std::size_t>(layers_), [&] {
    return std::string(reader) + ": the cache holds a flow of " +
           std::to_string(ctx.modules.size()) + " modules, this core has " +
           std::to_string(layers_);
  });
  return ctx;
}

bool GSympNet::splits_columns(Index n, const std::vector<Columns>& ranges) const {
  if (!ranges_tile(n, ranges)) return false;
  // The sweeps' products with the columns as their n: K X and Kᵀ U.
  auto covered = [this](Index cols) {
    return kernels::product_kernel_covers(width_, d(), cols) &&
           kernels::product_kernel_covers(d(), width_, cols);
  };
  if (!covered(n)) return false;
  for (const Columns& c : ranges) {
    if (!covered(c.size())) return false;
  }
  return true;
}

void GSympNet::flow_columns(ConstParams theta, Matrix& q, Matrix& p, const Vector& h,
                            ForwardCache* flow_cache, Columns cols) const {
  const Index dd = d();
  const Index c0 = cols.begin;
  const Index n = cols.size();
  // Sized by size_flow(): this only looks the context up (the ranges run in parallel).
  FlowContext* ctx =
      flow_cache != nullptr ? &flow_cache->context<FlowContext>("g::flow_columns") : nullptr;
  Matrix u(width_, n);
  Matrix sig_local;
  Matrix scratch;
  for (Index k = 0; k < layers_; ++k) {
    const Index off = module_offset(k);
    const Eigen::Map<const Matrix> kmat(theta.data() + off, width_, dd);
    const auto a = theta.segment(off + width_ * dd, width_).array();
    const auto b = theta.segment(off + width_ * (dd + 1), width_).array();
    const bool kick = k % 2 == 0;
    const auto src = (kick ? q : p).middleCols(c0, n);
    auto dst = (kick ? p : q).middleCols(c0, n);
    FlowContext::Module* rec =
        ctx != nullptr ? &ctx->modules[static_cast<std::size_t>(k)] : nullptr;
    if (rec != nullptr) kernels::copy_columns(src, rec->input.middleCols(c0, n));
    detail::core_product_to(kmat, src, u, scratch);
    u.array().colwise() += b;
    // u then holds (a ⊙ σ) scaled by h per column; kick: p += Kᵀ u.
    if (rec != nullptr) {
      auto sig = rec->sigma.middleCols(c0, n);
      sigmoid_to(u, sig);
      kernels::columns_times_scaled(sig, a.data(), h.data() + c0, u);
    } else {
      sigmoid_into(u, sig_local);
      kernels::columns_times_scaled(sig_local, a.data(), h.data() + c0, u);
    }
    detail::core_product_add(kmat.transpose(), u, dst, scratch);
  }
}

void GSympNet::sweep_module(ConstParams theta, Index k, const FlowContext::Module& rec,
                            const Vector& h, Matrix& gq, Matrix& gp, Columns cols,
                            FlowContext::ModuleRecords& out) const {
  const Index dd = d();
  const Index c0 = cols.begin;
  const Index n = cols.size();
  const Index off = module_offset(k);
  const Eigen::Map<const Matrix> kmat(theta.data() + off, width_, dd);
  const auto a = theta.segment(off + width_ * dd, width_).array();
  const bool kick = k % 2 == 0;
  auto gsrc = (kick ? gq : gp).middleCols(c0, n);
  const auto gdst = (kick ? gp : gq).middleCols(c0, n);
  const auto sig = rec.sigma.middleCols(c0, n);
  Matrix scratch;
  // dst += Kᵀ y H:  dy = K (G_dst H);  y = a ⊙ σ(u):  du = dy ⊙ a ⊙ σ(1 − σ);
  // u = K src + b:  g_src += Kᵀ du.
  auto ghc = out.g_dst_h.middleCols(c0, n);
  kernels::columns_times(gdst, h.data() + c0, ghc);
  auto gyc = out.gy.middleCols(c0, n);
  detail::core_product_to(kmat, ghc, gyc, scratch);
  auto guc = out.gu.middleCols(c0, n);
  guc = ((gyc.array() * sig.array() * (1.0 - sig.array())).colwise() * a).matrix();
  detail::core_product_add(kmat.transpose(), guc, gsrc, scratch);
}

void GSympNet::params_module(ConstParams theta, Index k, const FlowContext::Module& rec,
                             const FlowContext::ModuleRecords& in, ParamsRef grad) const {
  const Index dd = d();
  const Index off = module_offset(k);
  const auto a = theta.segment(off + width_ * dd, width_).array();
  const Matrix& src = rec.input;
  const Matrix& sig = rec.sigma;
  const Matrix& gh = in.g_dst_h;
  const Matrix& gy = in.gy;
  const Matrix& gu = in.gu;
  Eigen::Map<Matrix> grad_k(grad.data() + off, width_, dd);
  Matrix gk;
  // dK = y (G_dst H)ᵀ + du srcᵀ,  da = Σ_j dy ⊙ σ,  db = Σ_j du.
  const Matrix y = (sig.array().colwise() * a).matrix();
  detail::core_product_add(y, gh.transpose(), grad_k, gk);
  grad.segment(off + width_ * dd, width_).array() += (gy.array() * sig.array()).rowwise().sum();
  grad.segment(off + width_ * (dd + 1), width_) += gu.rowwise().sum();
  detail::core_product_add(gu, src.transpose(), grad_k, gk);
}

void GSympNet::flow_backward(ConstParams theta, const ForwardCache& flow_cache, const Vector& h,
                             Matrix& gq, Matrix& gp, ParamsRef grad) const {
  const FlowContext& ctx = recorded(flow_cache, "g::flow_backward");
  const Index n = gq.cols();
  // The serial pass keeps one module's sweep values at a time.
  FlowContext::ModuleRecords live{Matrix(d(), n), Matrix(width_, n), Matrix(width_, n)};
  for (Index k = layers_ - 1; k >= 0; --k) {
    const auto& rec = ctx.modules[static_cast<std::size_t>(k)];
    sweep_module(theta, k, rec, h, gq, gp, {0, n}, live);
    params_module(theta, k, rec, live, grad);
  }
}

void GSympNet::backward_columns(ConstParams theta, const ForwardCache& flow_cache, const Vector& h,
                                Matrix& gq, Matrix& gp, Columns cols) const {
  const FlowContext& ctx = recorded(flow_cache, "g::backward_columns");
  for (Index k = layers_ - 1; k >= 0; --k) {
    const auto m = static_cast<std::size_t>(k);
    sweep_module(theta, k, ctx.modules[m], h, gq, gp, cols, ctx.records[m]);
  }
}

void GSympNet::backward_params(ConstParams theta, const ForwardCache& flow_cache,
                               const Vector& /*h*/, ParamsRef grad, Share share) const {
  const FlowContext& ctx = recorded(flow_cache, "g::backward_params");
  for (Index k = layers_ - 1; k >= 0; --k) {
    if (!share.owns(layers_ - 1 - k)) continue;
    const auto m = static_cast<std::size_t>(k);
    params_module(theta, k, ctx.modules[m], ctx.records[m], grad);
  }
}

void GSympNet::flow_tangent(ConstParams theta, Vector& q, Vector& p, Matrix& tq, Matrix& tp,
                            double h) const {
  const Index dd = d();
  for (Index k = 0; k < layers_; ++k) {
    const Index off = module_offset(k);
    const Eigen::Map<const Matrix> kmat(theta.data() + off, width_, dd);
    const auto a = theta.segment(off + width_ * dd, width_).array();
    const auto b = theta.segment(off + width_ * (dd + 1), width_);
    const bool kick = k % 2 == 0;
    const Vector& src = kick ? q : p;
    Vector& dst = kick ? p : q;
    const Matrix& tsrc = kick ? tq : tp;
    Matrix& tdst = kick ? tp : tq;
    const Vector u = kmat * src + b;
    const Vector sig = u.unaryExpr([](double v) { return sigmoid(v); });
    // D(h Kᵀ(a ⊙ σ(K x + b))) = h Kᵀ diag(a ⊙ σ'(u)) K.
    const Vector slope = h * a * sig.array() * (1.0 - sig.array());
    const Matrix k_tsrc = kmat * tsrc;
    tdst.noalias() += kmat.transpose() * (slope.asDiagonal() * k_tsrc);
    dst.noalias() += kmat.transpose() * (h * a * sig.array()).matrix();
  }
}

}  // namespace csympnet
