#include "bench_setup.hpp"

#include "../src/models/csympnet_id.hpp"
#include "../src/models/g_sympnet.hpp"
#include "../src/models/la_sympnet.hpp"
#include "../src/models/sympnet.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/data/generate.hpp"
#include "csympnet/paper/run.hpp"

#include <algorithm>
#include <optional>
#include <regex>

namespace csympnet::bench {

namespace {

bool preset_names_contain(const std::string& name) {
  const auto names = preset_names();
  return std::find(names.begin(), names.end(), name) != names.end();
}

}  // namespace

Setup make_setup(const std::string& workload, const std::string& model, std::uint64_t seed) {
  // P-Nk: preset P with N thousand training pairs.
  std::string preset = workload;
  std::optional<Index> n_train;
  static const std::regex kSized("(.+)-([1-9][0-9]*)k");
  std::smatch m;
  if (std::regex_match(workload, m, kSized) && preset_names_contain(m[1].str())) {
    preset = m[1].str();
    n_train = std::stoll(m[2].str()) * 1000;
  }
  RunConfig c = default_run_config(preset, model);
  if (n_train) c.preset.n_train = *n_train;
  const System sys(c.preset.system);
  Setup s;
  Rng train_rng(seed, "train-pairs");
  Rng val_rng(seed, "val-pairs");
  s.train = generate_pairs(sys, c.preset.n_train, c.preset.train_steps, train_rng, c.reference);
  s.val = generate_pairs(sys, c.preset.n_val, c.preset.train_steps, val_rng, c.reference);
  s.model = make_model(model_spec_for(c.preset, model));
  s.theta.resize(s.model.n_params());
  Rng init(seed, "init");
  s.model.init_params(init, s.theta);
  return s;
}

namespace {

// Per epoch, forward + backward, of the core alone (docs/benchmarks.md, "FLOPs per epoch").
double core_flops(const SymplecticCore& core, double n) {
  const double d = static_cast<double>(core.d());
  if (const auto* la = dynamic_cast<const LaSympNet*>(&core)) {
    const double layers = static_cast<double>(la->layers());
    const double sublayers = static_cast<double>(la->sublayers());
    const double shear = 6 * d * d * n + 2 * d * n + 3 * d * d;
    return layers * sublayers * shear + layers * 8 * d * n + (layers - 1) * 15 * d * n;
  }
  if (const auto* g = dynamic_cast<const GSympNet*>(&core)) {
    const double w = static_cast<double>(g->width());
    return static_cast<double>(g->layers()) * (12 * w * d * n + 13 * w * n + d * n);
  }
  throw Error("csympnet_epoch_flops: unknown core type " + core.type());
}

}  // namespace

double csympnet_epoch_flops(const OneStepMap& map, Index n_pairs) {
  const auto* model = dynamic_cast<const CSympNetId*>(&map);
  require(model != nullptr, "csympnet_epoch_flops: not a CSympNet-ID model");
  const double n = static_cast<double>(n_pairs);
  const double d = static_cast<double>(model->core().d());
  const double scaling = 7 * d * n + 5 * n;  // S_a twice, forward and backward, and ∂L/∂β
  const double loss = 8 * d * n;             // residual, its squared norm, dL/dΦ̂
  const double adamw = 14 * static_cast<double>(map.n_params());
  return core_flops(model->core(), n) + scaling + loss + adamw;
}

}  // namespace csympnet::bench
