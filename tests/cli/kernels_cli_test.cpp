// The kernels switch from the command line: `csympnet kernels` lists every kernel family and
// whether it runs; CSYMPNET_KERNELS=portable forces the portable code in the whole process,
// CSYMPNET_KERNELS=avx2 the forms of a CPU without AVX-512, and a run under either writes the
// same report and model, bit for bit, as a run with the widest kernels.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "../src/kernels/registry.hpp"
#include "../src/kernels/targets.hpp"
#include "cli_support.hpp"

namespace csympnet::testing_cli {
namespace {

namespace fs = std::filesystem;

class KernelsCli : public CliTest {};

int count(const std::string& text, const std::string& what) {
  int n = 0;
  for (auto p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
  return n;
}

TEST_F(KernelsCli, ListsEveryFamilyAndTheSwitchForcesThePortableCode) {
  const CliResult plain = run("kernels", "CSYMPNET_KERNELS= CSYMPNET_ARITHMETIC=");
  ASSERT_EQ(plain.code, 0) << plain.err;
  for (const char* name : {"product", "sigmoid", "scaled_exp", "d1_sweeps", "conformal_rows",
                           "column_scaling", "adamw", "fma_product"}) {
    EXPECT_NE(plain.out.find(name), std::string::npos) << name << "\n" << plain.out;
  }
  // 16 forms, the forms in use and the arithmetic.
  EXPECT_EQ(count(plain.out, "\n"), 18) << plain.out;
  EXPECT_NE(plain.out.find("\nin use: product "), std::string::npos) << plain.out;
  EXPECT_NE(plain.out.find(std::string("arithmetic: ") +
                           kernels::to_string(kernels::kDefaultArithmetic) + " (default)"),
            std::string::npos)
      << plain.out;
  const auto& cpu = kernels::cpu();
  if (kernels::kernels_built() && cpu.avx512f && cpu.avx512vl) {
    // All but the AVX and AVX2 forms and the two fma kernels (not the arithmetic).
    EXPECT_EQ(count(plain.out, ": runs"), 7) << plain.out;
    EXPECT_NE(plain.out.find("in use: product avx512f, sigmoid avx512f, scaled_exp avx512f, "
                             "d1_sweeps avx512f+avx512vl, conformal_rows avx512f, "
                             "column_scaling avx512f, adamw avx512f, fma_product portable"),
              std::string::npos)
        << plain.out;
    const CliResult capped = run("kernels", "CSYMPNET_KERNELS=avx2 CSYMPNET_ARITHMETIC=");
    ASSERT_EQ(capped.code, 0) << capped.err;
    EXPECT_EQ(count(capped.out, ": runs"), 7) << capped.out;
    EXPECT_EQ(count(capped.out, "capped at avx2 (CSYMPNET_KERNELS=avx2)"), 8) << capped.out;
    EXPECT_NE(capped.out.find("in use: product avx, sigmoid avx2, scaled_exp avx2, d1_sweeps "
                              "avx2, conformal_rows avx2, column_scaling avx2, adamw avx2, "
                              "fma_product portable"),
              std::string::npos)
        << capped.out;
    const CliResult capped_version = run("--version", "CSYMPNET_KERNELS=avx2");
    ASSERT_EQ(capped_version.code, 0);
    EXPECT_NE(capped_version.out.find("sigmoid (avx2)"), std::string::npos) << capped_version.out;
    EXPECT_NE(capped_version.out.find("capped at avx2"), std::string::npos) << capped_version.out;
    const CliResult fma = run("kernels", "CSYMPNET_KERNELS= CSYMPNET_ARITHMETIC=fma");
    ASSERT_EQ(fma.code, 0) << fma.err;
    EXPECT_NE(fma.out.find("fma_product avx512f: runs"), std::string::npos) << fma.out;
    EXPECT_NE(fma.out.find("product avx512f: portable, not chosen: the arithmetic is fma"),
              std::string::npos)
        << fma.out;
    EXPECT_NE(fma.out.find("arithmetic: fma (CSYMPNET_ARITHMETIC)"), std::string::npos) << fma.out;
  }
  const CliResult forced = run("kernels", "CSYMPNET_KERNELS=portable CSYMPNET_ARITHMETIC=");
  ASSERT_EQ(forced.code, 0) << forced.err;
  EXPECT_EQ(count(forced.out, ": runs"), 0) << forced.out;
  // Every family that ran (or was available but not chosen) now says why it does not.
  EXPECT_EQ(count(forced.out, "CSYMPNET_KERNELS=portable"),
            count(plain.out, ": runs") + count(plain.out, "not chosen"))
      << forced.out;

  const CliResult version = run("--version", "CSYMPNET_KERNELS=portable");
  ASSERT_EQ(version.code, 0);
  EXPECT_EQ(version.out.rfind("csympnet ", 0), 0u) << version.out;
  EXPECT_NE(version.out.find("portable code only"), std::string::npos) << version.out;
}

// A small training run of each core kind (d = 1 LA, d = 10 LA, d = 10 G) with the widest
// kernels, with CSYMPNET_KERNELS=avx2 (the forms of a CPU without AVX-512) and with
// CSYMPNET_KERNELS=portable: the same report (timings aside) and the same model file, byte for
// byte.
TEST_F(KernelsCli, PortableAndAvx2RunsWriteTheKernelsBits) {
  for (const char* preset : {"s1", "s2", "s3"}) {
    for (const char* model : {"csympnet"}) {
      SCOPED_TRACE(std::string(preset) + " " + model);
      const std::string common = std::string("run --preset ") + preset + " --model " + model +
                                 " --seed 3 --epochs 40 --quiet --out ";
      const fs::path a = dir_ / (std::string(preset) + model + "_kernels");
      const CliResult ra = run(common + a.string(), "CSYMPNET_KERNELS=");
      ASSERT_EQ(ra.code, 0) << ra.err;
      auto ja = nlohmann::json::parse(slurp(a / "report.json"));
      for (const char* timing : {"train_seconds", "eval_seconds"}) ja.erase(timing);
      for (const char* kernels : {"portable", "avx2"}) {
        SCOPED_TRACE(kernels);
        const fs::path b = dir_ / (std::string(preset) + model + "_" + kernels);
        const CliResult rb = run(common + b.string(), std::string("CSYMPNET_KERNELS=") + kernels);
        ASSERT_EQ(rb.code, 0) << rb.err;
        auto jb = nlohmann::json::parse(slurp(b / "report.json"));
        for (const char* timing : {"train_seconds", "eval_seconds"}) jb.erase(timing);
        EXPECT_EQ(ja.dump(), jb.dump());
        EXPECT_EQ(slurp(a / "model.json"), slurp(b / "model.json"));
        EXPECT_EQ(slurp(a / "rollout.csv"), slurp(b / "rollout.csv"));
      }
    }
  }
}

// The fma arithmetic end to end: a training run gives the same model on 1 and 2 threads, with
// the kernels and with the portable std::fma reference (CSYMPNET_KERNELS=portable), and from the
// variable or the option; it differs from the sse2 run; reports and model files record the
// arithmetic when it is not the default, and only then. An unknown value stops the command with an
// error that names the variable.
TEST_F(KernelsCli, FmaArithmeticIsThreadAndKernelInvariantAndRecorded) {
  for (const char* preset : {"s2", "s3"}) {
    SCOPED_TRACE(preset);
    const std::string common =
        std::string("run --preset ") + preset + " --seed 5 --epochs 30 --quiet --out ";
    const auto out = [&](const char* tag) { return dir_ / (std::string(preset) + "_" + tag); };
    const CliResult r1 =
        run(common + out("fma1").string() + " --threads 1", "CSYMPNET_ARITHMETIC=fma");
    ASSERT_EQ(r1.code, 0) << r1.err;
    const CliResult r2 =
        run(common + out("fma2").string() + " --threads 2", "CSYMPNET_ARITHMETIC=fma");
    ASSERT_EQ(r2.code, 0) << r2.err;
    const CliResult rp = run(common + out("fmap").string() + " --threads 2",
                             "CSYMPNET_ARITHMETIC=fma CSYMPNET_KERNELS=portable");
    ASSERT_EQ(rp.code, 0) << rp.err;
    const CliResult ro =
        run(common + out("fmao").string() + " --arithmetic fma", "CSYMPNET_ARITHMETIC=sse2");
    ASSERT_EQ(ro.code, 0) << ro.err;
    const CliResult rd = run(common + out("sse2").string(), "CSYMPNET_ARITHMETIC=sse2");
    ASSERT_EQ(rd.code, 0) << rd.err;

    const std::string model = slurp(out("fma1") / "model.json");
    EXPECT_EQ(slurp(out("fma2") / "model.json"), model);
    EXPECT_EQ(slurp(out("fmap") / "model.json"), model);
    EXPECT_EQ(slurp(out("fmao") / "model.json"), model);
    EXPECT_NE(slurp(out("sse2") / "model.json"), model);

    // Recorded where it is not the default (and then by name), absent where it is.
    const auto recorded = [&](const char* tag, const char* name) {
      const auto report = nlohmann::json::parse(slurp(out(tag) / "report.json"));
      const auto file = nlohmann::json::parse(slurp(out(tag) / "model.json"));
      const bool is_default = kernels::to_string(kernels::kDefaultArithmetic) == std::string(name);
      EXPECT_EQ(report.at("config").value("arithmetic", "absent"), is_default ? "absent" : name);
      EXPECT_EQ(file.at("meta").value("arithmetic", "absent"), is_default ? "absent" : name);
    };
    recorded("fma1", "fma");
    recorded("sse2", "sse2");
  }
  const CliResult bad = run("kernels", "CSYMPNET_ARITHMETIC=avx512");
  EXPECT_EQ(bad.code, 1);
  EXPECT_NE(bad.err.find("CSYMPNET_ARITHMETIC = 'avx512'"), std::string::npos) << bad.err;
  EXPECT_NE(bad.err.find("expected 'sse2'"), std::string::npos) << bad.err;
  const CliResult bad_option =
      run("run --preset s2 --arithmetic avx --out " + (dir_ / "bad").string());
  EXPECT_EQ(bad_option.code, 2);
  EXPECT_NE(bad_option.err.find("--arithmetic"), std::string::npos) << bad_option.err;
}

}  // namespace
}  // namespace csympnet::testing_cli
