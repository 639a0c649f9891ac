#include "damping_profile.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <utility>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/QR>
#include <Eigen/SVD>

#include "csympnet/core/dense.hpp"
#include "csympnet/core/error.hpp"

namespace csympnet::detail {

Matrix DampingBasis::matrix(double c, const Vector& delta) const {
  require(!e.empty() && delta.size() == size(), "damping basis: wrong number of coefficients");
  Matrix m = c * Matrix::Identity(e.front().rows(), e.front().cols());
  for (Index i = 0; i < size(); ++i) m += delta(i) * e[static_cast<std::size_t>(i)];
  return m;
}

DampingBasis full_damping_basis(Index d) {
  DampingBasis b{"full d x d damping matrix", {}, Vector::Zero(d * d)};
  for (Index i = 0; i < d; ++i)
    for (Index j = 0; j < d; ++j) {
      Matrix e = Matrix::Zero(d, d);
      e(i, j) = 1.0;
      b.e.push_back(e);
      if (i == j) b.common(i * d + j) = 1.0;
    }
  return b;
}

DampingBasis coordinate_damping_basis(Index d) {
  DampingBasis b{"a rate per coordinate", {}, Vector::Ones(d)};
  for (Index i = 0; i < d; ++i) {
    Matrix e = Matrix::Zero(d, d);
    e(i, i) = 1.0;
    b.e.push_back(e);
  }
  return b;
}

DampingBasis modal_damping_basis(const Matrix& p) {
  const Index d = p.rows();
  require(p.cols() == d, "modal damping basis: expected a square matrix of directions");
  require(dense::is_invertible(p), "modal damping basis: the directions are not independent");
  const Matrix p_inv = dense::full_pivot_inverse(p);
  DampingBasis b{"a rate per mode of the fitted core's linearisation", {}, Vector::Ones(d)};
  for (Index k = 0; k < d; ++k) b.e.push_back(p.col(k) * p_inv.row(k));
  return b;
}

DampingProfile::DampingProfile(const OneStepMap& map, const Vector& theta, Index damping_index,
                               WindowSet windows)
    : map_(&map), core_theta_(theta), w_(std::move(windows)), d_(w_.dim() / 2) {
  require(w_.m == 1, "damping profile: expected one-step windows");
  require(damping_index >= 0 && damping_index < theta.size(),
          "damping profile: the damping parameter's index is outside theta");
  core_theta_(damping_index) = 0.0;  // the map with no damping is the core Ψ
  for (Index b : w_.block) n_blocks_ = std::max(n_blocks_, b + 1);
}

Matrix DampingProfile::residuals(double c) const {
  const Index n = w_.size();
  const Vector h = w_.h.row(0).transpose();
  Matrix x = w_.z0;
  Matrix target = w_.zm;
  for (Index k = 0; k < n; ++k) {
    const double a = std::exp(-0.5 * c * h(k));
    x.col(k).tail(d_) *= a;
    target.col(k).tail(d_) /= a;
  }
  return map_->apply(core_theta_, x, h) - target;
}

Matrix DampingProfile::momentum_jacobian_times(const Vector& x, double h,
                                               const Matrix& dirs) const {
  if (map_->has_step_tangents()) {
    // Forward mode: the tangent block (0; dirs) carried through the step, no parameter columns.
    Matrix t(2 * d_, dirs.cols());
    t.topRows(d_).setZero();
    t.bottomRows(d_) = dirs;
    Vector z = x;
    map_->step_tangents(core_theta_, h, nullptr, z.data(), t, 0);
    return t;
  }
  return map_->jacobian(core_theta_, x, h).rightCols(d_) * dirs;
}

Vector DampingProfile::rate_jacobian(double c, Index k) const {
  const double h = w_.h(0, k);
  const double a = std::exp(-0.5 * c * h);
  Vector x = w_.z0.col(k);
  x.tail(d_) *= a;
  Vector u = momentum_jacobian_times(x, h, a * w_.z0.col(k).tail(d_));
  u.tail(d_) += w_.zm.col(k).tail(d_) / a;
  return -0.5 * h * u;
}

Matrix DampingProfile::entry_jacobian(double c, Index k, const DampingBasis& basis) const {
  const double h = w_.h(0, k);
  const double a = std::exp(-0.5 * c * h);
  Vector x = w_.z0.col(k);
  x.tail(d_) *= a;
  const Matrix jac_p = momentum_jacobian_times(x, h, Matrix::Identity(d_, d_));
  const auto p0 = w_.z0.col(k).tail(d_);
  const auto p1 = w_.zm.col(k).tail(d_);
  Matrix g(2 * d_, basis.size());
  for (Index m = 0; m < basis.size(); ++m) {
    const Matrix& e = basis.e[static_cast<std::size_t>(m)];
    g.col(m) = (-0.5 * h * a) * (jac_p * (e * p0));
    g.col(m).tail(d_) += (-0.5 * h / a) * (e * p1);
  }
  return g;
}

std::vector<BlockProfile> DampingProfile::blocks(double c, const DampingBasis* basis,
                                                 const std::function<bool()>& should_stop) const {
  const Matrix r = residuals(c);
  const Index n = w_.size();
  std::vector<BlockProfile> out(static_cast<std::size_t>(n_blocks_));
  const Index entries = basis != nullptr ? basis->size() : 0;
  for (BlockProfile& b : out) {
    b.big_a = Matrix::Zero(entries, entries);
    b.big_g = Vector::Zero(entries);
  }
  const auto same_block = [&](Index k, Index lag) {
    return k + lag < n &&
           w_.block[static_cast<std::size_t>(k)] == w_.block[static_cast<std::size_t>(k + lag)];
  };
  for (Index k = 0; k < n; ++k) {
    if (k % 64 == 0 && should_stop && should_stop()) break;
    BlockProfile& b = out[static_cast<std::size_t>(w_.block[static_cast<std::size_t>(k)])];
    const auto rk = r.col(k);
    b.samples += 1;
    b.energy += w_.z0.col(k).squaredNorm();
    b.motion += (w_.zm.col(k) - w_.z0.col(k)).squaredNorm();
    b.rss += rk.squaredNorm();
    Vector u;
    if (basis != nullptr) {
      const Matrix g = entry_jacobian(c, k, *basis);
      b.big_a.noalias() += g.transpose() * g;
      b.big_g.noalias() += g.transpose() * rk;
      u = g * basis->common;
    } else {
      u = rate_jacobian(c, k);
    }
    b.a += u.squaredNorm();
    b.g += u.dot(rk);
    if (same_block(k, 1)) {
      b.lag1 += rk.dot(r.col(k + 1));
      b.lag1_pairs += 1;
    }
    if (same_block(k, 2)) {
      b.lag0 += rk.squaredNorm();
      b.lag2 += rk.dot(r.col(k + 2));
      b.lag2_pairs += 1;
    }
  }
  for (BlockProfile& b : out)
    if (b.samples > 0) b.energy /= static_cast<double>(b.samples);
  return out;
}

namespace {

// Largest relative gap allowed between the p part of an eigenvector and its real direction,
// and the largest condition number of the directions: beyond either the modes are not those
// of a natural mechanical system (or are degenerate) and the basis is not used.
constexpr double kMaxImaginaryShare = 0.1;
constexpr double kMaxCondition = 1e4;
// Frequencies closer than this (relative) are degenerate: their modes are not defined.
constexpr double kMinFrequencyGap = 0.02;

}  // namespace

FixedPoint nearest_fixed_point(const OneStepMap& map, const Vector& theta, Vector z, double h) {
  const Vector hv = Vector::Constant(1, h);
  const auto residual = [&](const Vector& x) -> Vector {
    return map.apply(theta, x, hv).col(0) - x;
  };
  Vector f = residual(z);
  for (int it = 0; it < 40 && f.allFinite(); ++it) {
    if (f.norm() <= 1e-11 * (1.0 + z.norm())) break;
    const Matrix j = map.jacobian(theta, z, h) - Matrix::Identity(z.size(), z.size());
    // Least squares of least norm: a map with a line of equilibria (a free chain's
    // translation) has J − I singular (to within what training leaves, hence the relative
    // rank threshold), and the nearest equilibrium is wanted. A direction just above the
    // threshold (a translation with a slight fitted restoring force) gives a step too long to
    // lower the residual: the step is then taken again with that direction counted as null,
    // so that whether the equilibrium is found does not hang on the rounding of one singular
    // value.
    bool improved = false;
    for (const double rank_threshold : {1e-7, 1e-5, 1e-3}) {
      const Vector step = -dense::least_norm_solution(j, f, rank_threshold);
      if (!step.allFinite()) continue;
      double t = 1.0;
      for (int half = 0; half < 20; ++half, t *= 0.5) {
        const Vector fz = residual(z + t * step);
        if (fz.allFinite() && fz.norm() < f.norm()) {
          z += t * step;
          f = fz;
          improved = true;
          break;
        }
      }
      if (improved) break;
    }
    if (!improved) break;
  }
  return {z, f.allFinite() ? f.norm() : std::numeric_limits<double>::infinity()};
}

std::optional<Vector> map_fixed_point(const OneStepMap& map, const Vector& theta, Vector z,
                                      double h) {
  const FixedPoint p = nearest_fixed_point(map, theta, std::move(z), h);
  return p.residual <= 1e-8 * (1.0 + p.z.norm()) ? std::optional<Vector>(p.z) : std::nullopt;
}

std::optional<LinearModes> modes_of_linear_map(const Matrix& jac, double h) {
  const Index d = jac.rows() / 2;
  const dense::Eigensystem es = dense::eigensystem(jac, true);
  if (!es.ok) return std::nullopt;
  std::vector<std::pair<double, Vector>> modes;  // (angle, real p direction)
  for (Index i = 0; i < 2 * d; ++i) {
    const std::complex<double> lambda = es.values(i);
    if (!(lambda.imag() > 1e-9) || std::abs(std::abs(lambda) - 1.0) > 0.1) continue;
    const Eigen::VectorXcd vp = es.vectors.col(i).tail(d);
    Matrix ri(d, 2);
    ri.col(0) = vp.real();
    ri.col(1) = vp.imag();
    const dense::SingularValues svd = dense::singular_values(ri, true);
    const Vector& s = svd.values;
    if (!(s(0) > 0.0) || s(1) > kMaxImaginaryShare * s(0)) return std::nullopt;
    modes.emplace_back(std::arg(lambda), svd.u.col(0));
  }
  if (static_cast<Index>(modes.size()) != d) return std::nullopt;
  std::sort(modes.begin(), modes.end(),
            [](const auto& x, const auto& y) { return x.first < y.first; });
  for (std::size_t i = 1; i < modes.size(); ++i)
    if (modes[i].first - modes[i - 1].first < kMinFrequencyGap * modes[i].first)
      return std::nullopt;
  LinearModes out{Vector(d), Matrix(d, d), ""};
  for (Index k = 0; k < d; ++k) {
    out.frequency(k) = modes[static_cast<std::size_t>(k)].first / h;
    out.p.col(k) = modes[static_cast<std::size_t>(k)].second;
  }
  const Vector s = dense::singular_values(out.p, false).values;
  if (!(s(d - 1) > 0.0) || s(0) / s(d - 1) > kMaxCondition) return std::nullopt;
  return out;
}

std::optional<LinearModes> DampingProfile::linear_modes() const {
  const Index n = w_.size();
  if (n == 0) return std::nullopt;
  std::vector<double> hs(w_.h.row(0).data(), w_.h.row(0).data() + n);
  std::nth_element(hs.begin(), hs.begin() + n / 2, hs.end());
  const double h = hs[static_cast<std::size_t>(n / 2)];
  const Vector mean = w_.z0.rowwise().mean();
  const double spread = std::sqrt((w_.z0.colwise() - mean).squaredNorm() / static_cast<double>(n));
  const std::optional<Vector> z = map_fixed_point(*map_, core_theta_, mean, h);
  if (z && (*z - mean).norm() <= 3.0 * spread + 1e-12) {
    std::optional<LinearModes> m = modes_of_linear_map(map_->jacobian(core_theta_, *z, h), h);
    if (m) {
      m->where = "at its equilibrium";
      return m;
    }
  }
  // The core may be poorly determined at an equilibrium the data never approach, or have
  // none near them: its Jacobian averaged over the observed states instead (at most
  // kMaxAveraged of them, evenly spaced).
  constexpr Index kMaxAveraged = 2000;
  const Index stride = std::max<Index>(1, n / kMaxAveraged);
  Matrix avg = Matrix::Zero(2 * d_, 2 * d_);
  Index used = 0;
  for (Index k = 0; k < n; k += stride, ++used) avg += map_->jacobian(core_theta_, w_.z0.col(k), h);
  std::optional<LinearModes> m = modes_of_linear_map(avg / static_cast<double>(used), h);
  if (m) m->where = "averaged over the data";
  return m;
}

}  // namespace csympnet::detail
