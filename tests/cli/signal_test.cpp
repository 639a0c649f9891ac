// Every long stage of the classic recipe stops within a second of SIGINT or SIGTERM
// (docs/hardening.md, "Signals"): Ceres' LM, csympnet's own LM (normal equations of 4,111
// parameters taken in polled row blocks), L-BFGS and the bootstrap of `fit --recipe classic`,
// and `run`'s second stage. Each exits 128 + the signal, names the stage it stopped in, and
// keeps the best parameters so far with their report. AdamW, the identification recipe,
// `rollout`, blocking reads and `reproduce` have theirs in tests/cli/cli_test.cpp.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "cli/cli_support.hpp"

namespace csympnet {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using testing_cli::CliTest;
using testing_cli::shell_quote;
using testing_cli::slurp;

class Signals : public CliTest {
 protected:
  // 400 noisy pairs of the s2 chain (d = 10): enough that no second stage below ends by itself
  // within the delay.
  void SetUp() override {
    CliTest::SetUp();
    data_ = dir_ / "s2.csv";
    ASSERT_EQ(run("generate --preset s2 --n 400 --sigma 0.01 --out " + data_.string()).code, 0);
  }

  struct Stopped {
    int code = -1;
    long latency_ms = -1;
    std::string err;
  };

  // Starts `args`, sends `signal` after `delay` s, and measures how long the process takes to
  // end after it.
  Stopped signal_after(const std::string& args, const char* signal, double delay) const {
    const fs::path ms = dir_ / "latency_ms.txt", err = dir_ / "stderr.txt";
    const std::string cmd =
        std::string(CSYMPNET_CLI_PATH) + " " + args + " >/dev/null 2>" + shell_quote(err.string()) +
        " </dev/null & pid=$!; sleep " + std::to_string(delay) + "; t0=$(date +%s%N); kill -" +
        signal + " $pid; wait $pid; code=$?; echo $(( ($(date +%s%N) - t0) / 1000000 ))" + " > " +
        shell_quote(ms.string()) + "; exit $code";
    const int status = std::system(cmd.c_str());
    Stopped s;
    s.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    s.latency_ms = std::stol(slurp(ms));
    s.err = slurp(err);
    return s;
  }

  json classic_fit_stopped(const std::string& name, const std::string& options,
                           const char* signal = "INT") {
    const fs::path out = dir_ / name;
    const Stopped s = signal_after(
        "fit " + data_.string() + " --recipe classic -q " + options + " --out " + out.string(),
        signal, 1.5);
    EXPECT_EQ(s.code, std::string(signal) == "INT" ? 130 : 143) << name << ": " << s.err;
    EXPECT_LT(s.latency_ms, 1000) << name << " took " << s.latency_ms << " ms to stop";
    EXPECT_TRUE(fs::exists(out / "model.json")) << name;
    const json rep = json::parse(slurp(out / "report.json"));
    EXPECT_EQ(rep.value("interrupted", false), true) << name;
    last_err_ = s.err;
    return rep;
  }

  fs::path data_;
  std::string last_err_;
};

TEST_F(Signals, CeresLmStopsWithinASecond) {
  const json rep =
      classic_fit_stopped("ceres",
                          "--core g:2:8 --epochs 5 --refine lm --refine-solver dense_qr "
                          "--refine-iterations 100000000 --bootstrap 0");
  EXPECT_EQ(rep["refine"]["termination"], "interrupted");
  EXPECT_GT(rep["refine"]["iterations"].get<long>(), 0);
  EXPECT_LE(rep["refine"]["val_loss_after"].get<double>(),
            rep["refine"]["val_loss_before"].get<double>());  // the best iterate was kept
  EXPECT_NE(last_err_.find("stopped in the second stage (lm)"), std::string::npos) << last_err_;
}

TEST_F(Signals, OwnLmStopsWithinASecondInsideItsNormalEquations) {
  // 4,111 parameters and 6,400 residuals: one JᵀJ is ~1e11 operations, taken in row blocks.
  const json rep =
      classic_fit_stopped("blas",
                          "--epochs 5 --refine lm --refine-solver blas_normal_cholesky "
                          "--refine-iterations 100000000 --bootstrap 0",
                          "TERM");
  EXPECT_EQ(rep["params"], 4111);
  EXPECT_EQ(rep["refine"]["termination"], "interrupted");
}

TEST_F(Signals, LbfgsStopsWithinASecond) {
  const json rep = classic_fit_stopped(
      "lbfgs",
      "--core g:2:8 --epochs 5 --refine lbfgs --refine-iterations 100000000 --bootstrap 0");
  EXPECT_EQ(rep["refine"]["termination"], "interrupted");
  EXPECT_GT(rep["refine"]["iterations"].get<long>(), 0);
}

TEST_F(Signals, BootstrapStopsWithinASecondAndClaimsNoInterval) {
  const json rep = classic_fit_stopped(
      "boot", "--core g:2:8 --epochs 5 --refine lm --refine-iterations 2 --bootstrap 1000000");
  EXPECT_NE(rep["refine"]["termination"], "interrupted");  // the fit itself had finished
  EXPECT_TRUE(rep["gamma_ci_low"].is_null());
  EXPECT_NE(rep["gamma_ci_note"].get<std::string>().find("bootstrap was interrupted"),
            std::string::npos)
      << rep["gamma_ci_note"];
  EXPECT_NE(last_err_.find("stopped during the bootstrap"), std::string::npos) << last_err_;
}

TEST_F(Signals, RunSecondStageStopsWithinASecond) {
  const fs::path out = dir_ / "run";
  const Stopped s = signal_after(
      "run --preset s2 --model csympnet --core g:2:8 --epochs 5 "
      "--refine lm --refine-iterations 100000000 -q --out " +
          out.string(),
      "INT", 1.5);
  EXPECT_EQ(s.code, 130) << s.err;
  EXPECT_LT(s.latency_ms, 1000);
  const json rep = json::parse(slurp(out / "report.json"));
  EXPECT_EQ(rep["refine"]["termination"], "interrupted");
}

// A Ceres LM too large to stop within a second is refused before any training, naming the
// option and the solver that fits.
TEST_F(Signals, UninterruptibleCeresProblemsAreRefusedUpFront) {
  const testing_cli::CliResult r =
      run("fit " + data_.string() + " --recipe classic --refine lm --refine-solver dense_qr " +
          "--out " + (dir_ / "big").string());
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("--refine-solver: dense_qr with 4111 parameters"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("blas_normal_cholesky"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "big"));
}

}  // namespace
}  // namespace csympnet
