// Micro-benchmarks of the training hot path: one full-batch epoch (forward, backward, AdamW)
// of each preset's map models, and an input Jacobian. Run with `make bench`.
#include <benchmark/benchmark.h>

#include "csympnet/experiments/run.hpp"
#include "csympnet/train/adamw.hpp"
#include "csympnet/train/loss.hpp"

namespace {

using namespace csympnet;

struct Setup {
  std::unique_ptr<OneStepMap> map;
  Vector theta;
  PairSet train;
};

Setup make_setup(const std::string& preset, const std::string& model) {
  RunConfig c = default_run_config(preset, model);
  Setup s;
  Rng rng(42, "train-pairs");
  const System sys(c.preset.system);
  s.train = generate_pairs(sys, c.preset.n_train, c.preset.train_steps, rng, c.reference);
  s.map = make_one_step_map(model_spec_for(c.preset, model));  // map models only
  s.theta.resize(s.map->n_params());
  Rng init(42, "init");
  s.map->init_params(init, s.theta);
  return s;
}

void BM_Epoch(benchmark::State& state, const std::string& preset, const std::string& model) {
  Setup s = make_setup(preset, model);
  AdamW opt(s.map->n_params(), {}, s.map->damping_param_index());
  ForwardCache cache;
  Vector grad(s.map->n_params());
  for (auto _ : state) {
    benchmark::DoNotOptimize(one_step_loss(*s.map, s.theta, s.train, &grad, &cache));
    opt.step(s.theta, grad);
  }
  state.counters["params"] = static_cast<double>(s.map->n_params());
}

void BM_Jacobian(benchmark::State& state, const std::string& preset) {
  Setup s = make_setup(preset, "csympnet");
  const Vector z = s.train.z0.col(0);
  for (auto _ : state) benchmark::DoNotOptimize(s.map->jacobian(s.theta, z, 0.2));
}

BENCHMARK_CAPTURE(BM_Epoch, s1_csympnet, std::string("s1"), std::string("csympnet"))
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_Epoch, s2_csympnet, std::string("s2"), std::string("csympnet"))
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_Epoch, s3_csympnet, std::string("s3"), std::string("csympnet"))
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_Epoch, s2_100_csympnet, std::string("s2-100"), std::string("csympnet"))
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_Epoch, s1_sympnet, std::string("s1"), std::string("sympnet"))
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_Jacobian, s1, std::string("s1"))->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_Jacobian, s3, std::string("s3"))->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
