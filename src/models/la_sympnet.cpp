#include "csympnet/models/la_sympnet.hpp"

#include "csympnet/core/error.hpp"
#include "csympnet/models/activation.hpp"

namespace csympnet {

namespace {

using ConstMatrixMap = Eigen::Map<const Matrix>;
using MatrixMap = Eigen::Map<Matrix>;

// S = A + Aᵀ for the d x d block of θ at `offset`.
void symmetric_from(ConstParams theta, Index offset, Index d, Matrix& s) {
  const ConstMatrixMap a(theta.data() + offset, d, d);
  s = a + a.transpose();
}

}  // namespace

LaSympNet::LaSympNet(Index d, Index layers, Index sublayers)
    : SymplecticCore(d), layers_(layers), sublayers_(sublayers) {
  require(layers >= 1, "la core: layers = " + std::to_string(layers) + ", expected >= 1");
  require(sublayers >= 1, "la core: sublayers = " + std::to_string(sublayers) + ", expected >= 1");
}

Index LaSympNet::n_params() const {
  const Index dd = d();
  return layers_ * (sublayers_ * dd * dd + 2 * dd) + (layers_ - 1) * dd;
}

void LaSympNet::init_params(Rng& rng, ParamsRef theta) const {
  require(theta.size() == n_params(), "la::init_params: theta has " + std::to_string(theta.size()) +
                                          " entries, expected " + std::to_string(n_params()));
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
}

nlohmann::json LaSympNet::core_spec() const {
  return {{"type", "la"}, {"layers", layers_}, {"sublayers", sublayers_}};
}

std::size_t LaSympNet::cache_slots() const {
  // One input per linear sublayer, one σ value per activation module.
  return static_cast<std::size_t>(layers_ * sublayers_ + layers_ - 1);
}

void LaSympNet::flow(ConstParams theta, Matrix& q, Matrix& p, const Vector& h, ForwardCache* cache,
                     std::size_t slot0) const {
  const Index dd = d();
  const auto hrow = h.transpose().array();
  Matrix s(dd, dd);
  Matrix inc(dd, q.cols());
  Matrix sig_local;
  std::size_t slot = slot0;
  if (cache != nullptr) reserve_slots(*cache, slot0 + cache_slots());
  for (Index k = 0; k < layers_; ++k) {
    Index off = module_offset(k);
    for (Index i = 0; i < sublayers_; ++i, off += dd * dd) {
      const bool kick = i % 2 == 0;
      const Matrix& src = kick ? q : p;
      Matrix& dst = kick ? p : q;
      if (cache != nullptr) cache->mats[slot++] = src;
      symmetric_from(theta, off, dd, s);
      product_into(s, src, inc);
      dst.array() += inc.array().rowwise() * hrow;  // kick p += h S q / drift q += h S p
    }
    p.noalias() += theta.segment(off, dd) * h.transpose();
    q.noalias() += theta.segment(off + dd, dd) * h.transpose();
    if (k + 1 < layers_) {
      const bool kick = k % 2 == 0;
      const Matrix& src = kick ? q : p;
      Matrix& dst = kick ? p : q;
      Matrix& sig = cache != nullptr ? cache->mats[slot++] : sig_local;
      sigmoid_into(src, sig);
      const auto a = theta.segment(off + 2 * dd, dd).array();
      dst.array() += (sig.array().colwise() * a).rowwise() * hrow;  // kick p += h a ⊙ σ(q)
    }
  }
}

void LaSympNet::flow_backward(ConstParams theta, const ForwardCache& cache, std::size_t slot0,
                              const Vector& h, Matrix& gq, Matrix& gp, ParamsRef grad) const {
  const Index dd = d();
  const auto hrow = h.transpose().array();
  Matrix s(dd, dd);
  Matrix gh(dd, gq.cols());  // upstream gradient of the updated variable, times h per column
  Matrix sg(dd, gq.cols());
  Matrix outer(dd, dd);
  std::size_t slot = slot0 + cache_slots();
  for (Index k = layers_ - 1; k >= 0; --k) {
    const Index base = module_offset(k);
    const Index bias = base + sublayers_ * dd * dd;
    if (k + 1 < layers_) {
      // dst += h a ⊙ σ(src):  da = Σ_j h_j g_dst ⊙ σ,  g_src += h a ⊙ σ' ⊙ g_dst.
      const bool kick = k % 2 == 0;
      Matrix& gsrc = kick ? gq : gp;
      const Matrix& gdst = kick ? gp : gq;
      const Matrix& sig = cache.mats[--slot];
      const auto a = theta.segment(bias + 2 * dd, dd).array();
      gh = (gdst.array().rowwise() * hrow).matrix();
      grad.segment(bias + 2 * dd, dd).array() += (gh.array() * sig.array()).rowwise().sum();
      gsrc.array() += (gh.array() * sig.array() * (1.0 - sig.array())).colwise() * a;
    }
    // p += h b_p, q += h b_q:  db = G h.
    grad.segment(bias, dd).noalias() += gp * h;
    grad.segment(bias + dd, dd).noalias() += gq * h;
    for (Index i = sublayers_ - 1; i >= 0; --i) {
      // dst += S src H:  dS = (G_dst H) srcᵀ, dA = dS + dSᵀ,  g_src += S (G_dst H).
      const bool kick = i % 2 == 0;
      Matrix& gsrc = kick ? gq : gp;
      const Matrix& gdst = kick ? gp : gq;
      const Matrix& src = cache.mats[--slot];
      const Index off = base + i * dd * dd;
      gh = (gdst.array().rowwise() * hrow).matrix();
      product_into(gh, src.transpose(), outer);
      MatrixMap ga(grad.data() + off, dd, dd);
      ga += outer + outer.transpose();
      symmetric_from(theta, off, dd, s);
      product_into(s, gh, sg);
      gsrc += sg;
    }
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
      if (i % 2 == 0) {
        p.noalias() += h * (s * q);
        tp.noalias() += h * (s * tq);
      } else {
        q.noalias() += h * (s * p);
        tq.noalias() += h * (s * tp);
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
      const Vector sig = src.unaryExpr([](double v) { return sigmoid(v); });
      const Vector slope = h * a * sig.array() * (1.0 - sig.array());
      tdst += slope.asDiagonal() * tsrc;
      dst.array() += h * a * sig.array();
    }
  }
}

}  // namespace csympnet
