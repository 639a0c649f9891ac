// End-to-end tests of the csympnet binary: exit codes, messages, files, determinism.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <sys/wait.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "support/sanitizers.hpp"
#include "support/shell_and_files.hpp"

namespace {

namespace fs = std::filesystem;

struct Result {
  int code = -1;
  std::string out, err;
};

using csympnet::testing::slurp;

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("csympnet_cli_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
            std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  Result run(const std::string& args) {
    const fs::path out = dir_ / "stdout.txt", err = dir_ / "stderr.txt";
    const std::string cmd = std::string(CSYMPNET_CLI_PATH) + " " + args + " >" + out.string() +
                            " 2>" + err.string() + " </dev/null";
    const int status = std::system(cmd.c_str());
    Result r;
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    r.out = slurp(out);
    r.err = slurp(err);
    return r;
  }

  // Starts the CLI in the background, waits until `ready` exists (the command has passed option
  // parsing, so its signal handlers are installed) plus `delay` seconds, sends `signal`, and
  // waits for it. A fixed delay from process start flaked on a loaded CI machine: the signal
  // arrived before main() had installed the handlers and the default action killed the process.
  Result run_and_signal(const std::string& args, const fs::path& ready, const char* signal,
                        double delay) {
    const fs::path out = dir_ / "stdout.txt", err = dir_ / "stderr.txt";
    const std::string cmd = std::string(CSYMPNET_CLI_PATH) + " " + args + " >" + out.string() +
                            " 2>" + err.string() + " </dev/null & pid=$!; i=0; " +
                            "while [ ! -e '" + ready.string() + "' ] && [ $i -lt 1200 ]; " +
                            "do sleep 0.05; i=$((i+1)); done; sleep " + std::to_string(delay) +
                            "; kill -" + signal + " $pid; wait $pid";
    const int status = std::system(cmd.c_str());
    Result r;
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    r.out = slurp(out);
    r.err = slurp(err);
    return r;
  }

  fs::path write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    std::ofstream(p) << text;
    return p;
  }

  fs::path dir_;
};

// docs/protocol.md, "Models and their parameter counts": the whole table, 8 models x 5
// presets.
TEST_F(Cli, DescribeReportsTheProtocolParameterCounts) {
  const std::array<const char*, 8> models{"csympnet", "sympnet", "map",  "ode",
                                          "dhnn",     "dhnn2",   "phnn", "phnn2"};
  // Columns: s1, s2, s3, s2-100, s3-100.
  const std::array<std::array<long, 5>, 8> expected{{
      {115, 4111, 4201, 161101, 161101},
      {114, 4110, 4200, 161100, 161100},
      {1250, 6868, 6868, 168904, 168904},
      {1218, 6804, 6804, 168648, 168648},
      {2374, 11538, 11538, 275010, 275010},
      {1190, 5970, 5970, 157506, 157506},
      {1193, 6369, 6369, 197505, 197505},
      {1190, 5970, 5970, 157506, 157506},
  }};
  const std::array<const char*, 5> presets{"s1", "s2", "s3", "s2-100", "s3-100"};
  for (std::size_t m = 0; m < models.size(); ++m) {
    for (std::size_t p = 0; p < presets.size(); ++p) {
      const Result r =
          run(std::string("describe --preset ") + presets[p] + " --model " + models[m]);
      ASSERT_EQ(r.code, 0) << r.err;
      const auto j = nlohmann::json::parse(r.out);
      EXPECT_EQ(j["params"].get<long>(), expected[m][p]) << presets[p] << " " << models[m];
    }
  }
}

