// Micro-benchmarks of the training hot path and the numerics around it. Every benchmark
// starts from a preset's own training pairs and initial θ (bench_setup.hpp).
//
//   epoch/P/M       one full-batch training epoch: loss, gradient and AdamW step, as
//                   train_parameters() runs it (the table of `make bench` reads epoch/P/csympnet)
//   epoch/W/csympnet  the same for the GEMM-bound workloads s2-100-4k and s2-100-40k (the
//                   s2-100 model on 4,000 and 40,000 pairs)
//   epoch/P/csympnet/threads:T  the same on a team of T threads (TrainOptions::threads; wall
//                   time, since CPU time would count the calling thread only)
//   lossgrad/P/M    forward + backward only: the model's training loss with its gradient
//   adamw/P         one AdamW step over the parameters of P's CSympNet-ID
//   jacobian/P/M    the exact input Jacobian at one training state (h = 0.2); for vector
//                   fields, the variational equation through dopri5
//   rollout/P/M     a 50-step test rollout at h = 0.2 (dopri5 for vector fields)
//   hessian/closed|rop/NxWxW  ∇²s of a scalar tanh MLP n → w → w → 1 at one input, in closed
//                   form (Mlp::input_hessian) and by the R-op sweep with G = I, the d = 100
//                   baselines' H network; the variational equation evaluates one per stage
//   dgemm/eigen/MxKxN  C = A B with Eigen, the GEMM our cores run on, for the FLOP-rate floor
#include "bench_train.hpp"

#include <benchmark/benchmark.h>

#include "../src/models/mlp.hpp"
#include "bench_setup.hpp"
#include "csympnet/diagnostics/diagnostics.hpp"
#include "csympnet/diagnostics/learned_map.hpp"
#include "csympnet/train/adamw.hpp"
#include "csympnet/train/objective.hpp"

