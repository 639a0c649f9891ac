#include "csympnet/experiments/identify.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>

#include "../kernels/registry.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/core/options.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/core/thread_team.hpp"
#include "csympnet/diagnostics/diagnostics.hpp"
#include "csympnet/experiments/fit.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/io/json_text.hpp"
#include "csympnet/models/dof_scaled_map.hpp"
#include "csympnet/models/model_file.hpp"
#include "csympnet/models/normalized_map.hpp"
#include "csympnet/train/chunk_tree.hpp"
#include "csympnet/train/window_loss.hpp"

namespace csympnet {

const std::vector<std::string>& dof_scales_names() {
  static const std::vector<std::string> names = {"auto", "learned", "fixed"};
  return names;
}

std::string to_string(DofScales s) {
  return dof_scales_names().at(static_cast<std::size_t>(s));
}

DofScales parse_dof_scales(const std::string& text, const char* key) {
  return static_cast<DofScales>(choice_index(key, dof_scales_names(), text));
}

const std::vector<std::string>& identify_loss_names() {
  static const std::vector<std::string> names = {"balanced", "one-step"};
  return names;
}

void IdentifyConfig::validate() const {
  kWindowRange.check(window);
  kIdentifyEpochsRange.check(epochs);
  kLmIterationsRange.check(lm_iterations);
  kLrRange.check(lr);
  kValFractionRange.check(val_fraction);
  kBlocksRange.check(target_blocks);
  kLevelRange.check(level);
  kThreadsRange.check(static_cast<long>(threads));
}

void to_json(nlohmann::json& j, const IdentifyConfig& c) {
  j = {{"core", c.core},
       {"seed", c.seed},
       {"window", c.window},
       {"balanced", c.balanced},
       {"normalize", c.normalize},
       {"epochs", c.epochs},
       {"lr", c.lr},
       {"lm_iterations", c.lm_iterations},
       {"val_fraction", c.val_fraction},
       {"target_blocks", c.target_blocks},
       {"level", c.level},
       {"dof_scales", to_string(c.dof_scales)}};
  if (c.init) j["init"] = {{"file", c.init->file}, {"checksum", c.init->checksum}};
}

std::shared_ptr<const IdentifyInit> load_identify_init(const std::string& file) {
  auto out = std::make_shared<IdentifyInit>();
  out->file = file;
  nlohmann::json doc;
  SavedModel saved;
  try {
    doc = parse_json_text(read_text_file(file), file, "a csympnet model file", model_file_limits());
    saved = model_from_json(doc, file);
  } catch (const OptionError&) {
    throw;
  } catch (const StopRequested&) {
    throw;
  } catch (const Error& e) {
    throw OptionError("init", e.what());
  }
  // model_from_json checked the checksum against the contents: it is the file's.
  out->checksum = doc.at("checksum").get<std::string>();
  out->model = std::move(saved.model);
  out->theta = std::move(saved.theta);
  const nlohmann::json& spec = doc.at("model");
  if (!out->model.is_map() || out->model.type() != "csympnet" ||
      !out->model.damping_param_index().has_value())
    throw OptionError("init", file + ": a model of type '" + out->model.type() +
                                  "'; expected a CSympNet-ID (\"type\": \"csympnet\"), the "
                                  "one-step map with a damping rate that fit refines");
  // The rules --beta-init follows hold for a model file's β too (a β of 0 used to surface
  // later as a failure blamed on the data).
  const double beta = out->theta(*out->model.damping_param_index());
  if (beta == 0.0)
    throw OptionError("init", file +
                                  ": its damping parameter beta is 0; expected a nonzero beta, "
                                  "as --beta-init requires (a model csympnet fitted)");
  out->inner_spec = spec;
  if (spec.contains("normalization")) {
    Normalization n;
    from_json(spec.at("normalization"), n);
    out->normalization = std::move(n);
    out->inner_spec.erase("normalization");
  }
  out->dof_scales = out->inner_spec.contains("dof_scales");
  return out;
}

IdentifyConfig make_identify_config(const nlohmann::json& settings) {
  require(settings.is_object(),
          [&] { return "identify settings: expected a JSON object, got " + settings.dump(); });
  static const char* const kKeys[] = {
      "core", "seed",          "window",       "balanced", "normalize", "dof_scales", "epochs",
      "lr",   "lm_iterations", "val_fraction", "blocks",   "level",     "threads",    "init"};
  for (const auto& item : settings.items()) {
    const bool known = std::any_of(std::begin(kKeys), std::end(kKeys),
                                   [&](const char* k) { return item.key() == k; });
    require(known, [&] { return "identify settings: unknown key '" + item.key() + "'"; });
  }
  IdentifyConfig c;
  if (settings.contains("core")) c.core = settings.at("core");
  c.seed = settings.value("seed", c.seed);
  c.window = settings.value("window", c.window);
  c.balanced = settings.value("balanced", c.balanced);
  c.normalize = settings.value("normalize", c.normalize);
  if (settings.contains("dof_scales"))
    c.dof_scales = parse_dof_scales(settings.at("dof_scales").get<std::string>());
  c.epochs = settings.value("epochs", c.epochs);
  c.lr = settings.value("lr", c.lr);
  c.lm_iterations = settings.value("lm_iterations", c.lm_iterations);
  c.val_fraction = settings.value("val_fraction", c.val_fraction);
  c.target_blocks = settings.value("blocks", c.target_blocks);
  c.level = settings.value("level", c.level);
  c.threads = settings.value("threads", c.threads);
  c.validate();
  if (settings.contains("init") && !settings.at("init").is_null()) {
    if (!settings.at("init").is_string() || settings.at("init").get<std::string>().empty())
      throw OptionError("init", "expected the path of a model file");
    c.init = load_identify_init(settings.at("init").get<std::string>());
    const IdentifyInit& init = *c.init;
    if (!c.core.is_null())
      throw OptionError(
          "core", "cannot be given with {init}: the model file " + init.file + " fixes the core");
    if (!c.normalize && init.normalization)
      throw OptionError("normalize", "cannot be switched off with {init}: the model file " +
                                         init.file +
                                         " carries a normalisation, and its parameters are in "
                                         "those units");
    const bool learned = c.dof_scales == DofScales::kLearned;
    if (c.dof_scales != DofScales::kAuto && learned != init.dof_scales)
      throw OptionError("dof_scales",
                        "'" + to_string(c.dof_scales) + "' disagrees with {init}: " + init.file +
                            (init.dof_scales ? " learns" : " has no") + " per-dof momentum scales");
  }
  return c;
}

void to_json(nlohmann::json& j, const IdentifyQuality& q) {
  j = {{"train_loss", q.train_loss},
       {"val_loss", q.val_loss},
       {"val_relative_residual", q.val_relative_residual},
       {"null_ratio", q.null_ratio},
       {"structure_residual_max", q.structure_residual_max}};
}

namespace {

constexpr long kLmPatience = 100;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::string fmt(double v) {
  std::ostringstream s;
  s.precision(4);
  s << v;
  return s.str();
}

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
                                    Index min_steps) {
  if (static_cast<long>(trajs.size()) >= target) return trajs;
  const auto per = static_cast<Index>((target + static_cast<long>(trajs.size()) - 1) /
                                      static_cast<long>(trajs.size()));
  std::vector<Trajectory> out;
  for (const Trajectory& t : trajs) {
    const Index steps = t.steps();
    const Index pieces = std::clamp<Index>(steps / std::max<Index>(1, min_steps), 1, per);
    for (Index k = 0; k < pieces; ++k) {
      const Index a = steps * k / pieces, b = steps * (k + 1) / pieces;
      out.push_back(piece(t, a, b));
    }
  }
  return out;
}

// The candidate cores, chosen between by validation loss (section 3 of identify()).
//  - LA(5, 20) for d = 1; for d > 1 LA(4, m) with m ≤ 10 sublayers, fewer from d = 8 on, so
//    that a sublayer sweep holds about 1,200 parameters: an LM iteration forms JᵀJ, rows × P²
//    flops (seconds at d = 10 with 2,000 samples and P = 4,000), and factorises it. With step
//    polynomials when the steps vary. Exact for linear systems; its activation modules act
//    coordinate by coordinate, so a coupled or strongly nonlinear force is approximated
//    coarsely.
//  - G(6, w): six gradient modules, alternately kicks p += h Kᵀ(a ⊙ σ(K q + b)) and drifts,
//    each a ridge-function sum of width w ≤ 32, about 1,200 parameters at most. A learned
//    splitting method: any smooth potential, coupled or not; each module scales with h, so
//    irregular steps need no step polynomials.
std::vector<nlohmann::json> default_cores(Index d, bool varying_steps) {
  nlohmann::json la;
  if (d == 1) {
    la = {{"type", "la"}, {"layers", 5}, {"sublayers", 20}};
  } else {
    const Index per_sublayer = 4 * d * (d + 1) / 2;
    const Index m = std::clamp<Index>(1200 / per_sublayer, 2, 10);
    la = {{"type", "la"}, {"layers", 4}, {"sublayers", m}};
  }
  if (varying_steps) la["step_terms"] = 2;
  const Index g_layers = 6;
  const Index width = std::clamp<Index>(1200 / (g_layers * (d + 2)), 8, 32);
  nlohmann::json g = {{"type", "g"}, {"layers", g_layers}, {"width", width}};
  return {la, g};
}

std::string core_name(const nlohmann::json& core) {
  const std::string type = core.value("type", "?");
  if (type == "la")
    return "la:" + std::to_string(core.value("layers", 0)) + ":" +
           std::to_string(core.value("sublayers", 0)) +
           (core.value("step_terms", 1) == 2 ? ":h2" : "");
  if (type == "g")
    return "g:" + std::to_string(core.value("layers", 0)) + ":" +
           std::to_string(core.value("width", 0));
  return core.dump();
}

// One candidate model and how far its training got.
struct Candidate {
  nlohmann::json core;
  Model inner;
  Vector theta;
  TrainSummary training;
  LmReport lm;
  long lm_best_iteration = 0;
  double lm_seconds = 0.0;
  double val_loss = std::numeric_limits<double>::infinity();
};

std::vector<Index> index_range(Index begin, Index end) {
  std::vector<Index> idx(static_cast<std::size_t>(end - begin));
  std::iota(idx.begin(), idx.end(), begin);
  return idx;
}

// The window loss (and gradient) of a map on windows w, as chunks of windows summed over the
// fixed tree of chunk_tree.hpp, each rank computing its share of the chunks and its threads
// splitting that share: the same bits for any number of ranks and threads. Up to
// kWindowLossOneChunkMaxWindows windows it is one chunk, window_loss() itself, on every rank,
// so fits of that size keep the bits of earlier versions; above, chunks of kDefaultChunkPairs.
constexpr Index kWindowLossOneChunkMaxWindows = 4096;

ChunkPlan plan_window_chunks(Index windows) {
  return plan_chunks(windows, windows <= kWindowLossOneChunkMaxWindows ? std::max<Index>(windows, 1)
                                                                       : kDefaultChunkPairs);
}

class ChunkedWindowLoss {
 public:
  ChunkedWindowLoss(const OneStepMap& map, const WindowSet& w, bool balanced,
                    const Communicator& comm, int threads)
      : map_(&map), comm_(&comm), balanced_(balanced), plan_(plan_window_chunks(w.size())) {
    if (plan_.chunks() <= 1) {
      chunks_.push_back(w);
    } else {
      const auto [first, last] = share_of(0, plan_.chunks(), comm.rank(), comm.size());
      first_ = first;
      for (Index c = first; c < last; ++c)
        chunks_.push_back(select_windows(w, index_range(plan_.begin(c), plan_.end(c))));
      if (threads > 1) team_ = std::make_shared<ThreadTeam>(threads);
    }
    caches_.resize(static_cast<std::size_t>(std::max(1, threads)));
    grads_.resize(caches_.size());
  }