TEST_F(Cli, RunWritesItsFilesAndIsBitReproducible) {
  const std::string common = "run --preset s1 --model csympnet --seed 7 --epochs 300 --quiet";
  const Result a = run(common + " --out " + (dir_ / "a").string());
  ASSERT_EQ(a.code, 0) << a.err;
  const Result b = run(common + " --out " + (dir_ / "b").string());
  ASSERT_EQ(b.code, 0) << b.err;
  for (const char* f : {"report.json", "model.json", "rollout.csv", "reference.csv", "energy.csv"})
    EXPECT_TRUE(fs::exists(dir_ / "a" / f)) << f;
  auto ja = nlohmann::json::parse(slurp(dir_ / "a" / "report.json"));
  auto jb = nlohmann::json::parse(slurp(dir_ / "b" / "report.json"));
  for (const char* timing : {"train_seconds", "eval_seconds"}) {
    EXPECT_TRUE(ja.contains(timing));
    ja.erase(timing);
    jb.erase(timing);
  }
  EXPECT_EQ(ja.dump(), jb.dump());
  EXPECT_EQ(slurp(dir_ / "a" / "model.json"), slurp(dir_ / "b" / "model.json"));
  EXPECT_EQ(slurp(dir_ / "a" / "rollout.csv"), slurp(dir_ / "b" / "rollout.csv"));
  for (const char* key : {"model", "preset", "params", "seed", "epochs", "train_seconds",
                          "best_val_loss", "gamma_hat", "gamma_true", "gamma_abs_err", "l2_error",
                          "residual_mean", "residual_max", "lambda_abs_err_mean", "config"})
    EXPECT_TRUE(nlohmann::json::parse(slurp(dir_ / "a" / "report.json")).contains(key)) << key;
  EXPECT_EQ(ja["params"], 115);
  EXPECT_EQ(ja["seed"], 7);

  // A different seed gives different results.
  const Result c = run("run --preset s1 --model csympnet --seed 8 --epochs 300 --quiet --out " +
                       (dir_ / "c").string());
  ASSERT_EQ(c.code, 0) << c.err;
  EXPECT_NE(slurp(dir_ / "a" / "model.json"), slurp(dir_ / "c" / "model.json"));
}

TEST_F(Cli, RefusesToOverwriteANonEmptyOutputDirectory) {
  fs::create_directories(dir_ / "keep");
  const fs::path note = write("keep/notes.txt", "mine");
  const std::string args = "run --preset s1 --epochs 5 --quiet --out " + (dir_ / "keep").string();
  Result r = run(args);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--force"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "keep" / "report.json"));
  r = run(args + " --force");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(slurp(note), "mine");  // --force writes our files, it never deletes the user's
}

// Two writers into one output directory: while the first runs, a second (even with --force)
// is refused with the first one's pid and creates nothing; the first's result is whole, and
// its lock file is gone when it ends (here by SIGTERM, which keeps the best checkpoint).
TEST_F(Cli, ASecondWriterIntoTheSameDirectoryIsRefused) {
  const fs::path out = dir_ / "shared";
  const fs::path second_err = dir_ / "second.txt";
  const std::string first = std::string(CSYMPNET_CLI_PATH) +
                            " run --preset s2 --model csympnet --epochs 1000000 -q --out " +
                            out.string();
  const std::string second = std::string(CSYMPNET_CLI_PATH) +
                             " run --preset s1 --epochs 5 -q --force --out " + out.string();
  const std::string lock = (out / ".csympnet.lock").string();
  const std::string cmd = first + " >/dev/null 2>&1 </dev/null & pid=$!; i=0; while [ ! -e '" +
                          lock + "' ] && [ $i -lt 1200 ]; do sleep 0.05; i=$((i+1)); done; " +
                          second + " >/dev/null 2>" + second_err.string() +
                          " </dev/null; code=$?; kill -TERM $pid; wait $pid; exit $code";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1);
  const std::string err = slurp(second_err);
  EXPECT_NE(err.find("is being written by another csympnet (pid "), std::string::npos) << err;
  // The first writer, stopped by TERM, leaves its report whole; on a loaded machine TERM can
  // come before its training began, and then it has nothing to save and writes nothing. Never
  // the second writer's files, never a partial one.
  if (fs::exists(out / "report.json")) {
    const auto report = nlohmann::json::parse(slurp(out / "report.json"));
    EXPECT_EQ(report["preset"], "s2");  // the first writer's, whole
    EXPECT_TRUE(fs::exists(out / "model.json"));
  }
  EXPECT_FALSE(fs::exists(out / ".csympnet.lock"));
}

// A run that fails leaves no empty output directory behind; one into an existing directory
// leaves it as it was.
TEST_F(Cli, AFailedRunLeavesNoEmptyOutputDirectory) {
  const fs::path bad = write("bad.csv", "t,q1,p1\n0,1,oops\n");
  Result r = run("fit " + bad.string() + " -q --out " + (dir_ / "new").string());
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "new"));
  fs::create_directories(dir_ / "mine");
  r = run("fit " + bad.string() + " -q --out " + (dir_ / "mine").string());
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(fs::is_directory(dir_ / "mine"));
  EXPECT_TRUE(fs::is_empty(dir_ / "mine"));
}

