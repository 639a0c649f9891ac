// The kernels switch from the command line: `csympnet kernels` lists every kernel family and
// whether it runs; CSYMPNET_KERNELS=portable forces the portable code in the whole process, and
// a run under it writes the same report and model, bit for bit, as a run with the kernels.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

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
  const CliResult plain = run("kernels", "CSYMPNET_KERNELS=");
  ASSERT_EQ(plain.code, 0) << plain.err;
  for (const char* name : {"product", "sigmoid", "scaled_exp", "d1_sweeps", "conformal_rows",
                           "column_scaling", "adamw"}) {
    EXPECT_NE(plain.out.find(name), std::string::npos) << name << "\n" << plain.out;
  }
  EXPECT_EQ(count(plain.out, "\n"), 8) << plain.out;
  const auto& cpu = kernels::cpu();
  if (kernels::kernels_built() && cpu.avx512f && cpu.avx512vl) {
    EXPECT_EQ(count(plain.out, ": runs"), 7) << plain.out;  // all but the AVX product kernel
  }
  const CliResult forced = run("kernels", "CSYMPNET_KERNELS=portable");
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

// A small training run of each core kind (d = 1 LA, d = 10 LA, d = 10 G) with the kernels and with
// CSYMPNET_KERNELS=portable: the same report (timings aside) and the same model file, byte for
// byte.
TEST_F(KernelsCli, PortableRunsWriteTheKernelsBits) {
  for (const char* preset : {"s1", "s2", "s3"}) {
    for (const char* model : {"csympnet"}) {
      SCOPED_TRACE(std::string(preset) + " " + model);
      const std::string common = std::string("run --preset ") + preset + " --model " + model +
                                 " --seed 3 --epochs 40 --quiet --out ";
      const fs::path a = dir_ / (std::string(preset) + model + "_kernels");
      const fs::path b = dir_ / (std::string(preset) + model + "_portable");
      const CliResult ra = run(common + a.string(), "CSYMPNET_KERNELS=");
      ASSERT_EQ(ra.code, 0) << ra.err;
      const CliResult rb = run(common + b.string(), "CSYMPNET_KERNELS=portable");
      ASSERT_EQ(rb.code, 0) << rb.err;
      auto ja = nlohmann::json::parse(slurp(a / "report.json"));
      auto jb = nlohmann::json::parse(slurp(b / "report.json"));
      for (const char* timing : {"train_seconds", "eval_seconds"}) {
        ja.erase(timing);
        jb.erase(timing);
      }
      EXPECT_EQ(ja.dump(), jb.dump());
      EXPECT_EQ(slurp(a / "model.json"), slurp(b / "model.json"));
      EXPECT_EQ(slurp(a / "rollout.csv"), slurp(b / "rollout.csv"));
    }
  }
}

}  // namespace
}  // namespace csympnet::testing_cli
