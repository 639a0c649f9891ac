// One step of the Hamiltonian-library map with its forward-mode tangents (step_tangents), on
// the shapes the identification runs: the library of a chain of d unit masses (each q_i^2 and
// each neighbour difference (q_i - q_{i+1})^2, (q_i - q_{i+1})^4), a full inverse mass, order 6
// with 2 substeps (18 stages a step), one thread:
//
//   library/tangents/<d>/<what>
//       theta   every parameter's column and the 2d start-state columns (an LM Jacobian)
//       start   the 2d start-state columns alone (a start state's fit)
//       states  no tangents (a rollout)
//
// docs/benchmarks.md, "The library map's tangent step". Not part of `make bench`
// (bench/bench_table.py filters by name): `build/bin/csympnet_bench
// --benchmark_filter=library/`.
#include <benchmark/benchmark.h>

#include <string>
#include <vector>

#include "csympnet/core/rng.hpp"
#include "csympnet/models/hamiltonian_library.hpp"

namespace csympnet::bench {

namespace {

enum class TangentColumns { kTheta, kStart, kStates };

HamiltonianLibraryMap bench_chain_map(Index d) {
  std::vector<LibraryTerm> terms;
  for (Index i = 0; i < d; ++i) terms.push_back({i, -1, TermShape::kPower, 2, 1.0});
  for (Index i = 0; i + 1 < d; ++i) {
    terms.push_back({i, i + 1, TermShape::kPower, 2, 1.0});
    terms.push_back({i, i + 1, TermShape::kPower, 4, 1.0});
  }
  return HamiltonianLibraryMap(d, terms, 6, 2, true, 0.01);
}

void run_tangent_step(benchmark::State& state, Index d, TangentColumns what) {
  const HamiltonianLibraryMap map = bench_chain_map(d);
  Vector theta(map.n_params());
  Rng rng(5, "bench-library");
  map.init_params(rng, theta);
  const Index n_theta = what == TangentColumns::kTheta ? map.n_params() : 0;
  const Index cols = what == TangentColumns::kStates ? 0 : n_theta + 2 * d;
  Matrix t = Matrix::Zero(2 * d, cols);
  Vector z = rng.normal_matrix(2 * d, 1, 0.3);
  const Vector z0 = z;
  Index steps = 0;
  for (auto _ : state) {
    // A window of 8 steps from the identity, as the fits' windows and segments start.
    if (steps % 8 == 0) {
      t.setZero();
      if (cols > 0) t.rightCols(2 * d).setIdentity();
      z = z0;
    }
    map.step_tangents(theta, 0.1, nullptr, z.data(), t, n_theta);
    benchmark::DoNotOptimize(z.data());
    benchmark::DoNotOptimize(t.data());
    ++steps;
  }
  state.counters["columns"] = static_cast<double>(cols);
}

const bool kRegisteredLibrary = [] {
  for (Index d : {1, 3, 10})
    for (auto [what, name] :
         {std::pair{TangentColumns::kTheta, "theta"}, std::pair{TangentColumns::kStart, "start"},
          std::pair{TangentColumns::kStates, "states"}}) {
      const std::string label = "library/tangents/" + std::to_string(d) + "/" + name;
      benchmark::RegisterBenchmark(label.c_str(), run_tangent_step, d, what)
          ->Unit(benchmark::kMicrosecond);
    }
  return true;
}();

}  // namespace

}  // namespace csympnet::bench
