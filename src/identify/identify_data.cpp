// Stages of the identification before any training: the data, their units, the blocks and
// windows, and the warm start (identify_stages.hpp).
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "identify_stages.hpp"

namespace csympnet::detail {

namespace {

// Piece [a, b] (point indices, inclusive) of a trajectory.
Trajectory piece(const Trajectory& t, Index a, Index b) {
  Trajectory s;
  s.t = t.t.segment(a, b - a + 1);
  s.z = t.z.middleCols(a, b - a + 1);
  return s;
}

// The resampling blocks: trajectories as they are when there are enough of them, else each
// cut into contiguous segments of at least `min_steps` steps (neighbours share an end point,
// so no step is lost).
std::vector<Trajectory> make_blocks(const std::vector<Trajectory>& trajs, long target,
                                    Index min_steps, std::vector<std::pair<Index, Index>>& origin) {
  origin.clear();
  if (static_cast<long>(trajs.size()) >= target) {
    for (std::size_t k = 0; k < trajs.size(); ++k) origin.emplace_back(static_cast<Index>(k), 0);
    return trajs;
  }
  const auto per = static_cast<Index>((target + static_cast<long>(trajs.size()) - 1) /
                                      static_cast<long>(trajs.size()));
  std::vector<Trajectory> out;
  for (std::size_t j = 0; j < trajs.size(); ++j) {
    const Trajectory& t = trajs[j];
    const Index steps = t.steps();
    const Index pieces = std::clamp<Index>(steps / std::max<Index>(1, min_steps), 1, per);
    for (Index k = 0; k < pieces; ++k) {
      const Index a = steps * k / pieces, b = steps * (k + 1) / pieces;
      out.push_back(piece(t, a, b));
      origin.emplace_back(static_cast<Index>(j), a);
    }
  }
  return out;
}

// Windows of `len` steps, or of one step when the blocks are all shorter than `len`.
WindowSet windows_or_one_step(const std::vector<Trajectory>& b, Index len) {
  try {
    return windows_from_trajectories(b, len);
  } catch (const Error&) {
    return windows_from_trajectories(b, 1);
  }
}

PairSet pairs_of(const WindowSet& w) {
  // One-step windows as a pair set, for the closed-form warm start.
  PairSet p;
  p.z0 = w.z0;
  p.z1 = w.zm;
  p.h = w.h.row(0).transpose();
  return p;
}

// Blocks held out for validation: a seeded shuffle, round(val_fraction · B) of them (at
// least 1, leaving at least 2 to train on).
std::pair<std::vector<Index>, std::vector<Index>> hold_out(Index n_blocks,
                                                           const IdentifyConfig& config) {
  Index n_val =
      static_cast<Index>(std::llround(config.val_fraction * static_cast<double>(n_blocks)));
  n_val = std::clamp<Index>(n_val, 1, n_blocks - 2);
  std::vector<Index> order(static_cast<std::size_t>(n_blocks));
  std::iota(order.begin(), order.end(), Index{0});
  Rng split_rng(config.seed, "validation-blocks");
  for (Index i = n_blocks - 1; i > 0; --i) {
    const auto j = static_cast<Index>(split_rng.next_u64() % static_cast<std::uint64_t>(i + 1));
    std::swap(order[static_cast<std::size_t>(i)], order[static_cast<std::size_t>(j)]);
  }
  std::vector<Index> val_ids(order.begin(), order.begin() + n_val);
  std::vector<Index> train_ids(order.begin() + n_val, order.end());
  std::sort(val_ids.begin(), val_ids.end());
  std::sort(train_ids.begin(), train_ids.end());
  return {train_ids, val_ids};
}

}  // namespace

DataFacts inspect_data(const std::vector<Trajectory>& trajs, bool pairs_only) {
  DataFacts f;
  f.d = trajs.front().z.rows() / 2;
  std::vector<double> steps;
  Index samples = 0;
  for (std::size_t j = 0; j < trajs.size(); ++j) {
    const Trajectory& t = trajs[j];
    require(t.z.rows() == 2 * f.d, [&] {
      return "fit: trajectory " + std::to_string(j) + " has " + std::to_string(t.z.rows()) +
             " state rows, but trajectory 0 has " + std::to_string(2 * f.d) +
             " (d = " + std::to_string(f.d) + "); expected every trajectory to have the same d";
    });
    samples += t.z.cols();
    for (Index k = 0; k < t.steps(); ++k) steps.push_back(t.t(k + 1) - t.t(k));
  }
  require(!steps.empty(), "fit: the data have no step (every trajectory has a single point)");
  for (double h : steps)
    require(std::isfinite(h) && h >= std::numeric_limits<double>::min(), [&] {
      return "fit: a step of " + significant(h) +
             " is below the smallest normal double; rescale time";
    });
  std::sort(steps.begin(), steps.end());
  f.h_min = steps.front();
  f.h_max = steps.back();
  f.varying_steps = f.h_max > f.h_min * (1.0 + 1e-6);
  f.summary = {{"d", f.d},
               {"trajectories", pairs_only ? 0 : static_cast<long>(trajs.size())},
               {"pairs_file", pairs_only},
               {"samples", samples},
               {"steps", static_cast<long>(steps.size())},
               {"h_min", f.h_min},
               {"h_max", f.h_max},
               {"h_median", steps[steps.size() / 2]}};
  return f;
}

Units choose_units(const std::vector<Trajectory>& trajs, bool pairs_only,
                   const IdentifyConfig& config) {
  const Index d = trajs.front().z.rows() / 2;
  const IdentifyInit* init = config.init.get();
  Units u;
  u.normalize = config.normalize;
  // A model file to start from keeps its own units (its θ is in those units).
  if (init != nullptr) {
    u.normalize = init->normalization.has_value();  // what the report says was done
    u.normalization = init->normalization.value_or(identity_normalization(d));
    u.choices["normalization_reason"] =
        init->normalization ? "the init model file's own (its parameters are in those units)"
                            : "none: the init model file has none, so the data are fitted "
                              "in their own units";
  } else {
    u.normalization = config.normalize
                          ? (pairs_only ? fit_normalization(pairs_from_trajectories(trajs))
                                        : fit_normalization(trajs))
                          : identity_normalization(d);
  }
  if (init != nullptr && init->normalization) {
    // The init file's time scale must suit these data's steps: the steps in its units must
    // be normal, finite numbers (a τ of 1e-308 used to surface as an error blamed on the data).
    const DataFacts f = inspect_data(trajs, pairs_only);
    const double tau = u.normalization.time_scale;
    const double lo = f.h_min / tau, hi = f.h_max / tau;
    if (!(std::isfinite(hi) && hi <= 1e150 && lo >= std::numeric_limits<double>::min()))
      throw OptionError("init", init->file + ": its time scale " + number_text(tau) +
                                    " puts the data's steps (" + number_text(f.h_min) + " to " +
                                    number_text(f.h_max) + ") at " + number_text(lo) + " to " +
                                    number_text(hi) +
                                    " in its units, beyond what can be computed with; expected "
                                    "a model fitted on data with steps like these");
  }
  u.trajectories = normalize(u.normalization, trajs);
  return u;
}

void BlockSplit::set_window(Index len) {
  m = len;
  train = windows_from_trajectories(train_blocks, m);  // blocks 0 … B_t − 1
  val = windows_or_one_step(val_blocks, m);
}

BlockSplit split_blocks(const std::vector<Trajectory>& nt, bool pairs_only,
                        const IdentifyConfig& config) {
  BlockSplit s;
  Index m = config.window > 0 ? config.window : (pairs_only ? 1 : 4);
  if (pairs_only) {
    if (config.window > 1)
      throw OptionError("window", std::to_string(config.window) +
                                      " needs trajectories; a pairs file gives one-step windows");
    m = 1;
    s.blocks = nt;
    for (std::size_t k = 0; k < nt.size(); ++k) s.origin.emplace_back(static_cast<Index>(k), 0);
  } else {
    // Shortest trajectories decide an automatic window: a window must fit in most blocks.
    if (config.window == 0) {
      std::vector<Index> lens;
      for (const Trajectory& t : nt) lens.push_back(t.steps());
      std::sort(lens.begin(), lens.end());
      const Index short_len = lens[lens.size() / 4];
      m = std::clamp<Index>(short_len / 2, 1, 4);
    }
    s.blocks = make_blocks(nt, config.target_blocks, std::max<Index>(2 * m, 6), s.origin);
  }
  const Index n_blocks = static_cast<Index>(s.blocks.size());
  require(n_blocks >= 3, [&] {
    return "fit: need at least 3 blocks to validate and to estimate an interval; "
           "the data give " +
           std::to_string(n_blocks) + " (give more trajectories, or a longer one)";
  });
  const auto [train_ids, val_ids] = hold_out(n_blocks, config);
  for (Index i : train_ids) s.train_blocks.push_back(s.blocks[static_cast<std::size_t>(i)]);
  for (Index i : val_ids) s.val_blocks.push_back(s.blocks[static_cast<std::size_t>(i)]);
  s.train_ids = train_ids;
  s.val_ids = val_ids;
  // An automatic window starts at one step and grows to m_long only if the one-step residuals
  // show that noise, not misfit, dominates (adapt_windows): windows fight noise but compound
  // misfit.
  s.adaptive = config.window == 0 && !pairs_only && m > 1;
  s.m_long = m;
  s.set_window(s.adaptive ? 1 : m);
  s.summary = {{"total", n_blocks},
               {"train", static_cast<long>(train_ids.size())},
               {"validation", static_cast<long>(val_ids.size())},
               {"kind", pairs_only ? "pairs"
                                   : (static_cast<long>(nt.size()) >= config.target_blocks
                                          ? "trajectories"
                                          : "segments of trajectories")}};
  return s;
}

WarmStart warm_start(const BlockSplit& split, Index d, const IdentifyConfig& given) {
  const IdentifyInit* init = given.init.get();
  WarmStart w;
  w.dof_scales = given.dof_scales;
  if (init != nullptr)
    w.dof_scales = init->dof_scales ? DofScales::kLearned : DofScales::kFixed;
  else if (w.dof_scales == DofScales::kAuto)
    w.dof_scales = d > 1 ? DofScales::kLearned : DofScales::kFixed;
  w.choices["dof_scales"] = to_string(w.dof_scales);
  if (init != nullptr)
    w.choices["dof_scales_reason"] = "the init model file's";
  else if (w.dof_scales == DofScales::kLearned)
    w.choices["dof_scales_reason"] =
        given.dof_scales == DofScales::kAuto
            ? "d > 1: momenta's per-dof units (velocities, masses) are learned, not assumed"
            : "given";
  const WindowSet one = windows_from_trajectories(split.train_blocks, 1);
  try {
    w.gamma = gamma_warm_start(pairs_of(one));
    w.beta_init = std::max(std::abs(w.gamma->gamma), 1e-6);
  } catch (const Error& e) {
    w.note = e.what();
  }
  return w;
}

std::string significant(double v, int digits) {
  std::ostringstream s;
  s.precision(digits);
  s << v;
  return s.str();
}

}  // namespace csympnet::detail
