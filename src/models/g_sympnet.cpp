#include "csympnet/models/g_sympnet.hpp"

#include "csympnet/core/error.hpp"
#include "csympnet/models/activation.hpp"
#include "exact_product.hpp"

namespace csympnet {

GSympNet::GSympNet(Index d, Index layers, Index width)
    : SymplecticCore(d), layers_(layers), width_(width) {
  require(layers >= 1, "g core: layers = " + std::to_string(layers) + ", expected >= 1");
  require(width >= 1, "g core: width = " + std::to_string(width) + ", expected >= 1");
}

void GSympNet::init_params(Rng& rng, ParamsRef theta) const {
  require(theta.size() == n_params(), "g::init_params: theta has " + std::to_string(theta.size()) +
                                          " entries, expected " + std::to_string(n_params()));
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

void GSympNet::flow(ConstParams theta, Matrix& q, Matrix& p, const Vector& h, ForwardCache* cache,
                    std::size_t slot0) const {
  const Index dd = d();
  const Index n = q.cols();
  Matrix u(width_, n);
  Matrix sig_local;
  Matrix inc(dd, n);
  std::size_t slot = slot0;
  if (cache != nullptr) reserve_slots(*cache, slot0 + cache_slots());
  for (Index k = 0; k < layers_; ++k) {
    const Index off = module_offset(k);
    const Eigen::Map<const Matrix> kmat(theta.data() + off, width_, dd);
    const auto a = theta.segment(off + width_ * dd, width_).array();
    const auto b = theta.segment(off + width_ * (dd + 1), width_).array();
    const bool kick = k % 2 == 0;
    const Matrix& src = kick ? q : p;
    Matrix& dst = kick ? p : q;
    if (cache != nullptr) cache->mats[slot++] = src;
    Matrix& sig = cache != nullptr ? cache->mats[slot++] : sig_local;
    detail::core_product(kmat, src, u);
    u.array().colwise() += b;
    sigmoid_into(u, sig);
    // u now holds (a ⊙ σ) scaled by h per column; kick: p += Kᵀ u.
    u.array() = (sig.array().colwise() * a).rowwise() * h.transpose().array();
    detail::core_product_add(kmat.transpose(), u, dst, inc);
  }
}

void GSympNet::flow_backward(ConstParams theta, const ForwardCache& cache, std::size_t slot0,
                             const Vector& h, Matrix& gq, Matrix& gp, ParamsRef grad) const {
  const Index dd = d();
  const Index n = gq.cols();
  Matrix gh(dd, n);        // G_dst H
  Matrix gy(width_, n);    // dL/dy for y = a ⊙ σ(u), then dL/du
  Matrix y(width_, n);     // a ⊙ σ(u)
  Matrix gk(width_, dd);   // dL/dK contributions
  Matrix gsrc_inc(dd, n);  // Kᵀ dL/du
  std::size_t slot = slot0 + cache_slots();
  for (Index k = layers_ - 1; k >= 0; --k) {
    const Index off = module_offset(k);
    const Eigen::Map<const Matrix> kmat(theta.data() + off, width_, dd);
    const auto a = theta.segment(off + width_ * dd, width_).array();
    Eigen::Map<Matrix> grad_k(grad.data() + off, width_, dd);
    const bool kick = k % 2 == 0;
    Matrix& gsrc = kick ? gq : gp;
    const Matrix& gdst = kick ? gp : gq;
    const Matrix& sig = cache.mats[--slot];
    const Matrix& src = cache.mats[--slot];
    // dst += Kᵀ y H:  dK = y (G_dst H)ᵀ, dy = K (G_dst H).
    gh = (gdst.array().rowwise() * h.transpose().array()).matrix();
    y = (sig.array().colwise() * a).matrix();
    detail::core_product_add(y, gh.transpose(), grad_k, gk);
    detail::core_product(kmat, gh, gy);
    // y = a ⊙ σ(u):  da = Σ_j dy ⊙ σ,  du = dy ⊙ a ⊙ σ(1 − σ).
    grad.segment(off + width_ * dd, width_).array() += (gy.array() * sig.array()).rowwise().sum();
    gy.array() = (gy.array() * sig.array() * (1.0 - sig.array())).colwise() * a;
    // u = K src + b:  db = Σ_j du,  dK += du srcᵀ,  g_src += Kᵀ du.
    grad.segment(off + width_ * (dd + 1), width_) += gy.rowwise().sum();
    detail::core_product_add(gy, src.transpose(), grad_k, gk);
    detail::core_product_add(kmat.transpose(), gy, gsrc, gsrc_inc);
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