  double operator()(ConstParams theta, Vector* grad) {
    if (plan_.chunks() <= 1)
      return window_loss(*map_, theta, chunks_.front(), balanced_, grad,
                         grad != nullptr ? &caches_.front() : nullptr);
    const Index p = map_->n_params();
    const Index width = grad != nullptr ? p + 1 : 1;  // [gradient, loss]
    const auto value = [&](Index c, int part, Vector& out) {
      const auto t = static_cast<std::size_t>(part);
      Vector* g = grad != nullptr ? &grads_[t] : nullptr;
      const double l =
          window_loss_part(*map_, theta, chunks_.at(static_cast<std::size_t>(c - first_)),
                           balanced_, plan_.pairs, g, &caches_[t]);
      if (g != nullptr) out.head(p) = *g;
      out(width - 1) = l;
    };
    const Vector total = tree_sum(plan_.chunks(), width, value, team_.get(), *comm_);
    if (grad != nullptr) *grad = total.head(p);
    return total(width - 1);
  }

 private:
  const OneStepMap* map_;
  const Communicator* comm_;
  bool balanced_;
  ChunkPlan plan_;
  Index first_ = 0;
  std::vector<WindowSet> chunks_;  // this rank's, from chunk first_ on
  std::shared_ptr<ThreadTeam> team_;
  std::vector<std::vector<ForwardCache>> caches_;
  std::vector<Vector> grads_;
};

// Windows up to this many give the normal equations as window_normal_equations() forms them
// on one process (the bits of a fit in one process); above, chunks of kLmChunkWindows.
constexpr Index kLmOneChunkMaxWindows = 4096;
constexpr Index kLmChunkWindows = 1024;

// window_normal_equations() over the ranks with the same bits for any number of them: up to
// kLmOneChunkMaxWindows windows the routine itself on every rank; above, chunks of
// kLmChunkWindows windows, each the routine on its windows, summed over the fixed tree of
// chunk_tree.hpp, each rank computing its share. `should_stop` must give every rank the same
// answer (a collective agreement): it is polled per chunk of the routine in the first case;
// in the second per chunk of 1,024 windows in one process, but once before the chunks over
// several ranks, which own different numbers of chunks and cannot agree in between.
NormalEquations normal_equations_over_ranks(const OneStepMap& map, ConstParams theta,
                                            const WindowSet& w, bool balanced, double scale,
                                            bool with_scores,
                                            const std::function<bool()>& should_stop,
                                            const Communicator& comm) {
  if (w.size() <= kLmOneChunkMaxWindows)
    return window_normal_equations(map, theta, w, balanced, scale, with_scores, should_stop);
  const Index p = map.n_params();
  NormalEquations ne;
  ne.a.setZero(p, p);  // sized, as the routine's are, even when stopped
  ne.g.setZero(p);
  const bool poll_each = comm.size() == 1 && should_stop;
  if (!poll_each && should_stop && should_stop()) {
    ne.stopped = true;
    return ne;
  }
  Index blocks = 0;
  if (with_scores)
    for (Index b : w.block) blocks = std::max(blocks, b + 1);
  const ChunkPlan plan = plan_chunks(w.size(), kLmChunkWindows);
  const Index lower = p * (p + 1) / 2;             // A's lower triangle, column by column
  const Index width = lower + p + 1 + p * blocks;  // [A, g, cost, scores]
  const auto value = [&](Index c, int /*part*/, Vector& out) {
    // One process, chunks in order: once stopped, the rest are skipped and never polled.
    if (poll_each && !ne.stopped && should_stop()) ne.stopped = true;
    if (ne.stopped) {
      out.setZero();
      return;
    }
    const WindowSet part = select_windows(w, index_range(plan.begin(c), plan.end(c)));
    const NormalEquations one =
        window_normal_equations(map, theta, part, balanced, scale, with_scores);
    out.setZero();
    for (Index j = 0, at = 0; j < p; at += p - j, ++j)
      out.segment(at, p - j) = one.a.col(j).tail(p - j);
    out.segment(lower, p) = one.g;
    out(lower + p) = one.cost;
    if (with_scores)  // the chunk's blocks are numbered as the whole set's, from 0 on
      out.segment(lower + p + 1, one.scores.size()) =
          Eigen::Map<const Vector>(one.scores.data(), one.scores.size());
  };
  const Vector total = tree_sum(plan.chunks(), width, value, nullptr, comm);
  if (ne.stopped) return ne;  // incomplete sums: not to be used
  for (Index j = 0, at = 0; j < p; at += p - j, ++j)
    ne.a.col(j).tail(p - j) = total.segment(at, p - j);
  ne.g = total.segment(lower, p);
  ne.cost = total(lower + p);
  if (with_scores) ne.scores = Eigen::Map<const Matrix>(total.data() + lower + p + 1, p, blocks);
  return ne;
}

PairSet pairs_of(const WindowSet& w) {
  // One-step windows as a pair set, for the closed-form warm start.
  PairSet p;
  p.z0 = w.z0;
  p.z1 = w.zm;
  p.h = w.h.row(0).transpose();
  return p;
}

}  // namespace

