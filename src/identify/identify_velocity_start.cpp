// The start of the positions route's hidden momenta (identify_positions.hpp): velocities from a
// local quadratic fit of the positions, over half the time the motion stays correlated. A
// start only: γ̂ comes from the positions alone.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/QR>

#include "csympnet/core/dense.hpp"
#include "csympnet/core/error.hpp"
#include "identify_positions.hpp"

namespace csympnet::detail {

namespace {

// The lag, in samples, at which the positions' autocorrelation first falls below 1/2: the
// motion's time scale, an oscillation's (about a sixth of a period) or a decay's (about 0.7 of
// its time constant), whichever is shorter; the smallest over the coordinates, pooled over
// the trajectories.
double half_correlation_lag(const std::vector<Trajectory>& positions) {
  double lag = std::numeric_limits<double>::infinity();
  const Index d = positions.front().z.rows();
  for (Index i = 0; i < d; ++i) {
    const Index max_lag = 400;
    std::vector<double> num(max_lag + 1, 0.0);
    double var = 0.0;
    for (const Trajectory& t : positions) {
      const Vector x = t.z.row(i).transpose().array() - t.z.row(i).mean();
      var += x.squaredNorm();
      for (Index k = 1; k <= max_lag && k < x.size(); ++k)
        num[static_cast<std::size_t>(k)] += x.head(x.size() - k).dot(x.tail(x.size() - k));
    }
    if (!(var > 0.0)) continue;
    for (Index k = 1; k <= max_lag; ++k)
      if (num[static_cast<std::size_t>(k)] < 0.5 * var) {
        lag = std::min(lag, static_cast<double>(k));
        break;
      }
  }
  return std::isfinite(lag) ? lag : 400.0;
}

// dq/dt at every sample from a least-squares quadratic over the samples within `half` of its
// time (at least the 2 nearest on each side that exist; gaps are not spanned by more): a start
// for the momenta, not an estimate of them.
Trajectory with_local_velocities(const Trajectory& t, double half) {
  const Index d = t.z.rows(), n = t.t.size();
  Trajectory out;
  out.t = t.t;
  out.z.resize(2 * d, n);
  out.z.topRows(d) = t.z;
  if (n < 2) {
    out.z.bottomRows(d).setZero();
    return out;
  }
  // A sample exactly `half` away (half is a whole number of median steps) is inside: with a
  // margin far above rounding, so that times in s and in ms (0.2 s is 0.19999999999999907
  // after the arithmetic, 200 ms is 200) take the same samples and give the same answer.
  const double reach = half * (1.0 + 1e-9);
  for (Index j = 0; j < n; ++j) {
    Index lo = std::max<Index>(0, j - 2), hi = std::min<Index>(n - 1, j + 2);
    while (lo > 0 && t.t(j) - t.t(lo - 1) <= reach) --lo;
    while (hi < n - 1 && t.t(hi + 1) - t.t(j) <= reach) ++hi;
    const Index degree = hi - lo >= 2 ? 2 : 1;
    Matrix x(hi - lo + 1, degree + 1);
    // In units of `half`: powers of the raw offsets (1e-20 s and its square) would differ by
    // more than the QR's rank threshold spans, and it would drop the slope as rank-deficient.
    for (Index i = lo; i <= hi; ++i) {
      const double s = (t.t(i) - t.t(j)) / half;
      for (Index p = 0; p <= degree; ++p) x(i - lo, p) = std::pow(s, static_cast<double>(p));
    }
    const Matrix coef =
        dense::least_squares(x, dense::RowMajor(t.z.middleCols(lo, hi - lo + 1).transpose()));
    out.z.col(j).tail(d) = coef.row(1).transpose() / half;
  }
  return out;
}

// The velocity start must be a state the normalisation can scale: Δq/Δt with steps of 1e-200
// (or 1e200) time units is a velocity whose square is no normal double, and the states'
// normalisation would blame a "p" the record does not have. Refused in the record's own
// columns, t and q.
void check_velocity_start(const std::vector<Trajectory>& states, double h_median) {
  const Index d = states.front().z.rows() / 2;
  for (Index i = 0; i < d; ++i) {
    double sum = 0.0, sq = 0.0, count = 0.0, widest = 0.0;
    for (const Trajectory& t : states) {
      sum += t.z.row(d + i).sum();
      count += static_cast<double>(t.z.cols());
      widest = std::max(widest, t.z.row(i).maxCoeff() - t.z.row(i).minCoeff());
    }
    for (const Trajectory& t : states) sq += (t.z.row(d + i).array() - sum / count).square().sum();
    const double spread2 = sq / count;
    if (std::isfinite(spread2) && spread2 >= std::numeric_limits<double>::min()) continue;
    if (!(widest > 0.0)) continue;  // a constant q: check_positions names it
    const std::string q = "q" + std::to_string(i + 1);
    throw Error("fit: the times' median step " + number_text(h_median) + " with " + q +
                "'s variations (up to " + number_text(widest) +
                ") give velocities dq/dt whose squares are not normal doubles (" +
                (std::isfinite(spread2) ? "they underflow" : "they overflow") +
                "); expected the steps of t and the variations of " + q +
                " to keep |dq/dt| roughly between 1e-150 and 1e150 (rescale t, e.g. to seconds)");
  }
}

}  // namespace

void check_positions(const std::vector<Trajectory>& positions) {
  require(!positions.empty(), "fit: no data");
  const Index d = positions.front().z.rows();
  for (std::size_t k = 0; k < positions.size(); ++k) {
    const Trajectory& t = positions[k];
    const std::string where = "fit: trajectory " + std::to_string(k);
    require(d >= 1 && t.z.rows() == d, [&] {
      return where + " has " + std::to_string(t.z.rows()) +
             " position rows (d = " + std::to_string(t.z.rows()) + "), but trajectory 0 has " +
             std::to_string(d) + "; expected every trajectory to have the same d";
    });
    require(t.t.size() >= 1 && t.z.cols() == t.t.size(),
            [&] { return where + ": expected one time per sample"; });
    require(t.t.allFinite() && t.z.allFinite(), [&] { return where + ": non-finite value"; });
    for (Index i = 1; i < t.t.size(); ++i)
      require(t.t(i) > t.t(i - 1), [&] {
        return where + ": times must increase strictly (sample " + std::to_string(i) + ")";
      });
  }
  // As the states' normalisation refuses a constant column, before any fit (a constant q2 once
  // ran half a minute to "not identified").
  for (Index i = 0; i < d; ++i) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const Trajectory& t : positions) {
      lo = std::min(lo, t.z.row(i).minCoeff());
      hi = std::max(hi, t.z.row(i).maxCoeff());
    }
    require(hi > lo, [&] {
      return "fit: q" + std::to_string(i + 1) + " does not vary in the data (every value is " +
             number_text(lo) + "); expected every coordinate to vary";
    });
  }
}

VelocityStart velocity_start(const std::vector<Trajectory>& positions) {
  // Half the time over which the motion stays correlated, in the median step: the local fits
  // stay within the motion's own time scale.
  std::vector<double> steps;
  for (const Trajectory& t : positions)
    for (Index k = 1; k < t.t.size(); ++k) steps.push_back(t.t(k) - t.t(k - 1));
  require(!steps.empty(),
          "fit: every trajectory has a single position; expected at least one "
          "with two or more");
  std::nth_element(steps.begin(), steps.begin() + static_cast<long>(steps.size() / 2), steps.end());
  const double h_median = steps[steps.size() / 2];
  VelocityStart v;
  v.lag = half_correlation_lag(positions);
  v.half = std::clamp(std::floor(v.lag / 2.0), 2.0, 20.0) * h_median;
  for (const Trajectory& t : positions) v.states.push_back(with_local_velocities(t, v.half));
  check_velocity_start(v.states, h_median);
  return v;
}

}  // namespace csympnet::detail
