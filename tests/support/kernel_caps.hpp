// The instruction-set caps under which the kernel tests run each family: none (the widest form
// this machine runs: AVX-512 where present) and AVX2 (the forms of a machine without AVX-512,
// which a machine with it runs too once capped). Tests parameterised over the cap compare every
// form with the portable code.
#pragma once

#include <gtest/gtest.h>

#include <optional>
#include <string>

#include "../src/kernels/registry.hpp"
#include "../src/kernels/targets.hpp"

namespace csympnet::testing {

enum class KernelCap { kNone, kAvx2 };

inline std::string kernel_cap_name(const ::testing::TestParamInfo<KernelCap>& info) {
  return info.param == KernelCap::kNone ? "Widest" : "Avx2";
}

// Caps the instruction set for its lifetime (nothing for kNone).
class KernelCapScope {
 public:
  explicit KernelCapScope(KernelCap cap) {
    if (cap == KernelCap::kAvx2) guard_.emplace();
  }

 private:
  std::optional<kernels::CapAtAvx2> guard_;
};

// The form of a family that must run under `cap` where the kernels are expected at all (the
// portable build on an AVX-512 (F, VL) machine, nothing forced): the AVX-512 one, or its AVX2
// twin when capped.
inline kernels::Family expected_form(kernels::Family avx512, kernels::Family avx2, KernelCap cap) {
  return cap == KernelCap::kAvx2 ? avx2 : avx512;
}

inline bool kernels_expected_here() {
  return kernels::kernels_built() && kernels::cpu().avx512f && kernels::cpu().avx512vl &&
         !kernels::portable_forced_by_environment() && !kernels::avx2_capped_by_environment();
}

// A fixture for tests parameterised over the cap: the cap holds for the whole test.
class KernelCapTest : public ::testing::TestWithParam<KernelCap> {
 protected:
  KernelCap cap() const { return GetParam(); }

 private:
  KernelCapScope scope_{GetParam()};
};

}  // namespace csympnet::testing
