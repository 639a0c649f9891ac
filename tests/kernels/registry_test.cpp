// The kernels layer's registry (src/kernels/registry.hpp): one CPU probe, one rule for whether a
// kernel runs, and one switch that forces the portable code everywhere. On an AVX-512 machine
// (F, VL) in the portable build every family must run, so that a kernel whose self-check
// started failing, or whose dispatch broke, cannot pass unnoticed as "portable, same bits".
#include <gtest/gtest.h>

#include <string>

#include "../src/kernels/registry.hpp"
#include "../src/kernels/targets.hpp"

namespace csympnet::testing {
namespace {

using kernels::Family;

constexpr Family kAll[] = {Family::kProductAvx512, Family::kProductAvx, Family::kSigmoid,
                           Family::kScaledExp,     Family::kD1Sweeps,   Family::kConformalRows,
                           Family::kColumnScaling, Family::kAdamW,      Family::kFmaProductAvx512,
                           Family::kFmaProductAvx2};

bool avx512_machine() {
  return kernels::kernels_built() && kernels::cpu().avx512f && kernels::cpu().avx512vl;
}

TEST(KernelsRegistry, EveryFamilyRunsOnAnAvx512Machine) {
  if (kernels::portable_forced_by_environment()) GTEST_SKIP() << "CSYMPNET_KERNELS=portable";
  if (!avx512_machine()) GTEST_SKIP() << "no AVX-512F/VL here, or kernels not built";
  for (const Family f : kAll) {
    if (f == Family::kProductAvx && !kernels::cpu().avx) continue;
    EXPECT_TRUE(kernels::available(f)) << static_cast<int>(f);
    EXPECT_TRUE(kernels::use(f)) << static_cast<int>(f);
  }
  const bool fma = kernels::arithmetic() == kernels::Arithmetic::kFma;
  for (const kernels::KernelStatus& s : kernels::report()) {
    if ((s.name == "product" && s.isa == "avx") ||
        (s.name == "fma_product" && s.isa != "avx512f")) {
      EXPECT_FALSE(s.runs) << "the AVX-512 kernel is chosen first";
      continue;
    }
    if (s.name == (fma ? "product" : "fma_product")) {
      // The product families of the other arithmetic.
      EXPECT_FALSE(s.runs) << s.name;
      EXPECT_NE(s.why.find("not chosen: the arithmetic is"), std::string::npos) << s.why;
      continue;
    }
    EXPECT_TRUE(s.runs) << s.name << " " << s.isa << ": " << s.why;
    EXPECT_EQ(s.why, "runs");
  }
}

TEST(KernelsRegistry, ReportListsEveryFamilyOnce) {
  const auto report = kernels::report();
  ASSERT_EQ(report.size(), std::size(kAll));
  const std::string text = kernels::report_text();
  for (const char* name : {"product", "sigmoid", "scaled_exp", "d1_sweeps", "conformal_rows",
                           "column_scaling", "adamw", "fma_product"}) {
    EXPECT_NE(text.find(name), std::string::npos) << name;
  }
  EXPECT_NE(text.find(std::string("arithmetic: ") + kernels::to_string(kernels::arithmetic())),
            std::string::npos)
      << text;
  for (const kernels::KernelStatus& s : report) EXPECT_FALSE(s.why.empty()) << s.name;
}

TEST(KernelsRegistry, ForcePortableStopsEveryKernelUntilTheLastGuardEnds) {
  const bool env = kernels::portable_forced_by_environment();
  bool before[std::size(kAll)];
  for (std::size_t i = 0; i < std::size(kAll); ++i) before[i] = kernels::use(kAll[i]);
  {
    const kernels::ForcePortable outer;
    EXPECT_TRUE(kernels::portable_forced());
    {
      const kernels::ForcePortable inner;  // guards nest
      for (const Family f : kAll) EXPECT_FALSE(kernels::use(f));
    }
    for (const Family f : kAll) EXPECT_FALSE(kernels::use(f));
    for (const kernels::KernelStatus& s : kernels::report()) {
      EXPECT_FALSE(s.runs) << s.name;
      if (kernels::available(Family::kSigmoid) && s.name == "sigmoid") {
        EXPECT_NE(s.why.find("forced portable"), std::string::npos) << s.why;
      }
    }
  }
  EXPECT_EQ(kernels::portable_forced(), env);
  for (std::size_t i = 0; i < std::size(kAll); ++i) EXPECT_EQ(kernels::use(kAll[i]), before[i]);
  if (avx512_machine() && !env) {
    EXPECT_TRUE(kernels::use(Family::kSigmoid));
  }
}

TEST(KernelsRegistry, AKernelRunsOnlyWhereTheCpuHasItsInstructions) {
  const kernels::CpuFeatures& cpu = kernels::cpu();
  EXPECT_EQ(&cpu, &kernels::cpu());  // probed once
  if (!cpu.avx512f) {
    for (const Family f : {Family::kProductAvx512, Family::kSigmoid, Family::kScaledExp,
                           Family::kD1Sweeps, Family::kConformalRows, Family::kColumnScaling,
                           Family::kAdamW, Family::kFmaProductAvx512}) {
      EXPECT_FALSE(kernels::available(f));
    }
  }
  if (!cpu.avx512vl) {
    EXPECT_FALSE(kernels::available(Family::kD1Sweeps));
  }
  if (!cpu.avx) {
    EXPECT_FALSE(kernels::available(Family::kProductAvx));
  }
  if (!cpu.avx2 || !cpu.fma) {
    EXPECT_FALSE(kernels::available(Family::kFmaProductAvx2));
  }
  if (!kernels::kernels_built()) {
    EXPECT_FALSE(kernels::available(Family::kProductAvx512));
    EXPECT_FALSE(kernels::available(Family::kAdamW));
  }
}

}  // namespace
}  // namespace csympnet::testing
