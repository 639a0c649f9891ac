// Micro-benchmarks of the SympNet cores' exact-order products (src/kernels/product.hpp)
// on the shapes the training presets run, called as the cores call them:
//
//   product/MxKxN/<epilogue>[/at][/bt]   C = A B (A m x k, B k x n) then the epilogue
//       store      C = A B                       (core_product)
//       add        C += A B                      (core_product_add)
//       add_scaled C += (A B) diag(h)            (core_product_add_scaled)
//       /at        A is the transpose of a stored n x m matrix (Kᵀ in the G core)
//       /bt        B is the transpose of a stored n x k matrix (the gradients' (G H) Xᵀ)
//
// FLOPS counts the product's 2 m k n operations only (not the epilogue). Registered at static
// initialisation, so bench_main.cpp needs no change; they run before the epoch benchmarks.
#include <benchmark/benchmark.h>

#include <random>
#include <string>

#include "../src/kernels/product.hpp"

namespace csympnet::bench {

namespace {

using kernels::Epilogue;

Matrix random_matrix(std::mt19937_64& gen, Index rows, Index cols) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Matrix out(rows, cols);
  for (Index i = 0; i < out.size(); ++i) out.data()[i] = u(gen);
  return out;
}

struct ProductCase {
  Index m, k, n;
  Epilogue mode;
  bool a_transposed, b_transposed;
};

// One product per iteration through the same entry point as the cores. kAdd and kAddScaled
// keep adding into C: the values grow linearly, far from overflow or subnormals.
template <bool kAT, bool kBT>
void run_product(benchmark::State& state, const ProductCase& pc) {
  std::mt19937_64 gen(42);
  const Matrix a_store = kAT ? random_matrix(gen, pc.k, pc.m) : random_matrix(gen, pc.m, pc.k);
  const Matrix b_store = kBT ? random_matrix(gen, pc.n, pc.k) : random_matrix(gen, pc.k, pc.n);
  std::uniform_real_distribution<double> step(0.05, 0.15);
  Vector h(pc.n);
  for (Index j = 0; j < pc.n; ++j) h(j) = step(gen);
  Matrix c = random_matrix(gen, pc.m, pc.n);
  auto a = [&] {
    if constexpr (kAT) {
      return a_store.transpose();
    } else {
      return a_store.leftCols(pc.k);
    }
  }();
  auto b = [&] {
    if constexpr (kBT) {
      return b_store.transpose();
    } else {
      return b_store.leftCols(pc.n);
    }
  }();
  if (!kernels::sse2_order_product(a, b, c.data(), pc.mode, h.data())) {
    state.SkipWithError("exact_product declined this shape (Eigen would run)");
    return;
  }
  for (auto _ : state) {
    kernels::sse2_order_product(a, b, c.data(), pc.mode, h.data());
    benchmark::DoNotOptimize(c.data());
    benchmark::ClobberMemory();
  }
  state.counters["FLOPS"] = benchmark::Counter(2.0 * static_cast<double>(pc.m * pc.k * pc.n),
                                               benchmark::Counter::kIsIterationInvariantRate);
}

const char* mode_name(Epilogue mode) {
  switch (mode) {
    case Epilogue::kStore:
      return "store";
    case Epilogue::kAdd:
      return "add";
    case Epilogue::kAddScaled:
      return "add_scaled";
  }
  return "?";
}

void add(const ProductCase& pc) {
  std::string name = "product/" + std::to_string(pc.m) + "x" + std::to_string(pc.k) + "x" +
                     std::to_string(pc.n) + "/" + mode_name(pc.mode);
  if (pc.a_transposed) name += "/at";
  if (pc.b_transposed) name += "/bt";
  auto* fn = pc.a_transposed
                 ? (pc.b_transposed ? run_product<true, true> : run_product<true, false>)
                 : (pc.b_transposed ? run_product<false, true> : run_product<false, false>);
  benchmark::RegisterBenchmark(name.c_str(), fn, pc)->Unit(benchmark::kMicrosecond);
}

const bool kRegistered = [] {
  constexpr auto kStore = Epilogue::kStore;
  constexpr auto kAdd = Epilogue::kAdd;
  constexpr auto kScaled = Epilogue::kAddScaled;
  // d = 10 LA core (s2): kick/drift p += (S q) h, g_src += S (g h), dS = (G H) Xᵀ.
  add({10, 10, 400, kScaled, false, false});
  add({10, 10, 400, kAdd, false, false});
  add({10, 400, 10, kStore, false, true});
  // G core, width 50, d = 10 (s3): u = K q, p += Kᵀ u, dK += y (G H)ᵀ and du Xᵀ, dy = K (G H).
  add({50, 10, 400, kStore, false, false});
  add({10, 50, 400, kAdd, true, false});
  add({50, 400, 10, kAdd, false, true});
  // d = 100 LA core (s2-100).
  add({100, 100, 400, kScaled, false, false});
  add({100, 100, 400, kAdd, false, false});
  add({100, 400, 100, kStore, false, true});
  // Neighbours of the d = 10 shapes, for the rates of whole register tiles.
  add({8, 8, 400, kStore, false, false});
  add({16, 16, 400, kStore, false, false});
  return true;
}();

}  // namespace

}  // namespace csympnet::bench