// Inputs are read once: standard input ("-") and a pipe work; /dev/zero is refused at its
// first NUL byte instead of being read into memory; a FIFO nobody writes to does not hang the
// command past a SIGINT, which exits 130 and leaves no output directory.
TEST_F(Cli, InputsAreReadOnceFromStdinPipesAndFifos) {
  const std::string cli = CSYMPNET_CLI_PATH;
  ASSERT_EQ(run("generate --preset s1 --split train --out " + (dir_ / "s1.csv").string()).code, 0);
  const std::string small = " -q --epochs 200 --lm-iterations 3 --core la:2:2 --out ";
  const std::string piped = "cat " + (dir_ / "s1.csv").string() + " | " + cli + " fit -" + small +
                            (dir_ / "stdin").string() + " >/dev/null 2>&1";
  EXPECT_EQ(std::system(piped.c_str()), 0);
  const auto rep = nlohmann::json::parse(slurp(dir_ / "stdin" / "report.json"));
  EXPECT_EQ(rep["data"]["file"], "-");
  EXPECT_EQ(rep["identified"], true);

  Result r = run("fit /dev/zero -q --out " + (dir_ / "zero").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("NUL byte"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "zero"));

  const fs::path fifo = dir_ / "fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const fs::path err = dir_ / "fifo_err.txt";
  const std::string cmd = cli + " fit " + fifo.string() + " -q --out " + (dir_ / "never").string() +
                          " 2>" + err.string() + " & pid=$!; sleep 0.3; kill -INT $pid; wait $pid";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130) << slurp(err);
  EXPECT_NE(slurp(err).find("interrupted by SIGINT"), std::string::npos) << slurp(err);
  EXPECT_FALSE(fs::exists(dir_ / "never"));
}

// A reproduce.json is trusted by its content: a user's own file of that name does not make
// the directory resumable, so nothing of theirs is overwritten without --force.
TEST_F(Cli, ReproduceTrustsItsMarkerByContentNotName) {
  fs::create_directories(dir_ / "mine");
  const fs::path marker = write("mine/reproduce.json", R"({"my": "notes"})");
  const fs::path summary = write("mine/summary.json", R"({"my": "summary"})");
  const Result r = run("reproduce --suite quick --no-figures -q --out " + (dir_ / "mine").string());
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("--force"), std::string::npos) << r.err;
  EXPECT_EQ(slurp(marker), R"({"my": "notes"})");
  EXPECT_EQ(slurp(summary), R"({"my": "summary"})");
}

// `fit` stops within a second of SIGINT in every stage it reaches on a d = 10 fit of 1,990
// samples (AdamW, then LM iterations of several seconds whose normal equations poll the
// signal per chunk), exits 130, and keeps the best parameters so far with their report.
TEST_F(Cli, FitStopsWithinASecondOfSigintInEveryStage) {
  const fs::path data = dir_ / "d10.csv";
  ASSERT_EQ(run("generate --preset s2 --split test --n 39 --out " + data.string()).code, 0);
  for (const double delay : {0.3, 1.5, 4.0, 7.0}) {
    const fs::path out = dir_ / ("int" + std::to_string(static_cast<int>(delay * 10)));
    const fs::path ms = dir_ / "latency_ms.txt";
    const std::string cmd = std::string(CSYMPNET_CLI_PATH) + " fit " + data.string() +
                            " -q --out " + out.string() + " >/dev/null 2>&1 & pid=$!; sleep " +
                            std::to_string(delay) +
                            "; t0=$(date +%s%N); kill -INT $pid; wait $pid; code=$?; "
                            "echo $(( ($(date +%s%N) - t0) / 1000000 )) > " +
                            ms.string() + "; exit $code";
    const int status = std::system(cmd.c_str());
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 130) << "signalled after " << delay << " s";
    const long latency = std::stol(slurp(ms));
    EXPECT_LT(latency, 1000) << "signalled after " << delay << " s";
    const auto rep = nlohmann::json::parse(slurp(out / "report.json"));
    EXPECT_EQ(rep["stopped"], true);
    EXPECT_EQ(rep["identified"], false);
    EXPECT_TRUE(fs::exists(out / "model.json"));
  }
}

// Messages name both files and the real dimensions, and a one-pair file is told about --val.
TEST_F(Cli, MismatchedValidationAndOnePairFilesSayWhatToDo) {
  const fs::path s1 = dir_ / "s1.csv", s2 = dir_ / "s2val.csv";
  ASSERT_EQ(run("generate --preset s1 --n 20 --out " + s1.string()).code, 0);
  ASSERT_EQ(run("generate --preset s2 --split val --n 5 --out " + s2.string()).code, 0);
  Result r = run("train --data " + s1.string() + " --val " + s2.string() + " -q --epochs 5 --out " +
                 (dir_ / "o").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--val " + s2.string() + " has d = 10 (20 state columns) but " +
                       s1.string() + " has d = 1"),
            std::string::npos)
      << r.err;
  const fs::path one = write("one.csv", "h,q1,p1,next_q1,next_p1\n0.1,1,0,0.9,-0.1\n");
  r = run("train --data " + one.string() + " -q --out " + (dir_ / "o").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("a separate validation file (--val FILE)"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "o"));
}

