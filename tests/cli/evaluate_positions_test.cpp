// `csympnet evaluate --data positions.csv`: a record of positions alone is scored from a state
// fitted to a warm-up window, the warm-up left out; its refusals name --warmup and what was
// expected; SIGINT stops it within a second. The scores themselves are tested in
// tests/diagnostics/positions_score_test.cpp, and agree with Python's Model.score to the bit in
// python/tests/test_score_positions.py.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "cli/cli_support.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/diagnostics/learned_map.hpp"
#include "csympnet/models/model_file.hpp"

namespace csympnet {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using testing_cli::CliResult;
using testing_cli::CliTest;
using testing_cli::shell_quote;
using testing_cli::slurp;

// The damped oscillator H = ½p² + ½q², γ = 0.1, as a Hamiltonian-library csympnet model with
// `substeps` substeps a step.
Model oscillator(Vector& theta, Index substeps = 1) {
  Model m = make_model(
      {{"type", "csympnet"},
       {"d", 1},
       {"core", {{"type", "library"}, {"terms", {"q1^2"}}, {"order", 4}, {"substeps", substeps}}}});
  theta.resize(m.n_params());
  Rng rng(1, "unused");  // the library draws nothing
  m.init_params(rng, theta);
  theta(theta.size() - 1) = 0.1;
  return m;
}

class EvaluatePositions : public CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    model_ = (dir_ / "model.json").string();
    Vector theta;
    const Model m = oscillator(theta);
    std::ofstream(model_) << model_file_text(m, theta, json::object());
    // Two trajectories of its motion, 100 and 50 samples at h = 0.1, as a file of positions.
    const LearnedMap map = learned_map(m, theta);
    std::string text = "traj,t,q1\n";
    for (int k = 0; k < 2; ++k) {
      Vector z(2);
      z << 1.0, 0.5 * k;
      for (int n = 0; n < (k == 0 ? 100 : 50); ++n) {
        if (n > 0) z = map.step(z, 0.1);
        text +=
            std::to_string(k) + "," + round_trip_text(0.1 * n) + "," + round_trip_text(z(0)) + "\n";
      }
    }
    positions_ = write("pos.csv", text);
  }

  std::string write(const std::string& name, const std::string& text) const {
    const fs::path p = dir_ / name;
    std::ofstream(p) << text;
    return p.string();
  }

  CliResult evaluate(const std::string& data, const std::string& more = "") const {
    return run("evaluate --model " + shell_quote(model_) + " --data " + shell_quote(data) + " " +
               more);
  }

  std::string model_, positions_;
};

TEST_F(EvaluatePositions, ScoresTheSamplesAfterTheWarmUp) {
  CliResult r = evaluate(positions_, "--out " + shell_quote((dir_ / "o").string()));
  ASSERT_EQ(r.code, 0) << r.err;
  const json rep = json::parse(r.out);
  const json& p = rep.at("positions");
  EXPECT_FALSE(rep.contains("observed"));
  EXPECT_EQ(rep["test_trajectories"], 2);
  EXPECT_EQ(rep["gamma_hat"], 0.1);
  EXPECT_TRUE(p["warmup"].is_null());  // the default: a tenth, at least 10
  EXPECT_EQ(p["per_trajectory"][0]["warmup"], 10);
  EXPECT_EQ(p["per_trajectory"][1]["warmup"], 10);
  EXPECT_EQ(p["per_trajectory"][0]["scored"], 90);
  EXPECT_EQ(p["samples_scored"], 130);
  EXPECT_EQ(p["per_trajectory"][1]["t_start"], 0.9);
  EXPECT_LT(p["rmse"].get<double>(), 1e-6);  // the true model, clean positions
  EXPECT_EQ(p["rmse_per_coordinate"].size(), 1u);
  EXPECT_GT(p["spread"].get<double>(), 0.1);
  EXPECT_TRUE(p["rollout_finite"].get<bool>());
  EXPECT_EQ(json::parse(slurp(dir_ / "o" / "report.json")), rep);

  r = evaluate(positions_, "--warmup 40");
  ASSERT_EQ(r.code, 0) << r.err;
  const json q = json::parse(r.out).at("positions");
  EXPECT_EQ(q["warmup"], 40);
  EXPECT_EQ(q["samples_scored"], 60 + 10);
}

TEST_F(EvaluatePositions, NamedColumnsArePositionsToo) {
  const std::string named = write(
      "named.csv", "time_s,angle\n" + [&] {
        std::string rows;
        const std::string text = slurp(positions_);
        // The first trajectory's rows, without the traj column.
        std::size_t at = text.find('\n') + 1;
        while (at < text.size() && text.compare(at, 2, "0,") == 0) {
          const std::size_t end = text.find('\n', at);
          rows += text.substr(at + 2, end - at - 1);
          at = end + 1;
        }
        return rows;
      }());
  const CliResult r = evaluate(named, "--columns t=time_s,q1=angle --warmup 12");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(json::parse(r.out)["positions"]["samples_scored"], 88);
}

