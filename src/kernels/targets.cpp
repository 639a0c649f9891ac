#include "targets.hpp"

#include "sse2_order.hpp"

namespace csympnet::kernels {

namespace {

CpuFeatures probe() {
  CpuFeatures f;
#if (defined(__x86_64__) || defined(__i386__)) && (defined(__GNUC__) || defined(__clang__))
  __builtin_cpu_init();
  f.avx = __builtin_cpu_supports("avx") != 0;
  f.avx2 = __builtin_cpu_supports("avx2") != 0;
  f.fma = __builtin_cpu_supports("fma") != 0;
  f.avx512f = __builtin_cpu_supports("avx512f") != 0;
  f.avx512vl = __builtin_cpu_supports("avx512vl") != 0;
  f.avx512dq = __builtin_cpu_supports("avx512dq") != 0;
  f.avx512bw = __builtin_cpu_supports("avx512bw") != 0;
#endif
  return f;
}

}  // namespace

const CpuFeatures& cpu() {
  static const CpuFeatures features = probe();  // thread-safe one-time initialisation
  return features;
}

bool kernels_built() {
#ifdef CSYMPNET_SSE2_ORDER_KERNELS
  return true;
#else
  return false;
#endif
}

}  // namespace csympnet::kernels