// rollout streams its rows: 1e8 steps run in constant memory and stop within a second of
// SIGINT with exit 130 (they were all computed, 2.35 GB, before the first row was printed).
TEST_F(Cli, RolloutStreamsAndStopsOnSigint) {
  const fs::path out = dir_ / "m";
  ASSERT_EQ(run("run --preset s1 --epochs 5 -q --out " + out.string()).code, 0);
  const fs::path rows = dir_ / "rows.csv", ms = dir_ / "ms.txt";
  const std::string cmd = std::string(CSYMPNET_CLI_PATH) + " rollout --model " +
                          (out / "model.json").string() +
                          " --z0 0.5,-0.25 --h 0.2 --steps 100000000 >" + rows.string() +
                          " 2>/dev/null & pid=$!; sleep 1; t0=$(date +%s%N); kill -INT $pid; "
                          "wait $pid; code=$?; echo $(( ($(date +%s%N) - t0) / 1000000 )) > " +
                          ms.string() + "; exit $code";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130);
  EXPECT_LT(std::stol(slurp(ms)), 1000);
  // Rows were printed before the signal: streamed, not held back.
  EXPECT_GT(fs::file_size(rows), 1000u);
  EXPECT_EQ(slurp(rows).rfind("t,q1,p1\n0,0.5,-0.25\n", 0), 0u);
}

TEST_F(Cli, SavedModelRollsOutAndEvaluates) {
  const fs::path out = dir_ / "m";
  ASSERT_EQ(run("run --preset s1 --epochs 50 --quiet --out " + out.string()).code, 0);
  const std::string model = (out / "model.json").string();
  Result r = run("rollout --model " + model + " --z0 0.5,-0.25 --h 0.2 --steps 3");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 5);  // header + 4 states
  EXPECT_EQ(r.out.rfind("t,q1,p1\n0,0.5,-0.25\n", 0), 0u) << r.out;
  r = run("rollout --model " + model + " --z0 0.5 --h 0.2 --steps 3");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--z0"), std::string::npos) << r.err;
  // A step far outside the training range overflows: an error naming the step, no nan rows.
  r = run("rollout --model " + model + " --z0 0.5,-0.25 --h 1e300 --steps 3");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_EQ(r.out.find("nan"), std::string::npos) << r.out;
  EXPECT_NE(r.err.find("not finite after step"), std::string::npos) << r.err;
  r = run("evaluate --model " + model + " --preset s1");
  ASSERT_EQ(r.code, 0) << r.err;
  // Same model, same test set: evaluate agrees with the run's own report bit for bit.
  const auto ev = nlohmann::json::parse(r.out);
  const auto rep = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_EQ(ev["l2_error"], rep["l2_error"]);
  EXPECT_EQ(ev["residual_max"], rep["residual_max"]);
}

TEST_F(Cli, FitReadsIrregularTrajectoriesAndPrintsGamma) {
  // A damped rotation sampled at irregular times (exact solution of q' = p, p' = −q − γp).
  std::string csv = "traj,t,q1,p1\n";
  const double g = 0.05, w = std::sqrt(1 - g * g / 4);
  double t = 0;
  for (int k = 0; k < 60; ++k) {
    const double e = std::exp(-g * t / 2);
    const double q = e * std::cos(w * t);
    const double p = e * (-g / 2 * std::cos(w * t) - w * std::sin(w * t));
    char buf[128];
    std::snprintf(buf, sizeof buf, "0,%.17g,%.17g,%.17g\n", t, q, p);
    csv += buf;
    t += 0.05 + 0.1 * ((k * 37) % 11) / 10.0;
  }
  const fs::path data = write("traj.csv", csv);
  const Result r =
      run("fit " + data.string() + " --epochs 200 --quiet --out " + (dir_ / "fit").string());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out.rfind("gamma_hat = ", 0), 0u) << r.out;
  const auto rep = nlohmann::json::parse(slurp(dir_ / "fit" / "report.json"));
  EXPECT_EQ(rep["data"]["steps"].get<int>(), 59);
  EXPECT_TRUE(rep["identified"].is_boolean());
  EXPECT_TRUE(fs::exists(dir_ / "fit" / "model.json"));
}