TEST_F(EvaluatePositions, BadWarmUpsAreRefusedNamingTheOption) {
  for (const char* w : {"0", "2", "-1", "abc", "1.5"}) {
    const CliResult r = evaluate(positions_, std::string("--warmup ") + w);
    EXPECT_EQ(r.code, 2) << w << ": " << r.err;
    EXPECT_NE(r.err.find("--warmup"), std::string::npos) << r.err;
  }
  // As long as the shorter trajectory: none of it is left to score.
  CliResult r = evaluate(positions_, "--warmup 50");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--warmup: " + positions_ + ": trajectory 2 of 2 has 50 samples"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("a warm-up from 3 to 49"), std::string::npos) << r.err;
  EXPECT_EQ(r.out, "");
  r = evaluate(positions_, "--warmup 100000");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("leaves none to score"), std::string::npos) << r.err;
}

TEST_F(EvaluatePositions, ShortAndHostileRecordsAreRefused) {
  // Too short for the default warm-up.
  CliResult r = evaluate(write("short.csv", "t,q1\n0,1\n0.1,0.99\n0.2,0.98\n0.3,0.96\n"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("has 4 samples, and the default warm-up"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--warmup"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("expected a trajectory of more than 10 samples"), std::string::npos)
      << r.err;
  // Three samples cannot hold a warm-up and a score.
  r = evaluate(write("three.csv", "t,q1\n0,1\n0.1,0.99\n0.2,0.98\n"), "--warmup 3");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("needs at least 3 samples"), std::string::npos) << r.err;
  // NaN, and positions of another d.
  std::string text = slurp(positions_);
  const std::size_t value = text.find("\n0,0.5,") + 7;
  text.replace(value, text.find('\n', value) - value, "nan");
  r = evaluate(write("nan.csv", text));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.err.find("nan.csv"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("expected a finite number"), std::string::npos) << r.err;
  r = evaluate(write(
      "d2.csv", "t,q1,q2\n" + [] {
        std::string rows;
        for (int n = 0; n < 30; ++n) rows += std::to_string(n) + ",0.5," + std::to_string(n) + "\n";
        return rows;
      }()));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("expected d = 1"), std::string::npos) << r.err;
  // A window the model does not explain: no score from a state that means nothing.
  std::string zigzag = "t,q1\n";
  for (int n = 0; n < 40; ++n) zigzag += std::to_string(n) + "," + (n % 2 == 0 ? "1" : "-1") + "\n";
  r = evaluate(write("zigzag.csv", zigzag));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("does not explain"), std::string::npos) << r.err;
}

TEST_F(EvaluatePositions, WarmUpNeedsAPositionsFile) {
  // A file of states: its rollouts start from the first observed state.
  std::string states = "t,q1,p1\n";
  for (int n = 0; n < 20; ++n)
    states += round_trip_text(0.1 * n) + "," + round_trip_text(std::cos(0.1 * n)) + "," +
              round_trip_text(-std::sin(0.1 * n)) + "\n";
  const std::string file = write("states.csv", states);
  CliResult r = evaluate(file, "--warmup 5");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--warmup is the warm-up window of a positions file"), std::string::npos)
      << r.err;
  r = evaluate(file);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(json::parse(r.out).contains("observed"));
  r = run("evaluate --model " + shell_quote(model_) + " --preset s1 --warmup 5");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("expected --data POSITIONS.csv"), std::string::npos) << r.err;
}

TEST_F(EvaluatePositions, OnlyACsympnetModelScoresPositions) {
  const Model map = make_model({{"type", "map"}, {"d", 1}, {"width", 3}});
  const std::string other = (dir_ / "map.json").string();
  std::ofstream(other) << model_file_text(map, Vector::Zero(map.n_params()), json::object());
  const CliResult r =
      run("evaluate --model " + shell_quote(other) + " --data " + shell_quote(positions_));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("needs a csympnet model"), std::string::npos) << r.err;
}

// A model of 400,000 substeps a step (seconds per state fit): SIGINT ends the evaluation within
// a second, exit 130, no report.
TEST_F(EvaluatePositions, StopsWithinASecondOfSigint) {
  Vector theta;
  const Model slow = oscillator(theta, 400000);
  const std::string slow_model = (dir_ / "slow.json").string();
  std::ofstream(slow_model) << model_file_text(slow, theta, json::object());
  const fs::path ms = dir_ / "ms.txt", err = dir_ / "err.txt", out = dir_ / "o";
  const std::string cmd = std::string(CSYMPNET_CLI_PATH) + " evaluate --model " +
                          shell_quote(slow_model) + " --data " + shell_quote(positions_) +
                          " --out " + shell_quote(out.string()) + " >/dev/null 2>" +
                          shell_quote(err.string()) +
                          " </dev/null & pid=$!; sleep 1; t0=$(date +%s%N); kill -INT $pid; "
                          "wait $pid; code=$?; echo $(( ($(date +%s%N) - t0) / 1000000 )) > " +
                          shell_quote(ms.string()) + "; exit $code";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130) << slurp(err);
  EXPECT_LT(std::stol(slurp(ms)), 1000);
  EXPECT_NE(slurp(err).find("interrupted by SIGINT"), std::string::npos) << slurp(err);
  EXPECT_FALSE(fs::exists(out / "report.json"));
}

}  // namespace
}  // namespace csympnet
