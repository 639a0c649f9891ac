#include "damping_profile.hpp"

#include <cmath>
#include <utility>

#include "csympnet/core/error.hpp"

namespace csympnet::detail {

Index damping_entries(Index d, DampingFreedom freedom) {
  return freedom == DampingFreedom::kFull ? d * d : d;
}

Vector common_rate_direction(Index d, DampingFreedom freedom) {
  if (freedom == DampingFreedom::kDiagonal) return Vector::Ones(d);
  Vector v = Vector::Zero(d * d);
  for (Index i = 0; i < d; ++i) v(i * d + i) = 1.0;
  return v;
}

Matrix damping_matrix(double c, const Vector& delta, Index d, DampingFreedom freedom) {
  Matrix m = c * Matrix::Identity(d, d);
  for (Index i = 0; i < d; ++i) {
    if (freedom == DampingFreedom::kDiagonal) {
      m(i, i) += delta(i);
    } else {
      for (Index j = 0; j < d; ++j) m(i, j) += delta(i * d + j);
    }
  }
  return m;
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

Vector DampingProfile::rate_jacobian(double c, Index k) const {
  const double h = w_.h(0, k);
  const double a = std::exp(-0.5 * c * h);
  Vector x = w_.z0.col(k);
  x.tail(d_) *= a;
  const Matrix jac = map_->jacobian(core_theta_, x, h);
  Vector u = a * (jac.rightCols(d_) * w_.z0.col(k).tail(d_));
  u.tail(d_) += w_.zm.col(k).tail(d_) / a;
  return -0.5 * h * u;
}

Matrix DampingProfile::entry_jacobian(double c, Index k, DampingFreedom freedom) const {
  const double h = w_.h(0, k);
  const double a = std::exp(-0.5 * c * h);
  Vector x = w_.z0.col(k);
  x.tail(d_) *= a;
  const Matrix jac = map_->jacobian(core_theta_, x, h);
  const auto p0 = w_.z0.col(k).tail(d_);
  const auto p1 = w_.zm.col(k).tail(d_);
  Matrix g = Matrix::Zero(2 * d_, damping_entries(d_, freedom));
  for (Index i = 0; i < d_; ++i) {
    const auto column = [&](Index j, Index at) {
      g.col(at) = (-0.5 * h * a * p0(j)) * jac.col(d_ + i);
      g(d_ + i, at) += -0.5 * h * p1(j) / a;
    };
    if (freedom == DampingFreedom::kDiagonal) {
      column(i, i);
    } else {
      for (Index j = 0; j < d_; ++j) column(j, i * d_ + j);
    }
  }
  return g;
}

std::vector<BlockProfile> DampingProfile::blocks(double c, const DampingFreedom* freedom,
                                                 const std::function<bool()>& should_stop) const {
  const Matrix r = residuals(c);
  const Index n = w_.size();
  std::vector<BlockProfile> out(static_cast<std::size_t>(n_blocks_));
  const Index entries = freedom != nullptr ? damping_entries(d_, *freedom) : 0;
  const Vector common = freedom != nullptr ? common_rate_direction(d_, *freedom) : Vector();
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
    if (freedom != nullptr) {
      const Matrix g = entry_jacobian(c, k, *freedom);
      b.big_a.noalias() += g.transpose() * g;
      b.big_g.noalias() += g.transpose() * rk;
      u = g * common;
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

}  // namespace csympnet::detail