IdentifyResult identify(const std::vector<Trajectory>& trajs, bool pairs_only,
                        const IdentifyConfig& config, const IdentifyHooks& hooks) {
  config.validate();
  require(!trajs.empty(), "fit: no data");
  for (std::size_t k = 0; k < trajs.size(); ++k)
    trajs[k].validate("fit: trajectory " + std::to_string(k));
  const Index d = trajs.front().z.rows() / 2;
  const IdentifyInit* init = config.init.get();
  if (init != nullptr && init->model.dim() != 2 * d)
    throw OptionError("init",
                      init->file + " is a model of d = " + std::to_string(init->model.dim() / 2) +
                          " degrees of freedom, but the data have d = " + std::to_string(d) +
                          "; expected a model of the data's dimension");
  IdentifyResult r;
  r.config = config;
  auto stage = [&](const std::string& name) {
    if (hooks.stage) hooks.stage(name);
  };
  auto stop = [&] { return hooks.should_stop && hooks.should_stop(); };
  const Communicator& comm =
      hooks.communicator != nullptr ? *hooks.communicator : serial_communicator();

  // The data as given.
  std::vector<double> steps;
  Index samples = 0;
  for (const Trajectory& t : trajs) {
    require(t.z.rows() == 2 * d, "fit: trajectories differ in dimension");
    samples += t.z.cols();
    for (Index k = 0; k < t.steps(); ++k) steps.push_back(t.t(k + 1) - t.t(k));
  }
  require(!steps.empty(), "fit: the data have no step (every trajectory has a single point)");
  for (double h : steps)
    require(std::isfinite(h) && h >= std::numeric_limits<double>::min(), [&] {
      return "fit: a step of " + fmt(h) + " is below the smallest normal double; rescale time";
    });
  std::vector<double> sorted = steps;
  std::sort(sorted.begin(), sorted.end());
  const double h_min = sorted.front(), h_max = sorted.back();
  const bool varying = h_max > h_min * (1.0 + 1e-6);
  r.data = {{"d", d},
            {"trajectories", pairs_only ? 0 : static_cast<long>(trajs.size())},
            {"pairs_file", pairs_only},
            {"samples", samples},
            {"steps", static_cast<long>(steps.size())},
            {"h_min", h_min},
            {"h_max", h_max},
            {"h_median", sorted[sorted.size() / 2]}};

  // 1. Units and offsets: a model file to start from keeps its own (its θ is in those units).
  if (init != nullptr) {
    r.config.normalize = init->normalization.has_value();  // what the report says was done
    r.normalization = init->normalization.value_or(identity_normalization(d));
    r.choices["normalization_reason"] =
        init->normalization ? "the init model file's own (its parameters are in those units)"
                            : "none: the init model file has none, so the data are fitted "
                              "in their own units";
  } else {
    r.normalization = config.normalize
                          ? (pairs_only ? fit_normalization(pairs_from_trajectories(trajs))
                                        : fit_normalization(trajs))
                          : identity_normalization(d);
  }
  if (init != nullptr && init->normalization) {
    // The init file's time scale must suit these data's steps: the steps in its units must
    // be normal, finite numbers (a τ of 1e-308 used to surface as an error blamed on the data).
    const double tau = r.normalization.time_scale;
    const double lo = h_min / tau, hi = h_max / tau;
    if (!(std::isfinite(hi) && hi <= 1e150 && lo >= std::numeric_limits<double>::min()))
      throw OptionError("init", init->file + ": its time scale " + number_text(tau) +
                                    " puts the data's steps (" + number_text(h_min) + " to " +
                                    number_text(h_max) + ") at " + number_text(lo) + " to " +
                                    number_text(hi) +
                                    " in its units, beyond what can be computed with; expected "
                                    "a model fitted on data with steps like these");
  }
  const std::vector<Trajectory> nt = normalize(r.normalization, trajs);

  // 2. Window length and blocks.
  Index m = config.window > 0 ? config.window : (pairs_only ? 1 : 4);
  std::vector<Trajectory> blocks;
  if (pairs_only) {
    if (config.window > 1)
      throw OptionError("window", std::to_string(config.window) +
                                      " needs trajectories; a pairs file gives one-step windows");
    m = 1;
    blocks = nt;
  } else {
    // Shortest trajectories decide an automatic window: a window must fit in most blocks.
    if (config.window == 0) {
      std::vector<Index> lens;
      for (const Trajectory& t : nt) lens.push_back(t.steps());
      std::sort(lens.begin(), lens.end());
      const Index short_len = lens[lens.size() / 4];
      m = std::clamp<Index>(short_len / 2, 1, 4);
    }
    blocks = make_blocks(nt, config.target_blocks, std::max<Index>(2 * m, 6));
  }
  const Index n_blocks = static_cast<Index>(blocks.size());
  require(n_blocks >= 3, [&] {
    return "fit: need at least 3 blocks to validate and to estimate an interval; "
           "the data give " +
           std::to_string(n_blocks) + " (give more trajectories, or a longer one)";
  });
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
  std::vector<Trajectory> train_blocks, val_blocks;
  for (Index i : train_ids) train_blocks.push_back(blocks[static_cast<std::size_t>(i)]);
  for (Index i : val_ids) val_blocks.push_back(blocks[static_cast<std::size_t>(i)]);
  // An automatic window starts at one step and grows to m_long only if the one-step residuals
  // show that noise, not misfit, dominates (below): windows fight noise but compound misfit.
  const bool adaptive = config.window == 0 && !pairs_only && m > 1;
  const Index m_long = m;
  if (adaptive) m = 1;
  auto windows_of = [](const std::vector<Trajectory>& b, Index len) {
    try {
      return windows_from_trajectories(b, len);
    } catch (const Error&) {
      return windows_from_trajectories(b, 1);  // blocks all shorter than the window
    }
  };
  WindowSet train = windows_from_trajectories(train_blocks, m);  // blocks 0 … B_t − 1
  WindowSet val = windows_of(val_blocks, m);

  // 3. Candidate cores. Given: that one. Else an LA and a G core, each trained (AdamW, then
  // LM) on a share of the budget; the lower validation loss wins and continues LM.
  IdentifyConfig& c = r.config;
  if (init != nullptr) c.core = init->inner_spec.at("core");
  const bool choose = c.core.is_null();
  std::vector<nlohmann::json> cores =
      choose ? default_cores(d, varying) : std::vector<nlohmann::json>{c.core};
  r.choices["blocks"] = {{"total", n_blocks},
                         {"train", static_cast<long>(train_ids.size())},
                         {"validation", n_val},
                         {"kind", pairs_only ? "pairs"
                                             : (static_cast<long>(nt.size()) >= config.target_blocks
                                                    ? "trajectories"
                                                    : "segments of trajectories")}};

  stage("warm start");
  double beta_init = 0.1;
  if (init != nullptr)
    c.dof_scales = init->dof_scales ? DofScales::kLearned : DofScales::kFixed;
  else if (c.dof_scales == DofScales::kAuto)
    c.dof_scales = d > 1 ? DofScales::kLearned : DofScales::kFixed;
  r.choices["dof_scales"] = to_string(c.dof_scales);
  if (init != nullptr)
    r.choices["dof_scales_reason"] = "the init model file's";
  else if (c.dof_scales == DofScales::kLearned)
    r.choices["dof_scales_reason"] =
        config.dof_scales == DofScales::kAuto
            ? "d > 1: momenta's per-dof units (velocities, masses) are learned, not assumed"
            : "given";
  {
    const WindowSet one = windows_from_trajectories(train_blocks, 1);
    try {
      r.warm_start = gamma_warm_start(pairs_of(one));
      beta_init = std::max(std::abs(r.warm_start->gamma), 1e-6);
    } catch (const Error& e) {
      r.warm_start_note = e.what();
    }
  }
  std::vector<Candidate> cand(cores.size());
  for (std::size_t k = 0; k < cores.size(); ++k) {
    Candidate& x = cand[k];
    x.core = cores[k];
    if (init != nullptr) {  // the file's map in its normalised units, and its θ
      x.inner = make_model(init->inner_spec);
      x.theta = init->theta;
      continue;
    }
    nlohmann::json spec = {
        {"type", "csympnet"}, {"d", d}, {"core", x.core}, {"beta_init", beta_init}};
    if (c.dof_scales == DofScales::kLearned && d > 1) spec["dof_scales"] = to_string(c.dof_scales);
    x.inner = make_model(spec);
    x.theta.resize(x.inner.n_params());
    Rng init_rng(config.seed, k == 0 ? std::string("init") : "init-" + std::to_string(k));
    x.inner.init_params(init_rng, x.theta);
  }
  const bool bal = config.balanced;
  const double share = 1.0 / static_cast<double>(cand.size());
  // A window loss alone, over the ranks.
  auto loss_on = [&](const OneStepMap& mp, const Vector& th, const WindowSet& w) {
    return ChunkedWindowLoss(mp, w, bal, comm, c.threads)(th, nullptr);
  };

  // 4. AdamW on the window loss.
  // The AdamW budget by an estimate of an epoch's seconds (about 4 ns per sample, step and
  // parameter on one core), about 10 s in all (shared by the candidates), between 300 and
  // 50,000 epochs.
  // From a model file, AdamW runs only when epochs are given: LM starts from the file's θ.
  auto epochs_for = [&](const Candidate& x) -> long {
    if (config.epochs > 0) return config.epochs;
    if (init != nullptr) return 0;
    const double epoch_seconds = 4e-9 * static_cast<double>(train.size()) * static_cast<double>(m) *
                                 static_cast<double>(x.inner.n_params());
    return std::clamp<long>(std::lround(10.0 * share / epoch_seconds), 300, 50000);
  };
  auto run_adamw = [&](Candidate& x, const std::string& label) {
    if (stop()) return;
    const OneStepMap& map = *x.inner.map;
    auto train_loss = std::make_shared<ChunkedWindowLoss>(map, train, bal, comm, c.threads);
    auto val_loss = std::make_shared<ChunkedWindowLoss>(map, val, bal, comm, c.threads);
    if (epochs_for(x) == 0) {  // none: the summary of the parameters as they are
      x.training = TrainSummary{};
      x.training.best_val_loss = (*val_loss)(x.theta, nullptr);
      x.training.final_train_loss = (*train_loss)(x.theta, nullptr);
      return;
    }
    stage(label);
    Objective o;
    o.n_params = x.inner.n_params();
    o.damping_index = map.damping_param_index();
    o.damping_rate = [&map](const Vector& th) { return map.damping_rate(th); };
    o.train_loss = [train_loss](const Vector& th, Vector& grad) {
      return (*train_loss)(th, &grad);
    };
    o.val_loss = [val_loss](const Vector& th) { return (*val_loss)(th, nullptr); };
    TrainOptions t;
    t.epochs = epochs_for(x);
    t.adamw.lr = c.lr;
    t.adamw.decay_damping = false;  // no pull of γ̂ towards 0
    t.lr_schedule = LrSchedule::kCosine;
    t.threads = c.threads;
    ProgressCallback cb = [&](const TrainProgress& p) {
      if (stop()) return false;
      return hooks.progress ? hooks.progress(p) : true;
    };
    x.training = train_parameters(o, x.theta, t, cb);
  };

  // 5. Levenberg–Marquardt on the same residuals, best validation kept.
  const Index dim = 2 * d;
  r.choices["lm_patience"] = kLmPatience;
  // The LM budget by work: an estimate of one iteration's seconds on one core (a reverse pass
  // per row of J and step, about 5 µs + 30 ns per parameter, measured on d = 1 and d = 2; the
  // Gram matrix; the factorisation), so that LM takes about `target` seconds; a patience of
  // 100 iterations without a better validation loss ends it sooner. At least `floor`
  // iterations (a stage that must run); a continuation passes 0 and is skipped when its share
  // buys no iteration.
  auto lm_budget = [&](const Candidate& x, double target, long floor = 5) -> long {
    if (config.lm_iterations > 0) return config.lm_iterations;
    const Index np = x.inner.n_params();
    if (np > 6000) return 0;
    const double rows = static_cast<double>(train.size() * dim);
    const double p_d = static_cast<double>(np);
    const double seconds = rows * static_cast<double>(m) * (5e-6 + 30e-9 * p_d) +
                           rows * p_d * p_d / 3e10 + p_d * p_d * p_d / 3e10;
    return std::clamp<long>(std::lround(target / seconds), floor, 3000);
  };
  bool stopped = false;
  auto run_lm = [&](Candidate& x, long budget, const std::string& label) {
    if (stopped || stop() || x.training.stop_reason == StopReason::kDiverged || budget <= 0) return;
    stage(label);
    const OneStepMap& map = *x.inner.map;
    const Index n_params = x.inner.n_params();
    const double sc = 1.0 / std::sqrt(static_cast<double>(train.size()));
    LeastSquaresProblem prob;
    prob.n_residuals = train.size() * dim;
    prob.n_params = n_params;
    prob.residuals = [&](ConstParams th, Eigen::Ref<Vector> res) {
      res = sc * window_residuals(map, th, train, bal);
      return true;
    };
    prob.normal_equations = [&](ConstParams th, Matrix& a, Vector& g) {
      // Polled per chunk: a large core's normal equations take seconds.
      NormalEquations ne = normal_equations_over_ranks(map, th, train, bal, sc, false, stop, comm);
      a = std::move(ne.a);
      g = std::move(ne.g);
    };
    IterationCallbacks callbacks;
    callbacks.progress = hooks.progress;
    callbacks.should_stop = stop;
    callbacks.patience = kLmPatience;
    ChunkedWindowLoss val_loss(map, val, bal, comm, c.threads);
    IterationMonitor monitor(
        "lm", budget, [&](const Vector& th) { return val_loss(th, nullptr); }, x.theta, callbacks,
        [&map](const Vector& th) { return map.damping_rate(th); });
    prob.should_stop = [&monitor] { return monitor.interrupted(); };
    const auto t0 = std::chrono::steady_clock::now();
    LmSettings ls;
    ls.max_iterations = budget;
    Vector th = x.theta;
    LmReport rep = levenberg_marquardt(prob, th, ls, lm_hooks(monitor));
    x.theta = monitor.best();
    if (stop()) stopped = true;
    if (monitor.cause() == StopCause::kPatience)
      rep.message = "no better validation loss in " + std::to_string(kLmPatience) + " iterations";
    x.lm = rep;
    x.lm_best_iteration = monitor.best_iteration();
    x.lm_seconds += seconds_since(t0);
  };

  nlohmann::json tried = nlohmann::json::array();
  std::size_t win = 0;
  for (std::size_t k = 0; k < cand.size(); ++k) {
    Candidate& x = cand[k];
    const std::string of = cand.size() > 1
                               ? " (core " + std::to_string(k + 1) + " of " +
                                     std::to_string(cand.size()) + ", " + core_name(x.core) + ")"
                               : "";
    run_adamw(x, "AdamW" + of);
    // With several candidates each gets at least 2 iterations (a large core's iteration can
    // take seconds); the winner continues below.
    const long budget = cand.size() > 1 ? lm_budget(x, 10.0, 2) : lm_budget(x, 25.0);
    run_lm(x, budget, "LM" + of);
    x.val_loss = loss_on(*x.inner.map, x.theta, val);
    if (!std::isfinite(x.val_loss)) x.val_loss = std::numeric_limits<double>::infinity();
    tried.push_back({{"core", x.core},
                     {"params", x.inner.n_params()},
                     {"epochs", x.training.epochs_run},
                     {"lm_iterations", x.lm.iterations},
                     {"val_loss", x.val_loss}});
    if (x.val_loss < cand[win].val_loss) win = k;
  }
  if (stop()) stopped = true;
  Candidate& best = cand[win];
  c.core = best.core;
  r.choices["core"] = best.core;
  if (choose) {
    r.choices["core_candidates"] = tried;
    std::string why = "lowest validation loss of " + std::to_string(cand.size()) + " candidates (" +
                      core_name(best.core) + ")";
    if (varying) why += "; the LA candidate has step polynomials because the steps vary";
    r.choices["core_reason"] = why;
  } else {
    r.choices["core_reason"] = init != nullptr ? "the init model file's" : "given";
  }
  c.epochs = epochs_for(best);
  r.choices["epochs"] = c.epochs;
  if (init != nullptr) {
    r.choices["init"] = {{"file", init->file}, {"checksum", init->checksum}};
    r.choices["epochs_reason"] = config.epochs > 0
                                     ? "given: AdamW from the init model file's parameters"
                                     : "none: LM refines the init model file's parameters";
  }
  long lm_total = cand.size() > 1 ? lm_budget(best, 10.0, 2) : lm_budget(best, 25.0);
  // The winner continues where its LM stopped, with the rest of the one-step budget.
  const long more = cand.size() > 1 && config.lm_iterations == 0 && best.lm.iterations > 0 &&
                            best.lm.message.rfind("no better", 0) != 0 && !stopped
                        ? lm_budget(best, 12.0, 0)
                        : 0;
  if (more > 0) {
    const LmReport first = best.lm;
    const long first_best = best.lm_best_iteration;
    run_lm(best, more, "LM (continued, " + core_name(best.core) + ")");
    best.lm_best_iteration =
        best.lm_best_iteration > 0 ? first.iterations + best.lm_best_iteration : first_best;
    best.lm.iterations += first.iterations;
    best.lm.accepted += first.accepted;
    best.lm.initial_cost = first.initial_cost;
    lm_total += more;
  }
  r.choices["lm_iterations"] = lm_total;
  c.lm_iterations = lm_total;
  const Model& inner = best.inner;
  const OneStepMap& map = *inner.map;
  const Index n_params = inner.n_params();
  r.theta = best.theta;
  r.training = best.training;
  const bool lm_fits = n_params <= 6000;
  if (!lm_fits) r.choices["lm_note"] = "more than 6000 parameters: no LM, no interval";
  r.stopped = stopped;

  // 5b. Longer windows when noise dominates. Along a trajectory, one-step residuals of pure
  // measurement noise, D e_k − e_{k+1}, correlate at about −1/2 with their successors; a
  // misfit is smooth in the state and correlates positively. So a negative lag-one
  // correlation says noise dominates, and windows of m_long steps (which divide its bias and
  // variance) are worth their compounding of misfit; LM continues from the one-step fit.
  if (adaptive && !r.stopped) {
    const Vector res = window_residuals(map, r.theta, train, bal);
    double num = 0.0, den = 0.0;
    for (Index i = 0; i < train.size(); ++i) {
      const auto ri = res.segment(i * dim, dim);
      den += ri.squaredNorm();
      if (i + 1 < train.size() &&
          train.block[static_cast<std::size_t>(i)] == train.block[static_cast<std::size_t>(i + 1)])
        num += ri.dot(res.segment((i + 1) * dim, dim));
    }
    const double rho = den > 0.0 ? num / den : 0.0;
    r.choices["one_step_residual_lag1_correlation"] = rho;
    if (rho < 0.0) {
      m = m_long;
      train = windows_from_trajectories(train_blocks, m);
      val = windows_of(val_blocks, m);
      r.choices["window_reason"] =
          "one-step residuals correlate negatively along trajectories "
          "(noise dominates misfit): windows of " +
          std::to_string(m) + " steps";
      const long stage_b = lm_budget(best, 15.0);
      r.choices["lm_iterations_windows"] = stage_b;
      run_lm(best, stage_b, "LM on longer windows (noise dominates)");
      r.theta = best.theta;
    } else {
      r.choices["window_reason"] =
          "one-step residuals correlate positively along trajectories "
          "(misfit dominates noise): one-step windows";
    }
  } else {
    r.choices["window_reason"] = config.window > 0 ? "given"
                                 : pairs_only      ? "pairs: one step"
                                                   : "trajectories too short for longer windows";
  }
  r.stopped = r.stopped || stopped;
  r.lm = best.lm;
  r.lm_best_iteration = best.lm_best_iteration;
  r.lm_seconds = 0.0;
  r.adamw_seconds = 0.0;
  for (const Candidate& x : cand) {
    r.lm_seconds += x.lm_seconds;
    r.adamw_seconds += x.training.seconds;
  }
  c.window = m;
  r.choices["window"] = m;
  const double scale = 1.0 / std::sqrt(static_cast<double>(train.size()));

  // 6. γ̂ and its interval, in the user's time units.
  const double tau = r.normalization.time_scale;
  const double gamma_n = map.damping_rate(r.theta).value_or(0.0);
  r.gamma = gamma_n / tau;
  r.quality.train_loss = loss_on(map, r.theta, train);
  r.quality.val_loss = loss_on(map, r.theta, val);
  if (!r.stopped && lm_fits && r.training.stop_reason != StopReason::kDiverged) {
    stage("interval");
    const auto t_interval = std::chrono::steady_clock::now();
    const NormalEquations ne =
        normal_equations_over_ranks(map, r.theta, train, bal, scale, true, stop, comm);
    if (ne.stopped) {
      r.stopped = true;  // interrupted: no interval
    } else {
      const Index bi = *map.damping_param_index();
      const double beta = r.theta(bi);
      double data_scale = 0.0;
      for (const Trajectory& t : nt) data_scale = std::max(data_scale, t.z.cwiseAbs().maxCoeff());
      SandwichInterval s =
          sandwich_interval(ne.a, ne.g, ne.scores, bi, gamma_n, beta >= 0.0 ? 1.0 : -1.0,
                            train.size() * dim, ne.cost, scale, data_scale, c.level);
      // The scores are formed from training residuals, which a flexible core has fitted: they
      // understate the residuals it makes on data it has not seen. The held-out blocks measure
      // by how much; the variance is scaled by that ratio of losses when it exceeds 1 (a
      // jackknife-like correction, docs/derivations.md "Held-out inflation").
      const double ratio = r.quality.train_loss > 0.0 && std::isfinite(r.quality.val_loss)
                               ? r.quality.val_loss / r.quality.train_loss
                               : 1.0;
      inflate_interval(s, std::sqrt(std::max(1.0, ratio)));
      for (double* v : {&s.gamma, &s.low, &s.high, &s.std_error, &s.sandwich, &s.model_based,
                        &s.optimisation, &s.rounding})
        *v /= tau;
      r.interval = s;
    }
    r.interval_seconds = seconds_since(t_interval);
  }

  // 7. Quality, in normalised units (where every coordinate counts alike).
  {
    Matrix z = val.z0;
    Vector h(val.size());
    for (Index k = 0; k < val.m; ++k) {
      h = val.h.row(k).transpose();
      z = map.apply(r.theta, z, h);
    }
    r.quality.val_relative_residual = (z - val.zm).norm() / (val.zm - val.z0).norm();
    // The null model: a pure contraction towards a fixed point, zm ≈ c z0 + b (c scalar),
    // fitted on the training windows. A map that predicts held-out windows hardly better has
    // learned no dynamics, whatever γ̂ it reports (pure noise fits as strong damping).
    const Vector m0 = train.z0.rowwise().mean(), mm = train.zm.rowwise().mean();
    const Matrix d0 = train.z0.colwise() - m0, dm = train.zm.colwise() - mm;
    const double cc = d0.squaredNorm() > 0.0 ? (d0.cwiseProduct(dm)).sum() / d0.squaredNorm() : 0.0;
    const Matrix null_pred = (cc * val.z0).colwise() + (mm - cc * m0);
    const double null_sq = (null_pred - val.zm).squaredNorm();
    r.quality.null_ratio = null_sq > 0.0 ? (z - val.zm).squaredNorm() / null_sq : 0.0;
    const Index n_check = std::min<Index>(val.size(), 50);
    const double g = gamma_n;
    for (Index j = 0; j < n_check; ++j) {
      const Index i = j * val.size() / n_check;
      Matrix jac = map.jacobian(r.theta, val.z0.col(i), val.h(0, i));
      // With learned dof scales the map is conformally symplectic for Dᵀ J D: D DΦ D⁻¹ is the
      // Jacobian of the unscaled map, to be checked against J.
      if (const auto* scaled = dynamic_cast<const DofScaledMap*>(&map)) {
        Vector diag = Vector::Ones(2 * d);
        diag.tail(d) = scaled->scales(r.theta);
        jac = diag.asDiagonal() * jac * diag.cwiseInverse().asDiagonal();
      }
      const double own = std::exp(-g * val.h(0, i));
      r.quality.structure_residual_max =
          std::max(r.quality.structure_residual_max, structure_at(jac, own, own).self_residual);
    }
  }

  // 8. The verdict.
  auto reason = [&](const std::string& s) { r.reasons.push_back(s); };
  if (r.training.stop_reason == StopReason::kDiverged)
    reason("training diverged (non-finite loss or gradient)");
  if (!std::isfinite(r.gamma)) reason("gamma_hat is not finite");
  if (!lm_fits) reason("the model has more than 6000 parameters: no interval can be formed");
  if (r.interval) {
    const SandwichInterval& s = *r.interval;
    if (!std::isfinite(s.low) || !std::isfinite(s.high))
      reason("the interval is not finite");
    else if (s.low <= 0.0)
      reason("the " + fmt(100.0 * c.level) + "% interval [" + fmt(s.low) + ", " + fmt(s.high) +
             "] reaches 0: these data do not tell the damping rate from no damping");
    if (!s.stable)
      reason("the interval changes " + fmt(s.regularisation_ratio) +
             "-fold with the regularisation of the Gauss-Newton matrix: the data do not "
             "separate the damping from the core's parameters");
  }
  // Not the estimate itself (a fit can collapse to γ̂ ≈ 0): the largest rate the interval
  // allows, over the longest step.
  if (r.interval && std::isfinite(r.interval->high) && r.interval->high * h_max < 1e-13)
    reason(
        "even the interval's upper end gives e^(-gamma h) = 1 to 13 digits at every step: "
        "damping that weak is invisible in these data");
  if ((train.zm - train.z0).norm() == 0.0)
    reason("the states do not change over any step: there is no motion to learn from");
  else if (r.quality.val_relative_residual > 0.9)
    reason(
        "the model explains less than 10% of the motion over a window on held-out data "
        "(unexplained share " +
        fmt(r.quality.val_relative_residual) + ")");
  if (r.quality.null_ratio > 0.5)
    reason("on held-out data the model predicts only " + fmt(100.0 * (1.0 - r.quality.null_ratio)) +
           "% better than a pure contraction towards a fixed point: it has learned no dynamics "
           "to tell damping from");
  // A generalisation gap matters when the held-out error is itself a visible share of the
  // motion; below 1% the interval's held-out inflation accounts for it.
  if (r.quality.val_loss > 10.0 * r.quality.train_loss && r.quality.val_loss > 1e-20 &&
      r.quality.val_relative_residual > 1e-2)
    reason("the validation loss is " + fmt(r.quality.val_loss / r.quality.train_loss) +
           " times the training loss and the model misses " +
           fmt(100.0 * r.quality.val_relative_residual) +
           "% of the held-out motion: it does not generalise to held-out data");
  r.identified = r.reasons.empty() && !r.stopped;

  // 9. The model in the user's units.
  nlohmann::json user_spec = inner.hyperparams();
  if (init == nullptr || init->normalization) user_spec["normalization"] = r.normalization;
  r.model = make_model(user_spec);
  return r;
}