// A model scored on a user's own trajectories, with no system known: evaluate --data reports
// the observed scores and assumes no γ; without --data it says what it needs.
TEST_F(Cli, EvaluateScoresAModelOnObservedTrajectoriesWithoutASystem) {
  std::string csv = "t,q1,p1\n";
  const double g = 0.05, w = std::sqrt(1 - g * g / 4);
  for (int k = 0; k < 80; ++k) {
    const double t = 0.1 * k, e = std::exp(-g * t / 2);
    char buf[128];
    std::snprintf(buf, sizeof buf, "%.17g,%.17g,%.17g\n", t, 3.0 + e * std::cos(w * t),
                  e * (-g / 2 * std::cos(w * t) - w * std::sin(w * t)));
    csv += buf;
  }
  const fs::path data = write("traj.csv", csv);
  ASSERT_EQ(
      run("fit " + data.string() + " --recipe classic --epochs 100 --bootstrap 0 --quiet --out " +
          (dir_ / "fit").string())
          .code,
      0);
  const std::string model = (dir_ / "fit" / "model.json").string();
  Result r = run("evaluate --model " + model + " --data " + data.string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto ev = nlohmann::json::parse(r.out);
  EXPECT_TRUE(ev["gamma_true"].is_null()) << r.out;
  EXPECT_TRUE(ev["system"].is_null());
  EXPECT_TRUE(ev["gamma_hat"].is_number());
  EXPECT_EQ(ev["observed"]["pairs"].get<int>(), 79);
  EXPECT_GT(ev["observed"]["one_step_r2"].get<double>(), 0.5);
  EXPECT_EQ(ev["observed"]["per_trajectory"].size(), 1u);
  EXPECT_EQ(ev.count("l2_error"), 0u);  // the system-based diagnostics need a system

  r = run("evaluate --model " + model);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--data or --preset is required"), std::string::npos) << r.err;
  r = run("evaluate --model " + model + " --data " + data.string() + " --gamma 0.1");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("expected --preset with them"), std::string::npos) << r.err;
  // With a preset, the system's diagnostics and the observed scores both.
  r = run("evaluate --model " + model + " --data " + data.string() + " --preset s1");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto both = nlohmann::json::parse(r.out);
  EXPECT_EQ(both["gamma_true"].get<double>(), 0.05);
  EXPECT_TRUE(both["l2_error"].is_number());
  EXPECT_EQ(both["observed"], ev["observed"]);
}

