// The CPU probe of the kernels layer: which instruction sets this machine offers, asked once per
// process. It is the only place in the tree that asks the CPU; every kernel family names the
// features it needs (registry.hpp) and the registry compares them with this answer.
#pragma once

namespace csympnet::kernels {

struct CpuFeatures {
  bool avx = false;
  bool avx2 = false;
  bool fma = false;
  bool avx512f = false;
  bool avx512vl = false;
  bool avx512dq = false;
  bool avx512bw = false;
};

// This machine's features (all false off x86 and in builds whose compiler cannot ask).
const CpuFeatures& cpu();

// Whether this build compiled the kernels at all: x86 with GCC, Eigen on SSE2 without AVX or
// FMA (the portable build whose order the kernels reproduce). See sse2_order.hpp.
bool kernels_built();

}  // namespace csympnet::kernels
