// Every numeric or file option of every subcommand is range-checked: an out-of-range,
// non-finite or nonexistent value is refused before any work, by name, with exit 2 (a usage
// error) or 1 (a value the library refuses), never a crash or an internal error.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "cli_support.hpp"

namespace csympnet::testing_cli {
namespace {

struct BadOption {
  std::string args;      // after the subcommand's required options
  std::string fragment;  // the message names this (the option)
  int code;              // 2: refused while parsing the options; 1: refused by the library
};

class OptionRanges : public CliTest {
 protected:
  void expect_refused(const std::string& base, const BadOption& c) {
    std::filesystem::remove_all(dir_ / "o");  // each case starts without an output
    const CliResult r = run(base + " " + c.args);
    SCOPED_TRACE(base + " " + c.args + "\n" + r.err);
    EXPECT_FALSE(r.signalled);
    EXPECT_EQ(r.code, c.code);
    EXPECT_NE(r.err.find(c.fragment), std::string::npos);
    EXPECT_EQ(r.err.find("internal error"), std::string::npos);
    EXPECT_TRUE(r.out.empty()) << r.out;
    // Refused before any work: not even the output directory was created.
    EXPECT_FALSE(std::filesystem::exists(dir_ / "o")) << "the output directory was created";
  }
  std::string out() const { return " --out " + (dir_ / "o").string(); }
};

const std::vector<BadOption> kSystem = {
    {"--d 0", "--d", 2},
    {"--d -3", "--d", 2},
    {"--d 2.5", "--d", 2},
    {"--gamma -0.1", "--gamma", 2},
    {"--gamma inf", "--gamma", 2},
    {"--gamma nan", "--gamma", 2},
    {"--omega 0", "--omega", 2},
    {"--omega -1", "--omega", 2},
    {"--omega nan", "--omega", 2},
    {"--k -1", "--k", 2},
    {"--k inf", "--k", 2},
    {"--alpha nan", "--alpha", 2},
    {"--alpha -inf", "--alpha", 2},
    {"--alpha x", "--alpha", 2},
};

TEST_F(OptionRanges, Describe) {
  expect_refused("describe", {"--preset s9", "--preset", 2});
  expect_refused("describe --preset s1", {"--model nosuch", "--model", 2});
  for (const BadOption& c : kSystem) expect_refused("describe --preset s1", c);
}

TEST_F(OptionRanges, Generate) {
  const std::string base = "generate --preset s1" + out();
  for (const BadOption& c : std::vector<BadOption>{
           {"--n 0", "--n", 2},
           {"--n -5", "--n", 2},
           {"--sigma -0.1", "--sigma", 2},
           {"--sigma 11", "--sigma", 2},
           {"--sigma nan", "--sigma", 2},
           {"--split nosuch", "--split", 2},
           {"--reference euler", "--reference", 2},
           {"--n 100000000", "more than the 1024 MiB csympnet reads back; expected --n <= ", 2},
           {"--seed -1", "--seed", 2},
           {"--seed x", "--seed", 2},
       })
    expect_refused(base, c);
  for (const BadOption& c : kSystem) expect_refused(base, c);
  expect_refused("generate", {"--preset s1", "--out", 2});  // --out is required
}

TEST_F(OptionRanges, EvaluateAndRollout) {
  // A real model, so only the option under test is wrong.
  const std::string m = (dir_ / "m").string();
  ASSERT_EQ(run("run --preset s1 --epochs 2 -q --out " + m).code, 0);
  const std::string model = " --model " + m + "/model.json";
  expect_refused("evaluate", {"--model " + (dir_ / "none.json").string(), "--model", 2});
  for (const BadOption& c : std::vector<BadOption>{
           {"--h-test 0", "--h-test", 2},
           {"--h-test -0.2", "--h-test", 2},
           {"--h-test inf", "--h-test", 2},
           {"--h-test nan", "--h-test", 2},
           {"--data " + (dir_ / "none.csv").string(), "--data", 2},
           {"--preset s9", "--preset", 2},
       })
    expect_refused("evaluate --preset s1" + model, c);
  for (const BadOption& c : kSystem) expect_refused("evaluate --preset s1" + model, c);

  const std::string roll = "rollout" + model;
  for (const BadOption& c : std::vector<BadOption>{
           {"--z0 0.5,0 --h 0 --steps 3", "--h", 2},
           {"--z0 0.5,0 --h -0.1 --steps 3", "--h", 2},
           {"--z0 0.5,0 --h nan --steps 3", "--h", 2},
           {"--z0 0.5,0 --h inf --steps 3", "--h", 2},
           {"--z0 0.5,0 --h 0.1 --steps 0", "--steps", 2},
           {"--z0 0.5,0 --h 0.1 --steps -1", "--steps", 2},
           {"--z0 0.5,nan --h 0.1 --steps 3", "--z0", 1},
           {"--z0 0.5,1e999 --h 0.1 --steps 3", "--z0", 1},
           {"--z0 0.5 --h 0.1 --steps 3", "--z0", 1},
           {"--z0 0.5,,1 --h 0.1 --steps 3", "--z0", 1},
       })
    expect_refused(roll, c);
  expect_refused("rollout --model " + (dir_ / "none.json").string(),
                 {"--z0 0,0 --h 0.1 --steps 1", "--model", 2});
}

TEST_F(OptionRanges, Reproduce) {
  const std::string base = "reproduce --no-figures -q" + out();
  for (const BadOption& c : std::vector<BadOption>{
           {"--jobs 0", "--jobs", 2},
           {"--jobs -2", "--jobs", 2},
           {"--jobs 2000", "--jobs", 2},
           {"--suites-dir " + (dir_ / "nodir").string(), "--suites-dir", 2},
           {"--suite ''", "--suite", 1},
           {"--suite table2,,noise", "--suite", 1},
           {"--suite nosuch", "--suite", 1},
       })
    expect_refused(base, c);
}

// run, train and fit: their option declarations live in cmd_run.cpp and cmd_train.cpp.
// `run --epochs 0` is accepted on purpose (it evaluates the initial parameters).
TEST_F(OptionRanges, RunTrainAndFit) {
  const std::string data = (dir_ / "data.csv").string();
  ASSERT_EQ(run("generate --preset s1 --n 20 --out " + data).code, 0);
  const std::vector<BadOption> common = {
      {"--epochs -1", "--epochs", 2},
      {"--lr 0", "--lr", 2},
      {"--lr -1e-3", "--lr", 2},
      {"--lr 100", "--lr", 2},
      {"--lr nan", "--lr", 2},
      {"--lr inf", "--lr", 2},
      {"--lr-schedule x", "--lr-schedule", 2},
      {"--val-every 0", "--val-every", 2},
      {"--beta-init 0", "--beta-init", 2},
      {"--beta-init -0.0", "--beta-init", 2},
      {"--beta-init nan", "--beta-init", 2},
      {"--beta-init x", "--beta-init", 2},
      {"--core la:0:3", "--core", 2},
      {"--core xx:1:1", "--core", 2},
      {"--core g:3", "--core", 2},
      {"--core g:3:4:h2", "--core", 2},
      {"--core la:3:4:h3", "--core", 2},
      {"--model nosuch", "--model", 2},
      {"--seed x", "--seed", 2},
      {"--seed -1", "--seed", 2},
      // Said in words, not clamped: 2^64 was once accepted as 2^64 - 1.
      {"--seed 18446744073709551616", "'18446744073709551616' is above 18446744073709551615", 2},
      {"--seed -1", "'-1' is negative; expected a seed from 0", 2},
      {"--epochs abc", "'abc' is not a whole number", 2},
      {"--epochs 2.5", "'2.5' is not a whole number", 2},
      {"--threads 0", "--threads", 2},
      {"--threads -2", "--threads", 2},
      {"--threads 257", "--threads", 2},
      {"--threads 1.5", "--threads", 2},
  };
  std::vector<BadOption> run_cases = common;
  run_cases.push_back({"--epochs x", "--epochs", 2});
  run_cases.push_back({"--sigma -1", "--sigma", 2});
  run_cases.push_back({"--sigma nan", "--sigma", 2});
  run_cases.push_back({"--recipe x", "--recipe", 2});
  run_cases.push_back({"--reference euler", "--reference", 2});
  for (const BadOption& c : kSystem) run_cases.push_back(c);
  for (const BadOption& c : run_cases) expect_refused("run --preset s1 -q" + out(), c);

  std::vector<BadOption> fit_cases = common;
  fit_cases.push_back({"--epochs 0", "--epochs", 2});
  fit_cases.push_back({"--val-fraction 0", "--val-fraction", 2});
  fit_cases.push_back({"--val-fraction 1", "--val-fraction", 2});
  fit_cases.push_back({"--val-fraction nan", "--val-fraction", 2});
  fit_cases.push_back({"--val " + (dir_ / "none.csv").string(), "--val", 2});
  fit_cases.push_back({"--chunk-pairs -1", "--chunk-pairs", 2});
  fit_cases.push_back({"--chunk-pairs 2.5", "--chunk-pairs", 2});
  fit_cases.push_back({"--batch-size -3", "--batch-size", 2});
  fit_cases.push_back({"--batch-size x", "--batch-size", 2});
  for (const BadOption& c : fit_cases) {
    expect_refused("fit " + data + " -q" + out(), c);
    expect_refused("train --data " + data + " -q" + out(), c);
  }
  // fit's default --refine auto chooses the solver itself: an explicit one is refused, not
  // silently overridden (train's default is none, so it needs --refine auto to refuse).
  expect_refused("fit " + data + " -q" + out(), {"--refine-solver dense_qr", "--refine-solver", 2});
  expect_refused("train --data " + data + " -q" + out(),
                 {"--refine auto --refine-solver blas_normal_cholesky", "--refine-solver", 2});
  // Too few bootstrap replicates is a usage error found before any work (it exited 1 after
  // creating --out).
  for (const char* n : {"1", "5", "9"}) {
    expect_refused(
        "fit " + data + " --recipe classic -q" + out(),
        {std::string("--bootstrap ") + n, "a percentile interval needs at least 10 replicates", 2});
    expect_refused(
        "train --data " + data + " -q" + out(),
        {std::string("--bootstrap ") + n, "expected 0 (off) or a number from 10 to 1000000", 2});
  }
  // A rule between options, checked with the others before any work (it exited 1 after
  // reading the data).
  expect_refused("train --data " + data + " -q" + out(),
                 {"--model sympnet --bootstrap 10", "--bootstrap: needs --model csympnet", 2});
  expect_refused("fit -q" + out(), {(dir_ / "none.csv").string(), "none.csv", 2});
  expect_refused("train -q" + out(), {"--data " + (dir_ / "none.csv").string(), "--data", 2});
}

}  // namespace
}  // namespace csympnet::testing_cli