nlohmann::json identify_report(const IdentifyResult& r) {
  nlohmann::json j = {
      {"model", "csympnet"},
      {"identified", r.identified},
      {"not_identified_reason",
       r.identified ? nlohmann::json(nullptr)
                    : nlohmann::json([&] {
                        std::string s;
                        for (const auto& x : r.reasons) s += (s.empty() ? "" : "; ") + x;
                        return r.stopped && s.empty() ? std::string("interrupted") : s;
                      }())},
      {"reasons", r.reasons},
      {"gamma_hat", r.gamma},
      {"gamma_ci_low", r.interval ? nlohmann::json(r.interval->low) : nlohmann::json(nullptr)},
      {"gamma_ci_high", r.interval ? nlohmann::json(r.interval->high) : nlohmann::json(nullptr)},
      {"gamma_ci_level", r.interval ? nlohmann::json(r.interval->level) : nlohmann::json(nullptr)},
      {"gamma_ci_method", r.interval ? nlohmann::json(r.interval->method) : nlohmann::json(nullptr)},
      {"interval", r.interval ? nlohmann::json(*r.interval) : nlohmann::json(nullptr)},
      {"data", r.data},
      {"normalization", r.normalization},
      {"choices", r.choices},
      {"config", r.config},
      {"params", r.model.n_params()},
      {"warm_start", r.warm_start ? nlohmann::json({{"gamma_normalised", r.warm_start->gamma},
                                                    {"method", to_string(r.warm_start->method)}})
                                  : nlohmann::json(r.warm_start_note)},
      {"training", [&] {
         nlohmann::json t = r.training;
         t.erase("seconds");  // wall times go to timings.json: the report is the same run to run
         return t;
       }()},
      {"lm",
       {{"iterations", r.lm.iterations},
        {"accepted", r.lm.accepted},
        {"best_iteration", r.lm_best_iteration},
        {"initial_cost", r.lm.initial_cost},
        {"final_cost", r.lm.final_cost},
        {"message", r.lm.message}}},
      {"quality", r.quality},
      {"stopped", r.stopped},
      {"architecture", r.model.hyperparams()}};
  if (r.config.init)
    j["init"] = {{"file", r.config.init->file}, {"checksum", r.config.init->checksum}};
  // As a run's configuration records it (run.cpp): only when not the default.
  if (kernels::arithmetic() != kernels::kDefaultArithmetic)
    j["arithmetic"] = kernels::to_string(kernels::arithmetic());
  return j;
}

}  // namespace csympnet
