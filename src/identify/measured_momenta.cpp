// The check that the momenta were measured, not computed from the positions
// (identify/model_checks.hpp; docs/derivations.md, "Momenta computed from the positions").
//
// Momenta computed from noisy positions (a difference, numpy.gradient, a Savitzky–Golay
// derivative) are a fixed linear filter of the positions: regressed on the positions at the
// neighbouring samples, they leave nothing, while the positions themselves keep their noise,
// which no filter of their neighbours predicts. Measured momenta carry noise of their own (or,
// noise-free, follow the positions only as far as the dynamics make them), and the best filter
// leaves at least a sizeable share of what it leaves for the positions.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "csympnet/core/dense.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/identify/model_checks.hpp"

namespace csympnet {

namespace {

constexpr double kUnset = std::numeric_limits<double>::quiet_NaN();
// Filters over up to 2K + 1 samples are recognised (Savitzky–Golay windows up to 17): the
// largest K ≤ 8 whose centres (samples with K neighbours each side) number at least
// min_rows(K), enough for 2K + 2 coefficients.
constexpr Index kMaxHalfWidth = 8;
constexpr Index kMinHalfWidth = 2;
constexpr Index min_rows(Index k) {
  return 10 * (2 * k + 2);
}
// Few enough rows to keep the regressions cheap on long records (centres evenly spread).
constexpr Index kMaxRows = 20000;
// Below this share left by a filter of the neighbours the positions follow a linear recurrence
// to rounding (noise-free linear, or finely sampled, motion), whose measured momenta are a
// filter of the positions too.
constexpr double kExactRecurrence = 1e-24;

std::string two_digits(double v, int digits = 2) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

// Residual and total sums of squares of the least-squares fit of y on the columns of x and an
// intercept.
struct Fit {
  double rss = 0.0, tss = 0.0;
  Fit& operator+=(const Fit& o) {
    rss += o.rss;
    tss += o.tss;
    return *this;
  }
  double share() const { return tss > 0.0 ? rss / tss : kUnset; }
};

Fit least_squares(const Matrix& x, const Vector& y) {
  const Index n = y.size();
  Matrix a(n, x.cols() + 1);
  a.leftCols(x.cols()) = x;
  a.col(x.cols()).setOnes();
  Vector scale = a.colwise().norm().transpose();
  for (Index j = 0; j < scale.size(); ++j)
    if (!(scale(j) > 0.0)) scale(j) = 1.0;
  a = a * scale.cwiseInverse().asDiagonal();
  const Vector c = dense::least_squares(a, y);
  return {(y - a * c).squaredNorm(), (y.array() - y.mean()).square().sum()};
}

double median_step(const Vector& t) {
  std::vector<double> h(static_cast<std::size_t>(t.size() - 1));
  for (Index i = 0; i + 1 < t.size(); ++i) h[static_cast<std::size_t>(i)] = t(i + 1) - t(i);
  std::sort(h.begin(), h.end());
  const std::size_t m = h.size() / 2;
  return h.size() % 2 == 1 ? h[m] : 0.5 * (h[m - 1] + h[m]);
}

// The weights w of q_c ≈ Σ_j w_j q_{c+j} (j = −k … k, j ≠ 0): the least-squares polynomial of
// degree min(4, 2k − 2) in time through the k neighbours on each side, at t_c. Smooth positions
// are predicted to O(h⁵) at any steps; noise is not predicted at all. The weights depend on the
// times alone, so one factorisation per centre serves every degree of freedom.
Vector centre_weights(const Vector& t, Index c, Index k) {
  const Index deg = std::min<Index>(4, 2 * k - 2);
  const double scale = t(c + k) - t(c - k);
  Matrix v(2 * k, deg + 1);
  Index row = 0;
  for (Index j = -k; j <= k; ++j) {
    if (j == 0) continue;
    const double tau = (t(c + j) - t(c)) / scale;
    double power = 1.0;
    for (Index m = 0; m <= deg; ++m, power *= tau) v(row, m) = power;
    ++row;
  }
  return dense::first_coefficient_weights(v);
}

// The trajectories regressed together (one long trajectory, or the short ones pooled), with
// the interpolation weights of their centres (every stride-th), shared by the degrees of
// freedom.
struct Group {
  std::vector<const Trajectory*> trajs;
  Matrix weights;  // a row per centre: the 2K neighbours' weights (centre_weights)
};

struct Groups {
  std::vector<Group> groups;
  Index total = 0;  // centres over every trajectory
  Index stride = 1;
  bool stopped = false;  // a stop was requested while the weights were computed
};

Groups groups_of(const std::vector<Trajectory>& trajs, Index k) {
  Groups out;
  std::vector<const Trajectory*> pooled;
  for (const Trajectory& t : trajs) {
    const Index n_centres = t.t.size() - 2 * k;
    if (n_centres < 1) continue;
    out.total += n_centres;
    if (n_centres >= min_rows(k))
      out.groups.push_back({{&t}, Matrix()});
    else
      pooled.push_back(&t);
  }
  if (!pooled.empty()) out.groups.push_back({pooled, Matrix()});
  out.stride = std::max<Index>(1, out.total / kMaxRows);
  for (Group& g : out.groups) {
    Index count = 0, seen = 0;
    for (const Trajectory* t : g.trajs)
      for (Index c = k; c < t->t.size() - k; ++c, ++seen)
        if (seen % out.stride == 0) ++count;
    g.weights.resize(count, 2 * k);
    Index row = 0;
    seen = 0;
    for (const Trajectory* t : g.trajs)
      for (Index c = k; c < t->t.size() - k; ++c, ++seen) {
        if (seen % out.stride != 0) continue;
        if (row % 1024 == 1023 && stop_requested()) {
          out.stopped = true;
          return out;
        }
        g.weights.row(row++) = centre_weights(t->t, c, k).transpose();
      }
  }
  return out;
}

// The regression rows of one group for one degree of freedom.
struct Rows {
  Matrix taps;    // q_{n−K} … q_{n+K}
  Vector interp;  // q_n from its 2K neighbours: a local polynomial at the actual times
  Vector grad;    // numpy.gradient's central difference at n
  Vector p, p_h;  // p_n, and h p_n (a filter's coefficients scale as 1/h)
  Index size() const { return p.size(); }
};

// Every stride-th centre of the group, as groups_of chose them.
Rows rows_of(const Group& g, Index dof, Index d, Index k, Index stride) {
  const Index count = g.weights.rows();
  Index seen = 0;
  Rows r{Matrix(count, 2 * k + 1), Vector(count), Vector(count), Vector(count), Vector(count)};
  Index row = 0;
  for (const Trajectory* t : g.trajs) {
    const double h = median_step(t->t);
    for (Index c = k; c < t->t.size() - k; ++c, ++seen) {
      if (seen % stride != 0) continue;
      for (Index j = -k; j <= k; ++j) r.taps(row, j + k) = t->z(dof, c + j);
      double interp = 0.0;
      for (Index j = 0; j < k; ++j)
        interp +=
            g.weights(row, j) * t->z(dof, c - k + j) + g.weights(row, k + j) * t->z(dof, c + 1 + j);
      r.interp(row) = interp;
      const double h0 = t->t(c) - t->t(c - 1), h1 = t->t(c + 1) - t->t(c);
      r.grad(row) = (h0 * h0 * t->z(dof, c + 1) - h1 * h1 * t->z(dof, c - 1) +
                     (h1 * h1 - h0 * h0) * t->z(dof, c)) /
                    (h0 * h1 * (h0 + h1));
      r.p(row) = t->z(d + dof, c);
      r.p_h(row) = h * r.p(row);
      ++row;
    }
  }
  return r;
}

// The regressions of one degree of freedom: each trajectory long enough on its own (its own
// filter, whatever step the user's filter assumed), the shorter ones pooled.
struct Shares {
  double momenta = kUnset;     // what the best filter of the positions leaves of the momenta
  double positions = kUnset;   // what the neighbouring positions leave unpredicted of a position
  double recurrence = kUnset;  // what the best filter of its neighbours leaves of a position
  Index rows = 0;
};

Index centres(const std::vector<Trajectory>& trajs, Index k) {
  Index total = 0;
  for (const Trajectory& t : trajs) total += std::max<Index>(0, t.t.size() - 2 * k);
  return total;
}

// The half-width K of the filters tried; 0 when even the smallest has too few centres.
Index half_width(const std::vector<Trajectory>& trajs) {
  for (Index k = kMaxHalfWidth; k >= kMinHalfWidth; --k)
    if (centres(trajs, k) >= min_rows(k)) return k;
  return 0;
}

Shares shares_of(const Groups& gs, Index dof, Index d, Index k) {
  Shares s;
  if (gs.total < min_rows(k)) return s;
  Fit fir, grad, pos, rec;
  for (const Group& g : gs.groups) {
    const Rows r = rows_of(g, dof, d, k, gs.stride);
    if (r.size() < 2 * k + 3) continue;  // a pooled remainder too small to fit
    fir += least_squares(r.taps, r.p_h);
    grad += least_squares(r.grad, r.p);
    const Vector q = r.taps.col(k);
    pos += Fit{(q - r.interp).squaredNorm(), (q.array() - q.mean()).square().sum()};
    Matrix neighbours(r.size(), 2 * k);
    neighbours << r.taps.leftCols(k), r.taps.rightCols(k);
    rec += least_squares(neighbours, q);
    s.rows += r.size();
  }
  s.momenta = std::min(fir.share(), grad.share());
  s.positions = pos.share();
  s.recurrence = rec.share();
  return s;
}

}  // namespace

ModelCheck measured_momenta_check(const std::vector<Trajectory>& trajs, bool pairs_only,
                                  const CheckThresholds& th) {
  ModelCheck k;
  k.name = "measured_momenta";
  k.assumption = "momenta (or velocities) that are measured, not computed from the positions";
  k.statistic_name =
      "share of the momenta that the best linear filter of the positions leaves, over the share "
      "of the positions that a filter of their neighbours leaves (the larger over the degrees of "
      "freedom)";
  k.effect_name = "the same ratio: below the threshold the momenta are a filter of the positions";
  k.effect_threshold = th.derived_share;
  if (pairs_only || trajs.empty()) {
    k.applicable = false;
    k.sentence = "pairs, not trajectories: no neighbouring samples to compare with";
    return k;
  }
  const Index d = trajs.front().z.rows() / 2;
  const Index half = half_width(trajs);
  const Groups groups = half > 0 ? groups_of(trajs, half) : Groups();
  std::vector<double> ratio, pos, mom, rec;
  for (Index i = 0; i < d && half > 0; ++i) {
    if (groups.stopped || stop_requested()) {
      k.applicable = false;
      k.sentence = "not judged: a stop was requested";
      return k;
    }
    const Shares s = shares_of(groups, i, d, half);
    if (s.rows < min_rows(half) || !std::isfinite(s.momenta) || !std::isfinite(s.positions)) break;
    mom.push_back(s.momenta);
    rec.push_back(s.recurrence);
    pos.push_back(s.positions);
    // Against the positions' share left by the same kind of filter: on smooth data both are
    // what a 2K + 1-sample filter cannot capture, on noisy data the noise.
    ratio.push_back(s.momenta / std::max(s.recurrence, 1e-300));
  }
  if (static_cast<Index>(mom.size()) < d) {
    k.applicable = false;
    k.sentence = "too few samples with " + std::to_string(kMinHalfWidth) +
                 " neighbours on each side to tell measured momenta from computed ones";
    return k;
  }
  k.details = {{"filter_leaves", mom},
               {"positions_leave", pos},
               {"positions_filter_leaves", rec},
               {"filter_samples", 2 * half + 1}};
  const double noise = *std::max_element(pos.begin(), pos.end());
  if (*std::max_element(rec.begin(), rec.end()) < kExactRecurrence) {
    k.applicable = false;
    k.sentence =
        "the positions carry no noise a filter of their neighbours misses (noise-free linear "
        "or finely sampled motion): measured and computed momenta cannot be told apart, and "
        "no noise would be amplified";
    return k;
  }
  k.statistic = *std::max_element(ratio.begin(), ratio.end());
  k.effect = k.statistic;
  const bool computed = k.effect < th.derived_share;
  const bool noisy = noise > th.smooth_positions;
  k.passed = !(computed && noisy);
  const std::string shares = "a filter of the positions leaves a share " +
                             two_digits(*std::max_element(mom.begin(), mom.end())) +
                             " of the momenta's variation, and the positions keep a share " +
                             two_digits(noise) + " that their neighbours do not predict";
  if (!k.passed) {
    k.sentence =
        "the momenta are computed from the positions (" + shares +
        ", their noise): they carry the positions' noise differenced, and the filter's bias, "
        "which the damping rate would inherit; give measured momenta or velocities, or the "
        "positions alone";
  } else if (computed) {
    k.sentence = "the momenta look computed from the positions (" + shares +
                 "): the positions are smooth, so little noise is amplified, but a difference's "
                 "bias remains where the sampling is coarse";
  } else {
    k.sentence = "the momenta are not a filter of the positions: measured (" + shares + ")";
  }
  return k;
}

}  // namespace csympnet
