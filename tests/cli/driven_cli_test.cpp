// `csympnet fit` and `csympnet evaluate` on a record driven by a known input (columns u1..um):
//   - fit writes report.json with gamma_hat, its interval, identified, verdict and "input" (B
//     and its interval), and model.json that reads the input;
//   - evaluate --data TEST.csv --warmup N scores the free run driven by the test record's inputs
//     under "simulation" (rmse per q column, in the data's units);
//   - a free model refuses a record with inputs, naming the columns.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "cli/cli_support.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/models/model.hpp"
#include "csympnet/models/model_file.hpp"
#include "support/driven_oscillator.hpp"

namespace csympnet {
namespace {

using nlohmann::json;
using testing_cli::CliResult;
using testing_cli::CliTest;
using testing_cli::shell_quote;
using testing_cli::slurp;

// t,q1,u1 rows (positions and input), 17 significant digits.
void write_positions_with_input(const std::string& path, const Trajectory& tr) {
  std::ofstream out(path);
  out << "t,q1,u1\n";
  char line[128];
  for (Index k = 0; k < tr.t.size(); ++k) {
    std::snprintf(line, sizeof line, "%.17g,%.17g,%.17g\n", tr.t(k), tr.z(0, k), tr.u(0, k));
    out << line;
  }
}

class DrivenCli : public CliTest {};

TEST_F(DrivenCli, FitReportsTheInputAndEvaluateSimulatesWithIt) {
  const std::string train = (dir_ / "train.csv").string(), test = (dir_ / "test.csv").string();
  const std::string fit_dir = (dir_ / "fit").string(), eval_dir = (dir_ / "eval").string();
  write_positions_with_input(train, testing::driven_record(1000, 0.05, 0.005, 11));
  const Trajectory held = testing::driven_record(300, 0.05, 0.005, 12);
  write_positions_with_input(test, held);
  CliResult r =
      run("fit " + shell_quote(train) + " --out " + shell_quote(fit_dir) + " -q --no-figures");
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("input gain B[q1,u1]"), std::string::npos) << r.out;
  const json rep = json::parse(slurp(dir_ / "fit" / "report.json"));
  EXPECT_EQ(rep["verdict"], "identified");
  EXPECT_TRUE(rep["identified"].get<bool>());
  EXPECT_LE(rep["gamma_ci_low"].get<double>(), testing::kDrivenGamma);
  EXPECT_GE(rep["gamma_ci_high"].get<double>(), testing::kDrivenGamma);
  EXPECT_EQ(rep["input"]["m"], 1);
  EXPECT_EQ(rep["input"]["hold"], "foh");
  EXPECT_LE(rep["input"]["B_ci_low"][0][0].get<double>(), testing::kDrivenGain);
  EXPECT_GE(rep["input"]["B_ci_high"][0][0].get<double>(), testing::kDrivenGain);
  EXPECT_EQ(rep["observed"], "positions");

  r = run("evaluate --model " + shell_quote(fit_dir + "/model.json") + " --data " +
          shell_quote(test) + " --warmup 20 --out " + shell_quote(eval_dir));
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  const json ev = json::parse(slurp(dir_ / "eval" / "report.json"));
  const json& sim = ev.at("simulation");
  EXPECT_EQ(sim["warmup"], 20);
  EXPECT_EQ(sim["inputs"], 1);
  EXPECT_EQ(sim["samples_scored"], 280);
  ASSERT_EQ(sim["rmse"].size(), 1u);
  // A free run of 280 samples (4.5 periods) driven by the input: its error stays near the
  // positions' noise (0.5% of their spread), far below the spread itself.
  const double spread = ev["positions"]["spread"].get<double>();
  std::printf("  simulation rmse %.4g, spread %.4g\n", sim["rmse"][0].get<double>(), spread);
  EXPECT_LT(sim["rmse"][0].get<double>(), 0.03 * spread);

  // A test record that starts before the drive: its warm-up is the oscillator at rest, positions
  // that are noise alone. The state fitted to them is a start like any other (the input carries
  // what follows), and the free run follows the record as closely.
  const std::string rest = (dir_ / "rest.csv").string(), rest_dir = (dir_ / "eval-rest").string();
  const Trajectory from_rest =
      testing::driven_record(300, 0.05, 0.005, 13, testing::kDrivenGamma, 0.0, false, 1.5);
  write_positions_with_input(rest, from_rest);
  r = run("evaluate --model " + shell_quote(fit_dir + "/model.json") + " --data " +
          shell_quote(rest) + " --warmup 20 --out " + shell_quote(rest_dir));
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  const json er = json::parse(slurp(dir_ / "eval-rest" / "report.json"));
  const double rest_spread = er["positions"]["spread"].get<double>();
  std::printf("  from rest: simulation rmse %.4g, spread %.4g\n",
              er["simulation"]["rmse"][0].get<double>(), rest_spread);
  EXPECT_LT(er["simulation"]["rmse"][0].get<double>(), 0.03 * rest_spread);
}

TEST_F(DrivenCli, AFreeModelRefusesARecordWithInputsAndTheCoreTakesJson) {
  const std::string data = (dir_ / "d.csv").string(), model = (dir_ / "free.json").string();
  write_positions_with_input(data, testing::driven_record(100, 0.05, 0.0, 13));
  Model m = make_model(
      {{"type", "csympnet"}, {"d", 1}, {"core", {{"type", "library"}, {"terms", {"q1^2"}}}}});
  Vector theta(m.n_params());
  Rng rng(1, "unused");
  m.init_params(rng, theta);
  std::ofstream(model) << model_file_text(m, theta, json::object());
  CliResult r = run("evaluate --model " + shell_quote(model) + " --data " + shell_quote(data) +
                    " --warmup 20");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("has 1 input columns (u1..um); the model is driven by 0"), std::string::npos)
      << r.err;
  // A library core given as JSON whose inputs disagree with the record's columns.
  r = run("fit " + shell_quote(data) + " --out " + shell_quote((dir_ / "f").string()) +
          " -q --no-figures --core " +
          shell_quote(R"({"type":"library","terms":["q1^2"],"inputs":{"m":2}})"));
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("inputs.m = 2 disagrees with the record's 1 input columns"),
            std::string::npos)
      << r.err;
}

}  // namespace
}  // namespace csympnet
