#include "identify_chain.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>

#include "csympnet/core/error.hpp"
#include "csympnet/models/hamiltonian_library.hpp"

namespace csympnet::detail {

const HamiltonianLibraryMap& library_map(const Candidate& c) {
  return dynamic_cast<const HamiltonianLibraryMap&>(*c.inner.map);
}

RecordLayout record_layout(const std::vector<Trajectory>& nt, const BlockSplit& split) {
  RecordLayout out;
  for (const Trajectory& t : nt) {
    out.observed.push_back(Vector::Zero(t.t.size()));
    out.block.emplace_back(static_cast<std::size_t>(t.t.size()), Index{0});
  }
  const std::size_t n_blocks = split.origin.size();
  std::vector<Index> train_position(n_blocks, -1);
  for (std::size_t i = 0; i < split.train_ids.size(); ++i)
    train_position[static_cast<std::size_t>(split.train_ids[i])] = static_cast<Index>(i);
  // A block owns its samples from its first up to the next block's first of the same
  // trajectory (neighbours share an end sample; it goes to the later one), the last block the
  // rest of its trajectory.
  for (std::size_t k = 0; k < n_blocks; ++k) {
    const auto [j, first] = split.origin[k];
    const auto tj = static_cast<std::size_t>(j);
    Index end = nt[tj].t.size();
    if (k + 1 < n_blocks && split.origin[k + 1].first == j) end = split.origin[k + 1].second;
    const Index pos = train_position[k];
    if (pos < 0) continue;
    for (Index c = first; c < end; ++c) {
      out.observed[tj](c) = 1.0;
      out.block[tj][static_cast<std::size_t>(c)] = pos;
    }
  }
  std::vector<double> steps;
  for (const Trajectory& t : nt)
    for (Index k = 1; k < t.t.size(); ++k) steps.push_back(t.t(k) - t.t(k - 1));
  out.gap = std::numeric_limits<double>::infinity();
  if (!steps.empty()) {
    std::nth_element(steps.begin(), steps.begin() + static_cast<long>(steps.size() / 2),
                     steps.end());
    out.gap = kWindowGapFactor * steps[steps.size() / 2];
  }
  return out;
}

Matrix step_inputs(const Trajectory& t, Index first, Index len) {
  const Index m = t.u.rows();
  if (m == 0) return Matrix();
  Matrix u(2 * m, len - 1);
  u.topRows(m) = t.u.middleCols(first, len - 1);
  u.bottomRows(m) = t.u.middleCols(first + 1, len - 1);
  return u;
}

namespace {

// One segment of trajectory j over samples [first, end), with its inputs when t has any.
void add_piece(const Trajectory& t, const RecordLayout& layout, std::size_t j, Index first,
               Index end, const std::vector<Matrix>& states, Chain& c,
               std::vector<Vector>& starts) {
  const Index len = end - first;
  const Index rows = layout.observed_rows > 0 ? layout.observed_rows : c.segs.d;
  c.segs.q.push_back(t.z.block(0, first, rows, len));
  c.segs.h.push_back(t.t.segment(first + 1, len - 1) - t.t.segment(first, len - 1));
  if (t.u.rows() > 0) c.segs.u.push_back(step_inputs(t, first, len));
  const Vector w = layout.observed[j].segment(first, len);
  const auto& blocks = layout.block[j];
  std::vector<Index> cb(blocks.begin() + first, blocks.begin() + end);
  Index own = cb.front();
  for (Index k = 0; k < len; ++k)
    if (w(k) > 0.0) {
      own = cb[static_cast<std::size_t>(k)];
      break;
    }
  c.segs.block.push_back(own);
  c.segs.observed.push_back(w);
  c.segs.column_block.push_back(std::move(cb));
  c.span.emplace_back(static_cast<Index>(j), first);
  starts.push_back(states[j].col(first));
}

}  // namespace

Chain cut_chain(const std::vector<Trajectory>& nt, const RecordLayout& layout, Index per_piece,
                const std::vector<Matrix>& states) {
  Chain c;
  c.segs.d = nt.front().z.rows() / 2;
  c.segs.row_weight = layout.row_weight;
  std::vector<Vector> starts;
  for (std::size_t j = 0; j < nt.size(); ++j) {
    const Trajectory& t = nt[j];
    const Vector& obs = layout.observed[j];
    const Index n = t.t.size();
    for (Index begin = 0; begin < n;) {
      Index end = begin + 1;  // one past the stretch without a gap
      while (end < n && t.t(end) - t.t(end - 1) <= layout.gap) ++end;
      // The stretch from its first training position to its last.
      Index lo = begin, hi = end - 1;
      while (lo <= hi && obs(lo) == 0.0) ++lo;
      while (hi >= lo && obs(hi) == 0.0) --hi;
      const double in_stretch = hi > lo ? obs.segment(lo, hi - lo + 1).sum() : 0.0;
      c.longest_stretch = std::max(c.longest_stretch, static_cast<Index>(in_stretch));
      if (in_stretch >= 2.0) {
        for (Index first = lo; first < hi;) {
          Index e = first;
          double count = 0.0;
          while (e <= hi && count < static_cast<double>(per_piece)) count += obs(e++);
          // A rest with under half a piece's positions joins this one.
          const double rest = e <= hi ? obs.segment(e, hi - e + 1).sum() : 0.0;
          if (2.0 * rest < static_cast<double>(per_piece) || hi + 1 - e < 2) e = hi + 1;
          add_piece(t, layout, j, first, e, states, c, starts);
          first = e;
        }
      }
      begin = end;
    }
  }
  c.z0.resize(2 * c.segs.d, static_cast<Index>(starts.size()));
  for (std::size_t s = 0; s < starts.size(); ++s) c.z0.col(static_cast<Index>(s)) = starts[s];
  return c;
}

void write_chain_states(const OneStepMap& map, ConstParams theta, const Chain& c,
                        std::vector<Matrix>& states) {
  for (Index s = 0; s < c.segs.size(); ++s) {
    const auto i = static_cast<std::size_t>(s);
    const auto [j, first] = c.span[i];
    const Matrix z = shooting_states(map, theta, c.z0.col(s), c.segs.h[i], c.segs.inputs(s));
    states[static_cast<std::size_t>(j)].middleCols(first, z.cols()) = z;
  }
}

namespace {

// The training loss per degree of freedom left: loss × n / (n − unknowns).
double corrected_loss(double loss, Index n, Index unknowns) {
  const double left = static_cast<double>(n - unknowns);
  return left > 0.0 ? loss * static_cast<double>(n) / left
                    : std::numeric_limits<double>::infinity();
}

// The longest of 4 per, 16 per, … (up to whole stretches; only lengths that merge segments)
// whose segments, started from `states` and rolled out with θ as it is, already follow the
// training positions: a corrected loss at most twice `kept`, the last stage's. There the misfit
// left is at most the noise (for an oscillation, a phase error of at most the noise over the
// amplitude), so the Gauss–Newton model of the fit holds from the start and the stages in between,
// each a few Levenberg–Marquardt iterations over the whole record, would only walk the same way. A
// probe is one rollout of the record, with no derivatives. `per` when none follows.
Index longest_followed(const OneStepMap& map, ConstParams theta, const std::vector<Trajectory>& nt,
                       const RecordLayout& layout, Index per, const std::vector<Matrix>& states,
                       double kept, Index n_free) {
  // The lengths that merge segments (a longer one that cuts the same segments is no skip).
  std::vector<std::pair<Index, Chain>> longer;
  Chain c = cut_chain(nt, layout, per, states);
  for (Index len = 4 * per, segments = c.segs.size(); per < c.longest_stretch; len *= 4) {
    Chain next = cut_chain(nt, layout, len, states);
    if (next.segs.size() < segments) {
      segments = next.segs.size();
      longer.emplace_back(len, std::move(next));
    }
    if (len >= c.longest_stretch || segments <= 1) break;
  }
  for (auto it = longer.rbegin(); it != longer.rend(); ++it) {
    const Chain& l = it->second;
    const double loss = shooting_loss(map, theta, l.z0, l.segs);
    const Index n = l.segs.n_residuals();
    const double corrected = corrected_loss(loss, n, n_free + map.dim() * l.segs.size());
    if (std::isfinite(corrected) && corrected <= 2.0 * kept) return it->first;
  }
  return per;
}

}  // namespace

LinkedFit link_segments(const OneStepMap& map, Vector& theta, const std::vector<Trajectory>& nt,
                        const RecordLayout& layout, Index first_length, std::vector<Matrix>& states,
                        const ShootingSegments& val, Matrix& val_z0, const ShootingOptions& options,
                        const ShootingReport& segment_fit) {
  const Index dim = map.dim();
  const Index n_free = options.n_free < 0 ? map.n_params() : options.n_free;
  LinkedFit out;
  out.record = {{"method",
                 "multiple shooting with continuity: the segments merged four at a time (more "
                 "where a rollout with theta as it is already follows), each "
                 "merged segment's start carried from the previous fit, theta and the starts "
                 "refitted, up to one segment per stretch of the record (a gap breaks one)"},
                {"stages", nlohmann::json::array()}};
  // The segment fit is the first stage; its loss is compared on the chain's own layout.
  out.chain = cut_chain(nt, layout, first_length, states);
  if (out.chain.segs.size() == 0) return out;
  out.report = segment_fit;
  // The starts of segments that begin where the segment fit had none (in a held-out block).
  double loss =
      fit_start_states(map, theta, out.chain.segs, out.chain.z0, 30, false, options.max_abs_state);
  Index n = out.chain.segs.n_residuals();
  double kept = corrected_loss(loss, n, n_free + dim * out.chain.segs.size());
  out.record["stages"].push_back({{"positions_per_segment", first_length},
                                  {"segments", out.chain.segs.size()},
                                  {"loss", loss},
                                  {"corrected_loss", kept},
                                  {"kept", true}});
  out.report.final_loss = loss;
  std::string why = "one segment spans each stretch of the record";
  write_chain_states(map, theta, out.chain, states);
  out.linked_fully = first_length >= out.chain.longest_stretch;
  out.per_piece = first_length;
  // Stages may skip lengths while the model already follows the positions (see
  // longest_followed); after a skip that is not kept, the fourfold steps resume.
  bool skipping = true;
  for (Index per = 4 * first_length; !out.linked_fully;) {
    const Index from = per;
    if (skipping) per = longest_followed(map, theta, nt, layout, per, states, kept, n_free);
    Chain c = cut_chain(nt, layout, per, states);
    if (c.segs.size() >= out.chain.segs.size()) {
      // No segment merged at this length (many short trajectories): longer still, or done.
      out.linked_fully = per >= c.longest_stretch;
      per *= 4;
      continue;
    }
    Vector th = theta;
    Matrix vz = val_z0;
    // A stage that skips lengths gets the iterations of the stages it skips: where the fit
    // converges slowly (a neural core of hundreds of parameters runs to its budget), a skip
    // must not leave it less far along than the fourfold stages would.
    ShootingOptions stage_options = watching_damping(map, options);
    for (Index len = from; len < per; len *= 4) stage_options.iterations += options.iterations;
    const auto t0 = std::chrono::steady_clock::now();
    const ShootingReport rep = fit_shooting(map, th, c.z0, c.segs, vz, val, stage_options);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    n = c.segs.n_residuals();
    const double corrected = corrected_loss(rep.final_loss, n, n_free + dim * c.segs.size());
    const double allowed = kept * (1.0 + 3.0 * std::sqrt(2.0 / static_cast<double>(n)));
    // At rounding level a rise of the loss is rounding, not a model that stops following.
    const bool at_rounding = rep.final_loss <= rounding_loss(c.segs);
    const bool accept =
        !rep.stopped && std::isfinite(corrected) && (corrected <= allowed || at_rounding);
    nlohmann::json stage = {{"positions_per_segment", per},
                            {"segments", c.segs.size()},
                            {"loss", rep.final_loss},
                            {"corrected_loss", corrected},
                            {"lm_iterations", rep.iterations},
                            {"lm_message", rep.message},
                            {"seconds", seconds},
                            {"at_rounding_level", at_rounding},
                            {"kept", accept}};
    if (per > from) stage["skipped_to_from"] = from;
    out.record["stages"].push_back(stage);
    if (rep.stopped) {
      out.report.stopped = true;
      why = "stopped on request";
      break;
    }
    if (!accept && per > from) {
      // The skip went too far for the fit: the fourfold steps from the stage before.
      skipping = false;
      per = from;
      continue;
    }
    if (!accept) {
      why = "the model does not follow the positions over segments of " + std::to_string(per) +
            " positions: the corrected training loss rose from " + std::to_string(kept) + " to " +
            std::to_string(corrected) +
            " (more than three standard errors), so the chain is broken into the segments of "
            "the stage before";
      break;
    }
    theta = th;
    val_z0 = vz;
    out.chain = std::move(c);
    out.per_piece = per;
    out.report = rep;
    kept = corrected;
    write_chain_states(map, theta, out.chain, states);
    out.linked_fully = per >= out.chain.longest_stretch;
    per *= 4;
  }
  out.record["linked_fully"] = out.linked_fully;
  out.record["why_it_ends"] = why;
  out.record["segments"] = out.chain.segs.size();
  return out;
}

}  // namespace csympnet::detail