namespace csympnet::bench {

namespace {

const std::vector<std::string> kPresets = {"s1", "s2", "s3", "s2-100"};
// The GEMM-bound sizes: the s2-100 model (d = 100) on 4,000 and 40,000 pairs (bench_setup.hpp).
const std::vector<std::string> kLargeWorkloads = {"s2-100-4k", "s2-100-40k"};
const std::vector<std::string> kModels = {"csympnet", "sympnet", "map",  "ode",
                                          "dhnn",     "dhnn2",   "phnn", "phnn2"};

void epoch(benchmark::State& state, const std::string& preset, const std::string& model,
           int threads) {
  Setup s = make_setup(preset, model);
  const Objective o = make_objective(s.model, s.train, s.val, threads);
  AdamW opt(o.n_params, {}, o.damping_index);
  Vector grad(o.n_params);
  for (auto _ : state) {
    benchmark::DoNotOptimize(o.train_loss(s.theta, grad));
    opt.step(s.theta, grad);
  }
  state.counters["params"] = static_cast<double>(o.n_params);
  state.counters["pairs"] = static_cast<double>(s.train.size());
  if (s.model.type() == "csympnet") {
    const double flops = csympnet_epoch_flops(*s.model.map, s.train.size());
    state.counters["flop_per_epoch"] = flops;
    state.counters["FLOPS"] =
        benchmark::Counter(flops, benchmark::Counter::kIsIterationInvariantRate);
  }
}

void loss_grad(benchmark::State& state, const std::string& preset, const std::string& model) {
  Setup s = make_setup(preset, model);
  const Objective o = make_objective(s.model, s.train, s.val);
  Vector grad(o.n_params);
  for (auto _ : state) benchmark::DoNotOptimize(o.train_loss(s.theta, grad));
  state.counters["params"] = static_cast<double>(o.n_params);
}

void adamw(benchmark::State& state, const std::string& preset) {
  Setup s = make_setup(preset, "csympnet");
  AdamW opt(s.model.n_params(), {}, s.model.damping_param_index());
  // A fixed pseudo-gradient: AdamW's cost does not depend on the values.
  const Vector grad = Vector::LinSpaced(s.model.n_params(), -1.0, 1.0);
  for (auto _ : state) {
    opt.step(s.theta, grad);
    benchmark::DoNotOptimize(s.theta.data());
  }
  state.counters["params"] = static_cast<double>(s.model.n_params());
}

void jacobian(benchmark::State& state, const std::string& preset, const std::string& model) {
  Setup s = make_setup(preset, model);
  const LearnedMap map = learned_map(s.model, s.theta);
  const Vector z = s.train.z0.col(0);
  for (auto _ : state) benchmark::DoNotOptimize(map.jacobian(z, 0.2));
}

void rollout_steps(benchmark::State& state, const std::string& preset, const std::string& model) {
  Setup s = make_setup(preset, model);
  const LearnedMap map = learned_map(s.model, s.theta);
  const Vector z0 = s.train.z0.col(0);
  const Vector steps = Vector::Constant(50, 0.2);
  for (auto _ : state) benchmark::DoNotOptimize(rollout(map, z0, steps));
}

void hessian(benchmark::State& state, Index n, Index w, bool closed_form) {
  const Mlp mlp({n, w, w, 1});
  Rng rng(42, "bench-hessian");
  Vector theta(mlp.n_params());
  mlp.init_params(rng, theta);
  const Vector x = rng.normal_matrix(n, 1, 1.0);
  const Matrix xs = x.replicate(1, n);
  const Matrix eye = Matrix::Identity(n, n);
  Vector grad = Vector::Zero(mlp.n_params());
  Matrix hess;
  for (auto _ : state) {
    if (closed_form) {
      hess = mlp.input_hessian(theta, x);
    } else {
      mlp.input_gradient_backward(theta, xs, eye, grad, &hess);
    }
    benchmark::DoNotOptimize(hess.data());
  }
}

void dgemm(benchmark::State& state, Index m, Index k, Index n) {
  const Matrix a = Matrix::Random(m, k);
  const Matrix b = Matrix::Random(k, n);
  Matrix c(m, n);
  for (auto _ : state) {
    c.noalias() = a * b;
    benchmark::DoNotOptimize(c.data());
  }
  state.counters["FLOPS"] = benchmark::Counter(2.0 * static_cast<double>(m * k * n),
                                               benchmark::Counter::kIsIterationInvariantRate);
}

}  // namespace

void register_benchmarks() {
  using benchmark::RegisterBenchmark;
  for (const auto& p : kPresets) {
    for (const auto& m : kModels) {
      RegisterBenchmark(("epoch/" + p + "/" + m).c_str(), epoch, p, m, 1)
          ->Unit(benchmark::kMicrosecond);
    }
  }
  for (const auto& p : kPresets) {
    for (int t : {2, 3, 4}) {
      const std::string name = "epoch/" + p + "/csympnet/threads:" + std::to_string(t);
      RegisterBenchmark(name.c_str(), epoch, p, std::string("csympnet"), t)
          ->Unit(benchmark::kMicrosecond)
          ->UseRealTime();
    }
  }
  for (const auto& p : kLargeWorkloads) {
    RegisterBenchmark(("epoch/" + p + "/csympnet").c_str(), epoch, p, std::string("csympnet"), 1)
        ->Unit(benchmark::kMillisecond);
    for (int t : {2, 3, 4}) {
      const std::string name = "epoch/" + p + "/csympnet/threads:" + std::to_string(t);
      RegisterBenchmark(name.c_str(), epoch, p, std::string("csympnet"), t)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    }
  }
  for (const auto& p : kPresets) {
    for (const auto& m : kModels) {
      RegisterBenchmark(("lossgrad/" + p + "/" + m).c_str(), loss_grad, p, m)
          ->Unit(benchmark::kMicrosecond);
    }
  }
  for (const auto& p : kPresets) {
    RegisterBenchmark(("adamw/" + p).c_str(), adamw, p)->Unit(benchmark::kMicrosecond);
  }
  for (const auto& p : kPresets) {
    RegisterBenchmark(("jacobian/" + p + "/csympnet").c_str(), jacobian, p, std::string("csympnet"))
        ->Unit(benchmark::kMicrosecond);
  }
  for (const std::string m : {"map", "ode", "phnn2"}) {
    RegisterBenchmark(("jacobian/s1/" + m).c_str(), jacobian, std::string("s1"), m)
        ->Unit(benchmark::kMicrosecond);
  }
  for (const std::string m : {"csympnet", "ode", "phnn2"}) {
    RegisterBenchmark(("rollout/s1/" + m).c_str(), rollout_steps, std::string("s1"), m)
        ->Unit(benchmark::kMicrosecond);
  }
  RegisterBenchmark("jacobian/s2-100/dhnn", jacobian, std::string("s2-100"), std::string("dhnn"))
      ->Unit(benchmark::kMillisecond);
  RegisterBenchmark("hessian/closed/200x256x256", hessian, Index{200}, Index{256}, true)
      ->Unit(benchmark::kMillisecond);
  RegisterBenchmark("hessian/rop/200x256x256", hessian, Index{200}, Index{256}, false)
      ->Unit(benchmark::kMillisecond);
  RegisterBenchmark("dgemm/eigen/100x100x400", dgemm, Index{100}, Index{100}, Index{400})
      ->Unit(benchmark::kMicrosecond);
  RegisterBenchmark("dgemm/eigen/1000x1000x1000", dgemm, Index{1000}, Index{1000}, Index{1000})
      ->Unit(benchmark::kMillisecond);
}

}  // namespace csympnet::bench