// A file with its own header names reads through --columns exactly like csympnet's own
// header; train takes its data positionally like fit, and --data still works.
TEST_F(Cli, ColumnsMapAFilesOwnHeaderAndDataIsPositional) {
  std::string own = "temperature,time_s,omega,theta\n", canonical = "t,q1,p1\n";
  const double g = 0.05, w = std::sqrt(1 - g * g / 4);
  for (int k = 0; k < 40; ++k) {
    const double t = 0.1 * k, e = std::exp(-g * t / 2);
    const double q = e * std::cos(w * t), p = e * (-g / 2 * std::cos(w * t) - w * std::sin(w * t));
    char buf[160];
    std::snprintf(buf, sizeof buf, "21.5,%.17g,%.17g,%.17g\n", t, p, q);
    own += buf;
    std::snprintf(buf, sizeof buf, "%.17g,%.17g,%.17g\n", t, q, p);
    canonical += buf;
  }
  const fs::path a = write("own.csv", own), b = write("canonical.csv", canonical);
  const std::string opts = " --epochs 30 --bootstrap 0 --quiet --out ";
  Result r = run("train " + a.string() + " --columns t=time_s,q1=theta,p1=omega" + opts +
                 (dir_ / "own").string());
  ASSERT_EQ(r.code, 0) << r.err;
  r = run("train --data " + b.string() + opts + (dir_ / "canonical").string());
  ASSERT_EQ(r.code, 0) << r.err;
  auto own_report = nlohmann::json::parse(slurp(dir_ / "own" / "report.json"));
  auto canonical_report = nlohmann::json::parse(slurp(dir_ / "canonical" / "report.json"));
  EXPECT_EQ(own_report["columns"], "t=time_s,q1=theta,p1=omega");
  EXPECT_EQ(own_report["gamma_hat"], canonical_report["gamma_hat"]);
  EXPECT_EQ(own_report["training"]["best_val_loss"], canonical_report["training"]["best_val_loss"]);

  r = run("train " + a.string() + " --columns x=time_s" + opts + (dir_ / "x").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--columns: 'x' is not a column csympnet reads"), std::string::npos)
      << r.err;
  r = run("train " + a.string() + " --columns t=time,q1=theta,p1=omega" + opts +
          (dir_ / "y").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("own.csv:1: --columns maps t to 'time', which is not a column"),
            std::string::npos)
      << r.err;
  r = run("train " + b.string() + " --warm-start --no-warm-start" + opts + (dir_ / "z").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("excludes"), std::string::npos) << r.err;
}

struct BadCase {
  const char* name;
  const char* text;
  const char* expect;  // a fragment the message must contain (":LINE:" after the file name)
};

TEST_F(Cli, BadInputGetsAClearErrorNamingFileAndLine) {
  const BadCase cases[] = {
      {"wrong_columns.csv", "h,q1,p1,next_q1,next_p1\n0.1,1,2,3\n", ":2:"},
      {"non_numeric.csv", "h,q1,p1,next_q1,next_p1\n0.1,1,abc,3,4\n", ":2:"},
      {"nan.csv", "h,q1,p1,next_q1,next_p1\n0.1,1,2,3,4\n0.1,nan,2,3,4\n", ":3:"},
      {"h_nonpositive.csv", "h,q1,p1,next_q1,next_p1\n0.1,1,2,3,4\n-0.1,1,2,3,4\n", ":3:"},
      {"odd_dimension.csv", "t,q1,q2,p1\n0,1,2,3\n0.1,1,2,3\n", ":1:"},
      {"empty.csv", "", "empty"},
  };
  for (const BadCase& c : cases) {
    const fs::path p = write(c.name, c.text);
    const Result r = run("fit " + p.string() + " --quiet --epochs 10 --out " +
                         (dir_ / (std::string("o_") + c.name)).string());
    EXPECT_EQ(r.code, 1) << c.name << ": " << r.err;
    EXPECT_NE(r.err.find(c.name), std::string::npos) << c.name << ": " << r.err;
    const std::string where =
        c.expect[0] == ':' ? std::string(c.name) + c.expect : std::string(c.expect);
    EXPECT_NE(r.err.find(where), std::string::npos) << c.name << ": " << r.err;
    EXPECT_EQ(r.err.find("internal error"), std::string::npos) << r.err;
  }
}

TEST_F(Cli, BadOptionsAreRejectedByName) {
  Result r = run("run --preset s9 --out " + (dir_ / "x").string());
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("--preset"), std::string::npos) << r.err;
  r = run("run --preset s1 --sigma -1 --out " + (dir_ / "x").string());
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("--sigma"), std::string::npos) << r.err;
  r = run("run --preset s1 --model nosuch --out " + (dir_ / "x").string());
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("--model"), std::string::npos) << r.err;
}

