#include "csympnet/train/window_loss.hpp"
#include "csympnet/core/dense.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <string>

#include "csympnet/core/error.hpp"
#include "lapack.hpp"

namespace csympnet {

void WindowSet::validate(const std::string& where) const {
  require(m >= 1, [&] { return where + ": a window needs at least one step"; });
  require(z0.rows() > 0 && z0.rows() % 2 == 0,
          [&] { return where + ": states need an even number 2d > 0 of rows"; });
  require(zm.rows() == z0.rows() && zm.cols() == z0.cols(),
          [&] { return where + ": start and end states differ in shape"; });
  require(h.rows() == m && h.cols() == z0.cols(), [&] {
    return where + ": steps must be " + std::to_string(m) + " x " + std::to_string(z0.cols());
  });
  require(block.empty() || static_cast<Index>(block.size()) == z0.cols(),
          [&] { return where + ": need one block index per window"; });
  require(z0.allFinite() && zm.allFinite() && h.allFinite(),
          [&] { return where + ": non-finite value"; });
  require((h.array() > 0.0).all(), [&] { return where + ": every step must be > 0"; });
}

WindowSet windows_from_trajectories(const std::vector<Trajectory>& trajs, Index m,
                                    const std::vector<Index>& block_of) {
  require(m >= 1, [&] { return "windows: m must be >= 1, got " + std::to_string(m); });
  require(!trajs.empty(), "windows: no trajectories");
  require(block_of.empty() || block_of.size() == trajs.size(),
          "windows: need one block index per trajectory");
  Index n = 0;
  for (const Trajectory& t : trajs) n += std::max<Index>(0, t.steps() - m + 1);
  require(n >= 1, [&] { return "windows: no trajectory has " + std::to_string(m) + " steps"; });
  const Index dim = trajs.front().z.rows();
  WindowSet w;
  w.m = m;
  w.z0.resize(dim, n);
  w.zm.resize(dim, n);
  w.h.resize(m, n);
  w.block.reserve(static_cast<std::size_t>(n));
  Index col = 0;
  for (std::size_t k = 0; k < trajs.size(); ++k) {
    const Trajectory& t = trajs[k];
    require(t.z.rows() == dim, "windows: trajectories differ in dimension");
    for (Index s = 0; s + m <= t.steps(); ++s, ++col) {
      w.z0.col(col) = t.z.col(s);
      w.zm.col(col) = t.z.col(s + m);
      for (Index j = 0; j < m; ++j) w.h(j, col) = t.t(s + j + 1) - t.t(s + j);
      w.block.push_back(block_of.empty() ? static_cast<Index>(k) : block_of[k]);
    }
  }
  return w;
}

WindowSet windows_from_pairs(const PairSet& pairs, const std::vector<Index>& block) {
  require(block.empty() || static_cast<Index>(block.size()) == pairs.size(),
          "windows: need one block index per pair");
  WindowSet w;
  w.m = 1;
  w.z0 = pairs.z0;
  w.zm = pairs.z1;
  w.h = pairs.h.transpose();
  if (block.empty()) {
    w.block.resize(static_cast<std::size_t>(pairs.size()));
    for (Index j = 0; j < pairs.size(); ++j) w.block[static_cast<std::size_t>(j)] = j;
  } else {
    w.block = block;
  }
  return w;
}

WindowSet select_windows(const WindowSet& w, const std::vector<Index>& idx) {
  WindowSet s;
  s.m = w.m;
  const Index n = static_cast<Index>(idx.size());
  s.z0.resize(w.dim(), n);
  s.zm.resize(w.dim(), n);
  s.h.resize(w.m, n);
  for (Index j = 0; j < n; ++j) {
    const Index i = idx[static_cast<std::size_t>(j)];
    require(i >= 0 && i < w.size(), "select_windows: index out of range");
    s.z0.col(j) = w.z0.col(i);
    s.zm.col(j) = w.zm.col(i);
    s.h.col(j) = w.h.col(i);
    if (!w.block.empty()) s.block.push_back(w.block[static_cast<std::size_t>(i)]);
  }
  return s;
}

namespace {

void check(const OneStepMap& map, ConstParams theta, const WindowSet& w) {
  w.validate("windows");
  require(w.dim() == map.dim(), [&] {
    return "windows: data dimension " + std::to_string(w.dim()) + " does not match the model's " +
           std::to_string(map.dim());
  });
  require(theta.size() == map.n_params(), [&] {
    return "windows: parameter vector has size " + std::to_string(theta.size()) + ", expected " +
           std::to_string(map.n_params());
  });
}

// The balancing: γ̂ and sign(β) when it applies, else nothing.
struct Balance {
  bool on = false;
  double gamma = 0.0;
  double sign = 0.0;  // d γ̂ / d β
  Index beta = -1;
  double weight(double span) const { return on ? std::exp(0.5 * gamma * span) : 1.0; }
};

Balance balance_of(const OneStepMap& map, ConstParams theta, bool balanced) {
  Balance b;
  const auto gamma = map.damping_rate(theta);
  const auto index = map.damping_param_index();
  if (!balanced || !gamma || !index) return b;
  b.on = true;
  b.gamma = *gamma;
  b.beta = *index;
  const double beta = theta(*index);
  b.sign = beta > 0.0 ? 1.0 : (beta < 0.0 ? -1.0 : 0.0);
  return b;
}

// Runs the m steps of the windows `cols` (all when count < 0), keeping caches when asked.
Matrix roll(const OneStepMap& map, ConstParams theta, const WindowSet& w, Index first, Index count,
            std::vector<ForwardCache>* caches) {
  Matrix z = w.z0.middleCols(first, count);
  Vector h(count);
  for (Index k = 0; k < w.m; ++k) {
    h = w.h.row(k).segment(first, count).transpose();
    z = map.forward(theta, z, h,
                    caches != nullptr ? &(*caches)[static_cast<std::size_t>(k)] : nullptr);
  }
  return z;
}

}  // namespace

double window_loss(const OneStepMap& map, ConstParams theta, const WindowSet& w, bool balanced,
                   Vector* grad, std::vector<ForwardCache>* kept) {
  return window_loss_part(map, theta, w, balanced, w.size(), grad, kept);
}

double window_loss_part(const OneStepMap& map, ConstParams theta, const WindowSet& w, bool balanced,
                        Index total, Vector* grad, std::vector<ForwardCache>* kept) {
  check(map, theta, w);
  require(total >= w.size(), "window_loss_part: the total is below the windows given");
  const Balance bal = balance_of(map, theta, balanced);
  const Index n = w.size(), d = w.dim() / 2;
  std::vector<ForwardCache> local;
  std::vector<ForwardCache>& caches = kept != nullptr ? *kept : local;
  if (grad != nullptr && caches.size() != static_cast<std::size_t>(w.m))
    caches.resize(static_cast<std::size_t>(w.m));
  Matrix r = roll(map, theta, w, 0, n, grad != nullptr ? &caches : nullptr) - w.zm;
  const Vector span = w.span();
  double loss = 0.0, beta_term = 0.0;
  for (Index i = 0; i < n; ++i) {
    const double w2 = bal.on ? std::exp(bal.gamma * span(i)) : 1.0;
    const double p2 = r.col(i).tail(d).squaredNorm();
    loss += r.col(i).head(d).squaredNorm() + w2 * p2;
    beta_term += span(i) * w2 * p2;
  }
  const double inv_n = 1.0 / static_cast<double>(total);
  if (grad == nullptr) return loss * inv_n;
  grad->setZero(map.n_params());
  // dL/dΦ̂ᵐ = (2/N) W² r; then back through the m steps.
  for (Index i = 0; i < n; ++i) {
    r.col(i) *= 2.0 * inv_n;
    if (bal.on) r.col(i).tail(d) *= std::exp(bal.gamma * span(i));
  }
  Matrix dz_in;
  for (Index k = w.m - 1; k >= 0; --k) {
    map.backward(theta, caches[static_cast<std::size_t>(k)], r, *grad, k > 0 ? &dz_in : nullptr);
    if (k > 0) r.swap(dz_in);
  }
  // ∂(w²)/∂β = sign(β) H w², with r held fixed.
  if (bal.on) (*grad)(bal.beta) += bal.sign * beta_term * inv_n;
  return loss * inv_n;
}

Vector window_residuals(const OneStepMap& map, ConstParams theta, const WindowSet& w,
                        bool balanced) {
  check(map, theta, w);
  const Balance bal = balance_of(map, theta, balanced);
  const Index d = w.dim() / 2;
  Matrix r = roll(map, theta, w, 0, w.size(), nullptr) - w.zm;
  if (bal.on) {
    const Vector span = w.span();
    for (Index i = 0; i < w.size(); ++i) r.col(i).tail(d) *= bal.weight(span(i));
  }
  return Eigen::Map<const Vector>(r.data(), r.size());
}

void window_jacobian_rows(const OneStepMap& map, ConstParams theta, const WindowSet& w,
                          bool balanced, Index first, Index count, Eigen::Ref<RowMajorMatrix> jac,
                          Eigen::Ref<Vector> r) {
  check(map, theta, w);
  const Index dim = w.dim(), d = dim / 2, p = map.n_params();
  require(first >= 0 && count >= 0 && first + count <= w.size(),
          "window_jacobian_rows: windows out of range");
  require(jac.rows() == count * dim && jac.cols() == p && r.size() == count * dim, [&] {
    return "window_jacobian_rows: output must be " + std::to_string(count * dim) + " x " +
           std::to_string(p);
  });
  const Balance bal = balance_of(map, theta, balanced);
  // The residual's row k times its weight w_k, and ∂w/∂β = sign(β) (H/2) w times the
  // unweighted residual on a momentum row.
  const auto finish_row = [&](Index j, Index k, double span, double weight, double raw) {
    const bool p_row = k >= d;
    r(j * dim + k) = (p_row ? weight : 1.0) * raw;
    if (bal.on && p_row) jac(j * dim + k, bal.beta) += bal.sign * 0.5 * span * weight * raw;
  };
  if (map.has_step_tangents()) {
    // Forward mode: ∂z_m/∂θ carried along the window (OneStepMap::step_tangents), one pass per
    // window in place of one reverse pass per state component.
    Matrix t(dim, p);
    Vector z(dim);
    for (Index j = 0; j < count; ++j) {
      const Index i = first + j;
      t.setZero();
      z = w.z0.col(i);
      for (Index s = 0; s < w.m; ++s) map.step_tangents(theta, w.h(s, i), nullptr, z.data(), t, p);
      const double span = w.h.col(i).sum();
      const double weight = bal.weight(span);
      for (Index k = 0; k < dim; ++k) {
        jac.row(j * dim + k) = (k >= d ? weight : 1.0) * t.row(k);
        finish_row(j, k, span, weight, z(k) - w.zm(k, i));
      }
    }
    return;
  }
  std::vector<ForwardCache> caches(static_cast<std::size_t>(w.m));
  Matrix dz_in;
  for (Index j = 0; j < count; ++j) {
    const Index i = first + j;
    const Matrix out = roll(map, theta, w, i, 1, &caches);
    const double span = w.h.col(i).sum();
    const double weight = bal.weight(span);
    for (Index k = 0; k < dim; ++k) {
      const double wk = k >= d ? weight : 1.0;
      Eigen::Map<Vector> row(jac.row(j * dim + k).data(), p);
      row.setZero();
      Matrix u = Matrix::Zero(dim, 1);
      u(k, 0) = wk;
      for (Index s = w.m - 1; s >= 0; --s) {
        map.backward(theta, caches[static_cast<std::size_t>(s)], u, row, s > 0 ? &dz_in : nullptr);
        if (s > 0) u.swap(dz_in);
      }
      finish_row(j, k, span, weight, out(k, 0) - w.zm(k, i));
    }
  }
}

NormalEquations window_normal_equations(const OneStepMap& map, ConstParams theta,
                                        const WindowSet& w, bool balanced, double scale,
                                        bool with_scores,
                                        const std::function<bool()>& should_stop) {
  check(map, theta, w);
  const Index dim = w.dim(), p = map.n_params(), n = w.size();
  NormalEquations ne;
  ne.a.setZero(p, p);
  ne.g.setZero(p);
  Index blocks = 0;
  if (with_scores) {
    require(!w.block.empty(), "normal equations: scores need the windows' blocks");
    for (Index b : w.block) {
      require(b >= 0, "normal equations: block indices must be >= 0");
      blocks = std::max(blocks, b + 1);
    }
    ne.scores.setZero(p, blocks);
  }
  const lapack::SingleThreaded one_thread;
  // Chunks of about 4 MB of J.
  const Index chunk = std::clamp<Index>((Index{1} << 19) / std::max<Index>(1, dim * p), 1, 256);
  RowMajorMatrix jac;
  Vector r;
  for (Index first = 0; first < n; first += chunk) {
    if (should_stop && should_stop()) {
      ne.stopped = true;
      break;
    }
    const Index count = std::min(chunk, n - first);
    jac.resize(count * dim, p);
    r.resize(count * dim);
    window_jacobian_rows(map, theta, w, balanced, first, count, jac, r);
    jac *= scale;
    r *= scale;
    ne.cost += 0.5 * r.squaredNorm();
    lapack::add_gram_from_transpose(jac.data(), p, count * dim, ne.a.data());
    lapack::add_transpose_times(jac.data(), p, count * dim, r.data(), ne.g.data());
    if (with_scores)
      for (Index j = 0; j < count; ++j) {
        const Index b = w.block[static_cast<std::size_t>(first + j)];
        ne.scores.col(b).noalias() +=
            jac.middleRows(j * dim, dim).transpose() * r.segment(j * dim, dim);
      }
  }
  return ne;
}

Vector gauss_newton_with_zeros(const NormalEquations& ne, const Vector& theta,
                               const std::vector<Index>& zeroed) {
  const Index n = theta.size();
  require(ne.a.rows() == n && ne.g.size() == n,
          "gauss_newton_with_zeros: the normal equations do not match theta");
  std::vector<char> is_zeroed(static_cast<std::size_t>(n), 0);
  for (Index j : zeroed) {
    require(j >= 0 && j < n, "gauss_newton_with_zeros: an index outside theta");
    is_zeroed[static_cast<std::size_t>(j)] = 1;
  }
  std::vector<Index> kept, gone;
  for (Index j = 0; j < n; ++j) (is_zeroed[static_cast<std::size_t>(j)] ? gone : kept).push_back(j);
  if (gone.empty() || kept.empty()) return {};
  const Matrix a = ne.a.selfadjointView<Eigen::Lower>();
  const Index nk = static_cast<Index>(kept.size()), nd = static_cast<Index>(gone.size());
  Matrix akk(nk, nk), akd(nk, nd);
  Vector rhs(nk), dd(nd);
  for (Index j = 0; j < nd; ++j) dd(j) = -theta(gone[static_cast<std::size_t>(j)]);
  for (Index i = 0; i < nk; ++i) {
    const Index ki = kept[static_cast<std::size_t>(i)];
    rhs(i) = ne.g(ki);
    for (Index j = 0; j < nk; ++j) akk(i, j) = a(ki, kept[static_cast<std::size_t>(j)]);
    for (Index j = 0; j < nd; ++j) akd(i, j) = a(ki, gone[static_cast<std::size_t>(j)]);
  }
  rhs.noalias() += akd * dd;
  akk.diagonal() += 1e-9 * akk.diagonal().cwiseMax(1e-300);
  const dense::Ldlt f(akk);
  if (!f.ok()) return {};
  const Vector dk = -f.solve(rhs);
  if (!dk.allFinite()) return {};
  Vector out = theta;
  for (Index i = 0; i < nk; ++i) out(kept[static_cast<std::size_t>(i)]) += dk(i);
  for (Index j = 0; j < nd; ++j) out(gone[static_cast<std::size_t>(j)]) = 0.0;
  return out;
}

Vector gauss_newton_step(const NormalEquations& ne) {
  const Matrix a = ne.a.selfadjointView<Eigen::Lower>();
  const Vector diag = a.diagonal().cwiseMax(1e-300);
  for (double mu = 1e-9; mu < 1e3; mu *= 100.0) {
    Matrix lhs = a;
    lhs.diagonal() += mu * diag;
    const dense::Ldlt f(lhs);
    if (!f.ok()) continue;
    Vector step = -f.solve(ne.g);
    if (step.allFinite()) return step;
  }
  return Vector::Zero(ne.g.size());
}

}  // namespace csympnet
