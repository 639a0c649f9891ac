#include "csympnet/train/gamma_warm_start.hpp"
#include "csympnet/core/dense.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include <Eigen/Dense>

#include "csympnet/core/error.hpp"
#include "csympnet/core/options.hpp"

namespace csympnet {

namespace {

// Least-squares [A c] for y ≈ A x + c (columns are samples), by column-pivoting QR.
Matrix affine_fit(const Matrix& x, const Matrix& y, const std::string& what) {
  const Index m = x.rows(), n = x.cols();
  Matrix design(n, m + 1);
  design.leftCols(m) = x.transpose();
  design.col(m).setOnes();
  const dense::RankedSolution fit =
      dense::least_squares_with_rank(design, dense::RowMajor(y.transpose()));
  require(fit.rank == m + 1, [&] {
    return what + ": the states do not span phase space (rank " + std::to_string(fit.rank) +
           " of " + std::to_string(m + 1) + "); need more varied pairs";
  });
  return fit.x.transpose();  // m × (m+1)
}

// Indices of pairs grouped by equal step (relative tolerance 1e-9).
std::vector<std::vector<Index>> step_groups(const PairSet& pairs) {
  std::vector<Index> order(static_cast<std::size_t>(pairs.size()));
  std::iota(order.begin(), order.end(), Index{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](Index a, Index b) { return pairs.h(a) < pairs.h(b); });
  std::vector<std::vector<Index>> groups;
  for (Index i : order) {
    if (!groups.empty() &&
        std::abs(pairs.h(i) - pairs.h(groups.back().front())) <= 1e-9 * pairs.h(i))
      groups.back().push_back(i);
    else
      groups.push_back({i});
  }
  return groups;
}

GammaWarmStart by_det(const PairSet& pairs, const std::vector<std::vector<Index>>& groups,
                      Index min_size) {
  const Index d = pairs.d();
  double num = 0.0, den = 0.0;
  GammaWarmStart w;
  w.method = WarmStartMethod::kDet;
  for (const auto& g : groups) {
    if (static_cast<Index>(g.size()) < min_size) continue;
    const PairSet sub = select_pairs(pairs, g);
    const Matrix ac = affine_fit(sub.z0, sub.z1, "gamma warm start (det)");
    const double det = dense::determinant(ac.leftCols(pairs.dim()));
    if (!(det > 0.0)) continue;  // not a damped flow at this step; leave it out
    const double h = sub.h(0), weight = static_cast<double>(g.size());
    num += weight * h * std::log(det);
    den += weight * h * h;
    ++w.groups;
  }
  require(w.groups > 0, [&] {
    return "gamma warm start (det): no group of at least " + std::to_string(min_size) +
           " pairs with one step and a positive determinant";
  });
  w.gamma = -num / (static_cast<double>(d) * den);
  return w;
}

GammaWarmStart by_midpoint(const PairSet& pairs) {
  const Matrix mid = 0.5 * (pairs.z0 + pairs.z1);
  const Matrix slope = (pairs.z1 - pairs.z0).array().rowwise() / pairs.h.transpose().array();
  const Matrix mc = affine_fit(mid, slope, "gamma warm start (midpoint)");
  GammaWarmStart w;
  w.method = WarmStartMethod::kMidpoint;
  w.gamma = -mc.leftCols(pairs.dim()).trace() / static_cast<double>(pairs.d());
  return w;
}

}  // namespace

const std::vector<std::string>& warm_start_method_names() {
  static const std::vector<std::string> names = {"auto", "det", "midpoint"};
  return names;
}

std::string to_string(WarmStartMethod m) {
  return warm_start_method_names().at(static_cast<std::size_t>(m));
}

WarmStartMethod parse_warm_start_method(const std::string& text, const char* key) {
  return static_cast<WarmStartMethod>(choice_index(key, warm_start_method_names(), text));
}

GammaWarmStart gamma_warm_start(const PairSet& pairs, WarmStartMethod method) {
  pairs.validate("warm-start pairs");
  const Index min_size = 2 * (pairs.dim() + 1);
  require(pairs.size() >= min_size, [&] {
    return "gamma warm start: needs at least " + std::to_string(min_size) + " pairs, got " +
           std::to_string(pairs.size());
  });
  if (method == WarmStartMethod::kMidpoint) return by_midpoint(pairs);
  const auto groups = step_groups(pairs);
  if (method == WarmStartMethod::kDet) return by_det(pairs, groups, min_size);
  Index covered = 0;
  for (const auto& g : groups)
    if (static_cast<Index>(g.size()) >= min_size) covered += static_cast<Index>(g.size());
  if (10 * covered >= 9 * pairs.size()) return by_det(pairs, groups, min_size);
  return by_midpoint(pairs);
}

}  // namespace csympnet