// `reproduce` on a tiny suite: outputs, resumption, refusal of foreign directories, bad suite
// names, and (when OpenMPI is installed) a 2-rank run identical to a 1-process run.
TEST_F(Cli, ReproduceRunsResumesAndMatchesAcrossRanks) {
  const fs::path suites = dir_ / "suites";
  fs::create_directories(suites);
  std::ofstream(suites / "tiny.json")
      << R"({"name": "tiny", "kind": "table", "columns": ["params", "l2_error"],
             "presets": ["s1"], "models": ["csympnet", "ode"], "seeds": [42],
             "epochs": {"*": {"*": 50}}})";
  std::ofstream(suites / "tgrid.json")
      << R"({"name": "tgrid", "kind": "grid", "vary": "sigma", "presets": ["s1"],
             "models": ["csympnet", "sympnet"], "seeds": [1, 2, 3], "sigmas": [0, 0.001],
             "epochs": {"*": {"*": 50}}})";
  const std::string common = "reproduce --suites-dir " + suites.string() + " --no-figures -q ";
  const fs::path one = dir_ / "one";
  Result r = run(common + "--suite tiny,tgrid --jobs 2 --out " + one.string());
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* f : {"summary.json", "timings.json", "tables/tiny.md", "tables/tiny.csv",
                        "tables/tiny.tex", "tables/tgrid.md", "tables/tgrid.csv"})
    EXPECT_TRUE(fs::exists(one / f)) << f;
  const auto summary = nlohmann::json::parse(slurp(one / "summary.json"));
  EXPECT_EQ(summary["tiny"]["s1"]["csympnet"]["params"], 115);
  EXPECT_EQ(summary["tgrid"]["s1"]["sympnet"].size(), 2u);

  // Resuming an interrupted reproduction: delete two records, rerun, same summary.
  std::vector<fs::path> records;
  for (const auto& e : fs::directory_iterator(one / "runs")) records.push_back(e.path());
  ASSERT_EQ(records.size(), 2u + 12u);
  fs::remove(records[0]);
  fs::remove(records[5]);
  r = run("reproduce --suites-dir " + suites.string() +
          " --no-figures --suite tiny,tgrid --jobs 1 --out " + one.string());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("executed 2 runs"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("12 cached"), std::string::npos) << r.err;
  EXPECT_EQ(slurp(one / "summary.json"), summary.dump(2) + "\n");

  // A non-empty directory that is not a reproduction is refused; a bad suite name is named.
  fs::create_directories(dir_ / "foreign");
  write("foreign/notes.txt", "mine");
  r = run(common + "--suite tiny --out " + (dir_ / "foreign").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--force"), std::string::npos) << r.err;
  EXPECT_EQ(slurp(dir_ / "foreign/notes.txt"), "mine");
  r = run(common + "--suite tiny,nosuch --out " + (dir_ / "x").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("'nosuch'"), std::string::npos) << r.err;

  if (std::system("command -v mpirun >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "mpirun not installed (scripts/install-deps.sh installs openmpi-bin)";
  const fs::path two = dir_ / "two";
  const std::string mpi = "mpirun --allow-run-as-root --oversubscribe -np 2 " +
                          std::string(CSYMPNET_CLI_PATH) + " " + common +
                          "--suite tiny,tgrid --jobs 1 --out " + two.string() + " >" +
                          (dir_ / "mpi.txt").string() + " 2>&1";
  ASSERT_EQ(std::system(mpi.c_str()), 0) << slurp(dir_ / "mpi.txt");
  EXPECT_EQ(slurp(two / "summary.json"), slurp(one / "summary.json"));
  for (const char* f : {"tiny.md", "tiny.csv", "tiny.tex", "tgrid.md", "tgrid.csv", "tgrid.tex"})
    EXPECT_EQ(slurp(two / "tables" / f), slurp(one / "tables" / f)) << f;
}

// SIGINT/SIGTERM: training stops at the next validation, the best checkpoint is evaluated and
// saved, and the exit code is 128 + the signal; an interrupted reproduction resumes.
TEST_F(Cli, InterruptSavesTheBestCheckpointAndExitsWithTheSignalCode) {
  const fs::path out = dir_ / "run";
  Result r =
      run_and_signal("run --preset s2 --model csympnet --epochs 1000000 -q --out " + out.string(),
                     out, "TERM", 0.5);
  EXPECT_EQ(r.code, 143) << r.err;
  EXPECT_NE(r.err.find("interrupted by SIGTERM"), std::string::npos) << r.err;
  const auto report = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_EQ(report["stop_reason"], "callback");
  EXPECT_LT(report["epochs"].get<long>(), 1000000);
  EXPECT_TRUE(fs::exists(out / "model.json"));

  // A second stage is not started after an interrupted first one.
  const fs::path lm = dir_ / "lm";
  r = run_and_signal(
      "run --preset s1 --model csympnet --epochs 100000000 --refine lm -q --out " + lm.string(), lm,
      "TERM", 0.5);
  EXPECT_EQ(r.code, 143) << r.err;
  const auto lm_report = nlohmann::json::parse(slurp(lm / "report.json"));
  EXPECT_EQ(lm_report["stop_reason"], "callback");
  EXPECT_EQ(lm_report["refine"]["method"], "none");
  EXPECT_GT(lm_report["best_val_loss"].get<double>(), 0.0);  // AdamW's, not a skipped stage's 0

  const fs::path suites = dir_ / "suites";
  fs::create_directories(suites);
  // Runs long enough that the signal 0.5 s in stops the suite before its third: under the
  // sanitizers an epoch takes 5 to 25 times longer, and the resumed suite then finishes in
  // seconds instead of 20 (gcc) to 100 (clang, without the gcc-only kernels).
  const int epochs = csympnet::testing::kUnderSanitizers ? 30000 : 150000;
  std::ofstream(suites / "slow.json")
      << R"({"name": "slow", "kind": "grid", "vary": "sigma", "presets": ["s1"],
             "models": ["csympnet"], "seeds": [1, 2, 3], "epochs": {"*": {"*": )"
      << epochs << "}}}";
  const std::string cmd = "reproduce --suites-dir " + suites.string() +
                          " --no-figures --suite slow --jobs 1 --out " + (dir_ / "rep").string();
  r = run_and_signal(cmd, dir_ / "rep", "INT", 0.5);
  EXPECT_EQ(r.code, 130) << r.err;
  EXPECT_NE(r.err.find("rerun the same command to resume"), std::string::npos) << r.err;
  std::size_t kept = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_ / "rep" / "runs")) ++kept;
  EXPECT_LT(kept, 3u);
  r = run(cmd + " -q");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto summary = nlohmann::json::parse(slurp(dir_ / "rep" / "summary.json"));
  EXPECT_EQ(summary["slow"]["s1"]["csympnet"][0]["seeds"].size(), 3u);
}

}  // namespace

