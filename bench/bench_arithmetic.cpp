// The cores' products in both arithmetics (src/kernels/registry.hpp: Arithmetic) and in the
// system BLAS, on the shapes the cores run, one thread:
//
//   arith/<sse2|fma|fma-avx2|openblas>/MxKxN/<epilogue>[/bt]
//       sse2      detail::core_product* in the sse2 arithmetic: the SSE2-order kernels where
//                 they cover the shape, else Eigen's GEMM (every k > 256 at m = 100)
//       fma       the same entry points in the fma arithmetic (fma_product.hpp)
//       fma-avx2  the fma arithmetic's AVX2 + FMA kernel, forced (what CPUs without AVX-512 run)
//       openblas  dgemm from libblas.so.3 (OpenBLAS where Debian's alternative selects it),
//                 single-threaded; beta = 0 for store, 1 for add (add_scaled is not a dgemm:
//                 it is timed as add)
//       /bt       B is the transpose of a stored n x k matrix (the parameter gradients)
//
// FLOPS counts 2 m k n. Not part of `make bench` (bench/bench_table.py filters by name).
#include <benchmark/benchmark.h>

#include <random>
#include <string>

#include "../src/kernels/fma_product.hpp"
#include "../src/kernels/registry.hpp"
#include "../src/models/core_product.hpp"
#include "../src/train/lapack.hpp"

extern "C" void dgemm_(const char* transa, const char* transb, const int* m, const int* n,
                       const int* k, const double* alpha, const double* a, const int* lda,
                       const double* b, const int* ldb, const double* beta, double* c,
                       const int* ldc);

namespace csympnet::bench {

namespace {

using kernels::Epilogue;

enum class Engine { kSse2, kFma, kFmaAvx2, kOpenBlas };

struct Case {
  Index m, k, n;
  Epilogue mode;
  bool bt;
  Engine engine;
};

Matrix random_matrix(std::mt19937_64& gen, Index rows, Index cols) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Matrix out(rows, cols);
  for (Index i = 0; i < out.size(); ++i) out.data()[i] = u(gen);
  return out;
}

template <typename B>
void core_call(const Matrix& a, const B& b, const Vector& h, Epilogue mode, Matrix& c,
               Matrix& scratch) {
  if (mode == Epilogue::kStore) {
    detail::core_product_to(a, b, c, scratch);
  } else if (mode == Epilogue::kAdd) {
    detail::core_product_add(a, b, c, scratch);
  } else {
    detail::core_product_add_scaled(a, b, h.data(), c, scratch);
  }
}

void run_case(benchmark::State& state, const Case& pc) {
  std::mt19937_64 gen(42);
  const Matrix a = random_matrix(gen, pc.m, pc.k);
  const Matrix b_store = pc.bt ? random_matrix(gen, pc.n, pc.k) : random_matrix(gen, pc.k, pc.n);
  std::uniform_real_distribution<double> step(0.05, 0.15);
  Vector h(pc.n);
  for (Index j = 0; j < pc.n; ++j) h(j) = step(gen);
  Matrix c = random_matrix(gen, pc.m, pc.n);
  Matrix scratch;
  if (pc.engine == Engine::kOpenBlas) {
    const lapack::SingleThreaded one;
    const int m = static_cast<int>(pc.m), n = static_cast<int>(pc.n), k = static_cast<int>(pc.k);
    const int ldb = static_cast<int>(b_store.rows());
    const double alpha = 1.0, beta = pc.mode == Epilogue::kStore ? 0.0 : 1.0;
    const char ta = 'N', tb = pc.bt ? 'T' : 'N';
    for (auto _ : state) {
      dgemm_(&ta, &tb, &m, &n, &k, &alpha, a.data(), &m, b_store.data(), &ldb, &beta, c.data(), &m);
      benchmark::DoNotOptimize(c.data());
      benchmark::ClobberMemory();
    }
  } else if (pc.engine == Engine::kFmaAvx2) {
    const Index bl = pc.bt ? pc.n : 1, bj = pc.bt ? 1 : pc.k;
    const auto call = [&] {
      return kernels::fma_kernel_using("avx2", 0, pc.m, pc.n, pc.k, a.data(), pc.m, b_store.data(),
                                       bl, bj, c.data(), pc.m, pc.mode, h.data());
    };
    if (!call()) {
      state.SkipWithError("the AVX2 fma kernel is not available here");
      return;
    }
    for (auto _ : state) {
      call();
      benchmark::DoNotOptimize(c.data());
      benchmark::ClobberMemory();
    }
  } else {
    const kernels::UseArithmetic use(pc.engine == Engine::kFma ? kernels::Arithmetic::kFma
                                                               : kernels::Arithmetic::kSse2);
    for (auto _ : state) {
      if (pc.bt) {
        core_call(a, b_store.transpose(), h, pc.mode, c, scratch);
      } else {
        core_call(a, b_store, h, pc.mode, c, scratch);
      }
      benchmark::DoNotOptimize(c.data());
      benchmark::ClobberMemory();
    }
  }
  state.counters["FLOPS"] = benchmark::Counter(2.0 * static_cast<double>(pc.m * pc.k * pc.n),
                                               benchmark::Counter::kIsIterationInvariantRate);
}

void add(Index m, Index k, Index n, Epilogue mode, bool bt) {
  const char* modes[] = {"store", "add", "add_scaled"};
  for (const Engine e : {Engine::kSse2, Engine::kFma, Engine::kFmaAvx2, Engine::kOpenBlas}) {
    const char* engine = e == Engine::kSse2      ? "sse2"
                         : e == Engine::kFma     ? "fma"
                         : e == Engine::kFmaAvx2 ? "fma-avx2"
                                                 : "openblas";
    std::string name = std::string("arith/") + engine + "/" + std::to_string(m) + "x" +
                       std::to_string(k) + "x" + std::to_string(n) + "/" +
                       modes[static_cast<int>(mode)];
    if (bt) name += "/bt";
    benchmark::RegisterBenchmark(name.c_str(), run_case, Case{m, k, n, mode, bt, e})
        ->Unit(benchmark::kMicrosecond);
  }
}

const bool kRegistered = [] {
  // d = 10 LA core (s2): the kick/drift and the shear gradient.
  add(10, 10, 400, Epilogue::kAddScaled, false);
  add(10, 400, 10, Epilogue::kStore, true);
  // d = 100 LA core: 100 x 100 times 100 x N, and the gradients' 100 x N times N x 100.
  for (const Index n : {400, 512, 4000, 40000}) {
    add(100, 100, n, Epilogue::kAddScaled, false);
    add(100, n, 100, Epilogue::kStore, true);
  }
  return true;
}();

}  // namespace

}  // namespace csympnet::bench
