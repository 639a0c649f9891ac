#include "identify_driven_link.hpp"

#include <algorithm>
#include <limits>

#include "csympnet/core/error.hpp"
#include "csympnet/train/positions_state.hpp"

namespace csympnet::detail {

DrivenRecord driven_record(const std::vector<Trajectory>& nt,
                           const std::vector<SegmentPlace>& places) {
  DrivenRecord out;
  std::vector<double> steps;
  for (const Trajectory& t : nt) {
    Trajectory x = t;
    x.z = Matrix::Zero(2 * t.z.rows(), t.z.cols());
    x.z.topRows(t.z.rows()) = t.z;
    out.states.push_back(std::move(x));
    out.layout.observed.push_back(Vector::Zero(t.t.size()));
    out.layout.block.emplace_back(static_cast<std::size_t>(t.t.size()), Index{0});
    for (Index k = 1; k < t.t.size(); ++k) steps.push_back(t.t(k) - t.t(k - 1));
  }
  Index block = 0;
  for (const SegmentPlace& s : places) {
    if (s.held_out) continue;
    const auto j = static_cast<std::size_t>(s.trajectory);
    out.layout.observed[j].segment(s.first, s.length).setOnes();
    std::fill_n(out.layout.block[j].begin() + s.first, s.length, block++);
  }
  out.layout.gap = std::numeric_limits<double>::infinity();
  if (!steps.empty()) {
    std::nth_element(steps.begin(), steps.begin() + static_cast<long>(steps.size() / 2),
                     steps.end());
    out.layout.gap = kWindowGapFactor * steps[steps.size() / 2];
  }
  return out;
}

std::vector<Matrix> driven_states(const OneStepMap& map, ConstParams theta,
                                  const DrivenRecord& record,
                                  const std::vector<SegmentPlace>& places,
                                  const DrivenSegments& fit, const Matrix& val_z0) {
  std::vector<Matrix> states;
  for (const Trajectory& t : record.states) states.push_back(t.z);
  Index train = 0, val = 0;
  for (const SegmentPlace& p : places) {
    const ShootingSegments& segs = p.held_out ? fit.val : fit.train;
    const Index s = p.held_out ? val++ : train++;
    const Matrix z = shooting_states(map, theta, (p.held_out ? val_z0 : fit.z0).col(s),
                                     segs.h[static_cast<std::size_t>(s)], segs.inputs(s));
    states[static_cast<std::size_t>(p.trajectory)].middleCols(p.first, z.cols()) = z;
  }
  return states;
}

LinkedFit link_driven_segments(const OneStepMap& map, Vector& theta, const DrivenRecord& record,
                               const std::vector<SegmentPlace>& places, const DrivenSegments& fit,
                               Index first_length, Matrix& val_z0, const ShootingOptions& options,
                               std::vector<Matrix>& states) {
  states = driven_states(map, theta, record, places, fit, val_z0);
  return link_segments(map, theta, record.states, record.layout, first_length, states, fit.val,
                       val_z0, options, fit.report);
}

std::vector<Trajectory> curved_inputs(const std::vector<Trajectory>& nt) {
  std::vector<Trajectory> out = nt;
  for (std::size_t j = 0; j < nt.size(); ++j) {
    const Vector& t = nt[j].t;
    const Matrix& u = nt[j].u;
    const Index n = t.size();
    for (Index k = 0; n >= 3 && k < n; ++k) {
      const Index c = std::clamp<Index>(k, 1, n - 2);  // the ends take their neighbour's u''
      const double h1 = t(c) - t(c - 1), h2 = t(c + 1) - t(c);
      const Vector curvature =
          2.0 * ((u.col(c + 1) - u.col(c)) / h2 - (u.col(c) - u.col(c - 1)) / h1) / (h1 + h2);
      const double step = 0.5 * (t(std::min(k + 1, n - 1)) - t(std::max<Index>(k - 1, 0))) *
                          (k == 0 || k == n - 1 ? 2.0 : 1.0);
      out[j].u.col(k) -= step * step / 12.0 * curvature;
    }
  }
  return out;
}

WindowSet training_state_windows(const DrivenRecord& record, const std::vector<Matrix>& states) {
  std::vector<std::pair<std::size_t, Index>> at;
  for (std::size_t j = 0; j < record.states.size(); ++j) {
    const Trajectory& t = record.states[j];
    for (Index k = 0; k + 1 < t.t.size(); ++k)
      if (record.layout.observed[j](k) > 0.0 && t.t(k + 1) - t.t(k) <= record.layout.gap)
        at.emplace_back(j, k);
  }
  WindowSet w;
  w.m = 1;
  const Index dim = states.empty() ? 0 : states.front().rows();
  const auto n = static_cast<Index>(at.size());
  w.z0.resize(dim, n);
  w.zm.resize(dim, n);
  w.h.resize(1, n);
  for (Index i = 0; i < n; ++i) {
    const auto [j, k] = at[static_cast<std::size_t>(i)];
    w.z0.col(i) = states[j].col(k);
    w.zm.col(i) = states[j].col(k + 1);
    w.h(0, i) = record.states[j].t(k + 1) - record.states[j].t(k);
    w.block.push_back(record.layout.block[j][static_cast<std::size_t>(k)]);
  }
  return w;
}

}  // namespace csympnet::detail