namespace {

// One argument quoted for /bin/sh (the test's own command lines go through a shell).
std::string sh_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// `reproduce` starts its figure script with an argument vector: an --out full of shell syntax
// reaches the script as one argument and runs nothing; a failing script fails the command.
TEST_F(Cli, ReproduceFigureStepRunsNoShellAndFailsLoudly) {
  const fs::path suites = dir_ / "suites";
  fs::create_directories(suites);
  std::ofstream(suites / "tiny.json")
      << R"({"name": "tiny", "kind": "table", "columns": ["params"], "presets": ["s1"],
             "models": ["csympnet"], "seeds": [42], "epochs": {"*": {"*": 5}}})";
  // A stand-in figure script: records the argument it got, in the directory it names.
  const fs::path script =
      write("figures.py",
            "import sys, pathlib\n"
            "pathlib.Path(sys.argv[1], 'figure-arg.txt').write_text(sys.argv[1])\n");
  const fs::path failing = write("failing.py", "import sys\nsys.exit(3)\n");
  const fs::path injected = dir_ / "INJECTED";
  const std::string hostile = (dir_ / "x';touch ").string() + injected.string() + ";'bob's run";
  const std::string common = "reproduce --suites-dir " + sh_quote(suites.string()) +
                             " --suite tiny -q --out " + sh_quote(hostile);
  Result r = run("--version >/dev/null; CSYMPNET_FIGURES_SCRIPT=" + sh_quote(script.string()) +
                 " " + std::string(CSYMPNET_CLI_PATH) + " " + common);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_FALSE(fs::exists(injected)) << "a shell ran part of --out";
  EXPECT_EQ(slurp(fs::path(hostile) / "figure-arg.txt"), hostile);

  r = run("--version >/dev/null; CSYMPNET_FIGURES_SCRIPT=" + sh_quote(failing.string()) + " " +
          std::string(CSYMPNET_CLI_PATH) + " " + common);
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("figure script"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("exit 3"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--no-figures"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(injected));

  // --no-figures does not claim figures.
  r = run(common + " --no-figures --force");
  ASSERT_EQ(r.code, 0) << r.err;
}

}  // namespace

namespace csympnet {
namespace {

// fit --help lists DATA once as required, --data once as its other spelling, no group of
// options "refused by fit", and the clock's unit; a missing DATA is a usage error.
TEST_F(Cli, FitHelpListsTheDataOnceAndNoOptionsForOtherCommands) {
  for (const char* command : {"fit", "train"}) {
    SCOPED_TRACE(command);
    Result r = run(std::string(command) + " --help");
    ASSERT_EQ(r.code, 0) << r.err;
    // CLI11's marker is on --out alone: DATA says "(required; ...)" itself, and --data is
    // its other spelling (once both were marked, each as REQUIRED).
    std::size_t required = 0, data_lines = 0;
    std::istringstream lines(r.out);
    for (std::string line; std::getline(lines, line);) {
      if (line.find("REQUIRED") == std::string::npos) continue;
      ++required;
      EXPECT_NE(line.find("--out"), std::string::npos) << line;
    }
    for (std::size_t at = r.out.find("--data TEXT"); at != std::string::npos;
         at = r.out.find("--data TEXT", at + 1))
      ++data_lines;
    EXPECT_EQ(required, 1u) << r.out;
    EXPECT_EQ(data_lines, 1u) << r.out;
    EXPECT_NE(r.out.find("(required; or give it as --data)"), std::string::npos) << r.out;
    EXPECT_EQ(r.out.find("refused by fit"), std::string::npos) << r.out;
    r = run(std::string(command) + " --out " + (dir_ / "out").string());
    EXPECT_EQ(r.code, 2);
    EXPECT_FALSE(fs::exists(dir_ / "out"));
    EXPECT_NE(r.err.find("DATA"), std::string::npos) << r.err;
  }
  EXPECT_NE(run("fit --help").out.find("--time-unit"), std::string::npos);
  const Result both = run("fit a.csv --data b.csv");
  EXPECT_EQ(both.code, 2) << both.err;
}

}  // namespace
}  // namespace csympnet
