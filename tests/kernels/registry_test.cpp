// The kernels layer's registry (src/kernels/registry.hpp): one CPU probe, one rule for whether a
// kernel runs, and one switch that forces the portable code everywhere. On an AVX-512 machine
// (F, VL) in the portable build every family must run (capped at AVX2: every AVX2 form), so that
// a kernel whose self-check started failing, or whose dispatch broke, cannot pass unnoticed as
// "portable, same bits".
#include <gtest/gtest.h>

#include <string>

#include "../src/kernels/registry.hpp"
#include "../src/kernels/targets.hpp"

namespace csympnet::testing {
namespace {

using kernels::Family;

constexpr Family kAll[] = {Family::kProductAvx512,
                           Family::kProductAvx,
                           Family::kSigmoid,
                           Family::kSigmoidAvx2,
                           Family::kScaledExp,
                           Family::kScaledExpAvx2,
                           Family::kD1Sweeps,
                           Family::kD1SweepsAvx2,
                           Family::kConformalRows,
                           Family::kConformalRowsAvx2,
                           Family::kColumnScaling,
                           Family::kColumnScalingAvx2,
                           Family::kAdamW,
                           Family::kAdamWAvx2,
                           Family::kFmaProductAvx512,
                           Family::kFmaProductAvx2};

// The forms for machines without AVX-512 (the product's is AVX, the fma product's AVX2 + FMA).
constexpr Family kAvx2Forms[] = {Family::kProductAvx,        Family::kSigmoidAvx2,
                                 Family::kScaledExpAvx2,     Family::kD1SweepsAvx2,
                                 Family::kConformalRowsAvx2, Family::kColumnScalingAvx2,
                                 Family::kAdamWAvx2,         Family::kFmaProductAvx2};

bool is_avx2_form(const kernels::KernelStatus& s) {
  return s.isa == "avx" || s.isa == "avx2" || s.isa == "avx2+fma";
}

bool avx512_machine() {
  return kernels::kernels_built() && kernels::cpu().avx512f && kernels::cpu().avx512vl;
}

TEST(KernelsRegistry, EveryFamilyRunsOnAnAvx512Machine) {
  if (kernels::portable_forced_by_environment()) GTEST_SKIP() << "CSYMPNET_KERNELS=portable";
  if (kernels::avx2_capped_by_environment()) GTEST_SKIP() << "CSYMPNET_KERNELS=avx2";
  if (!avx512_machine()) GTEST_SKIP() << "no AVX-512F/VL here, or kernels not built";
  for (const Family f : kAll) {
    EXPECT_TRUE(kernels::available(f)) << static_cast<int>(f);
    EXPECT_TRUE(kernels::use(f)) << static_cast<int>(f);
  }
  const bool fma = kernels::arithmetic() == kernels::Arithmetic::kFma;
  for (const kernels::KernelStatus& s : kernels::report()) {
    if (is_avx2_form(s)) {
      EXPECT_FALSE(s.runs) << "the AVX-512 kernel is chosen first: " << s.name;
      if (s.name != (fma ? "product" : "fma_product")) {
        EXPECT_EQ(s.why.rfind("not chosen: the avx512f", 0), 0u) << s.why;
        EXPECT_NE(s.why.find(s.name + " kernel runs"), std::string::npos) << s.why;
      }
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

TEST(KernelsRegistry, CappedAtAvx2EveryAvx2FormRunsAndNoAvx512One) {
  if (kernels::portable_forced_by_environment()) GTEST_SKIP() << "CSYMPNET_KERNELS=portable";
  if (!avx512_machine()) GTEST_SKIP() << "no AVX-512F/VL here, or kernels not built";
  bool before[std::size(kAll)];
  for (std::size_t i = 0; i < std::size(kAll); ++i) before[i] = kernels::use(kAll[i]);
  {
    const kernels::CapAtAvx2 cap;
    EXPECT_TRUE(kernels::avx2_capped());
    for (const Family f : kAll) {
      EXPECT_EQ(kernels::use(f), !kernels::needs_avx512(f)) << static_cast<int>(f);
    }
    const bool fma = kernels::arithmetic() == kernels::Arithmetic::kFma;
    for (const kernels::KernelStatus& s : kernels::report()) {
      if (!is_avx2_form(s)) {
        EXPECT_FALSE(s.runs) << s.name;
        EXPECT_NE(s.why.find("capped at avx2"), std::string::npos) << s.name << ": " << s.why;
      } else if (s.name == (fma ? "product" : "fma_product")) {
        EXPECT_FALSE(s.runs) << s.name;
      } else {
        EXPECT_TRUE(s.runs) << s.name << " " << s.isa << ": " << s.why;
      }
    }
    for (const kernels::FormInUse& f : kernels::forms_in_use()) {
      if (f.name == (fma ? "product" : "fma_product")) {
        EXPECT_EQ(f.isa, "portable") << f.name;
      } else {
        EXPECT_TRUE(f.isa == "avx" || f.isa == "avx2" || f.isa == "avx2+fma")
            << f.name << ": " << f.isa;
      }
    }
    {
      const kernels::ForcePortable portable;  // forcing wins over the cap
      for (const Family f : kAll) EXPECT_FALSE(kernels::use(f)) << static_cast<int>(f);
    }
  }
  EXPECT_EQ(kernels::avx2_capped(), kernels::avx2_capped_by_environment());
  for (std::size_t i = 0; i < std::size(kAll); ++i) EXPECT_EQ(kernels::use(kAll[i]), before[i]);
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
  // One form in use per family name, in the report's order.
  const auto forms = kernels::forms_in_use();
  ASSERT_EQ(forms.size(), 8u);
  EXPECT_EQ(forms.front().name, "product");
  EXPECT_EQ(forms.back().name, "fma_product");
  EXPECT_NE(text.find("in use: product "), std::string::npos) << text;
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
    EXPECT_TRUE(kernels::use(kernels::avx2_capped_by_environment() ? Family::kSigmoidAvx2
                                                                   : Family::kSigmoid));
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
  if (!cpu.avx2) {
    for (const Family f : kAvx2Forms) {
      if (f != Family::kProductAvx) {
        EXPECT_FALSE(kernels::available(f)) << static_cast<int>(f);
      }
    }
  }
  for (const Family f : kAvx2Forms) EXPECT_FALSE(kernels::needs_avx512(f));
  if (!kernels::kernels_built()) {
    EXPECT_FALSE(kernels::available(Family::kProductAvx512));
    EXPECT_FALSE(kernels::available(Family::kAdamW));
  }
}

}  // namespace
}  // namespace csympnet::testing
