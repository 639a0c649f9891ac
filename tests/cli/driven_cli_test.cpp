// `csympnet fit` and `csympnet evaluate` on a record driven by a known input (columns u1..um):
//   - fit writes report.json with gamma_hat, its interval, identified, verdict and "input" (B
//     and its interval), and model.json that reads the input;
//   - evaluate --data TEST.csv --warmup N scores the free run driven by the test record's inputs
//     under "simulation" (rmse per q column, in the data's units);
//   - a free model refuses a record with inputs, naming the columns.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
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

using testing::write_positions_with_input;

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
  std::ofstream(dir_ / "u.csv") << "u1\n0\n0\n";
  r = run("rollout --model " + shell_quote(model) + " --z0 0,0 --inputs " +
          shell_quote((dir_ / "u.csv").string()) + " --h 0.05 --steps 1");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("the model has no inputs"), std::string::npos) << r.err;
  // A library core given as JSON whose inputs disagree with the record's columns.
  r = run("fit " + shell_quote(data) + " --out " + shell_quote((dir_ / "f").string()) +
          " -q --no-figures --core " +
          shell_quote(R"({"type":"library","terms":["q1^2"],"inputs":{"m":2}})"));
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("inputs.m = 2 disagrees with the record's 1 input columns"),
            std::string::npos)
      << r.err;
}

// u1 per row (and t first when `with_t`), the rows k = first … first + count − 1 of tr.
void write_inputs(const std::string& path, const Trajectory& tr, Index first, Index count,
                  bool with_t) {
  std::ofstream out(path);
  out << (with_t ? "t,u1\n" : "u1\n");
  char line[96];
  for (Index k = first; k < first + count; ++k) {
    if (with_t)
      std::snprintf(line, sizeof line, "%.17g,%.17g\n", tr.t(k), tr.u(0, k));
    else
      std::snprintf(line, sizeof line, "%.17g\n", tr.u(0, k));
    out << line;
  }
}

// `rollout` of a driven model: started from a window of positions with its inputs, fed the
// inputs that follow, it follows the record; what does not fit is refused by name.
TEST_F(DrivenCli, RolloutIsFedItsInputsAndRefusesWhatDoesNotFit) {
  const std::string train = (dir_ / "train.csv").string(), fit_dir = (dir_ / "fit").string();
  write_positions_with_input(train, testing::driven_record(1000, 0.05, 0.005, 11));
  CliResult r =
      run("fit " + shell_quote(train) + " --out " + shell_quote(fit_dir) + " -q --no-figures");
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  const std::string model = shell_quote(fit_dir + "/model.json");
  // A record from rest: its first 20 samples are the window, the next 200 steps the forecast.
  const Trajectory rec =
      testing::driven_record(300, 0.05, 0.005, 13, testing::kDrivenGamma, 0.0, false, 1.5);
  Trajectory window = rec;
  window.t = rec.t.head(20);
  window.z = rec.z.leftCols(20);
  window.u = rec.u.leftCols(20);
  const std::string win = (dir_ / "window.csv").string(), in = (dir_ / "in.csv").string();
  write_positions_with_input(win, window);
  write_inputs(in, rec, 19, 201, true);
  r = run("rollout --model " + model + " --from-positions " + shell_quote(win) + " --inputs " +
          shell_quote(in) + " --h 0.05 --steps 200");
  ASSERT_EQ(r.code, 0) << r.err;
  std::istringstream rows(r.out);
  std::string row;
  std::getline(rows, row);
  EXPECT_EQ(row, "t,q1,p1");
  double sq = 0.0, spread = 0.0, mean = rec.z.row(0).segment(20, 200).mean();
  for (Index k = 0; std::getline(rows, row); ++k) {
    const double q = std::stod(row.substr(row.find(',') + 1));
    if (k == 0) continue;  // the window's last sample, fitted
    sq += std::pow(q - rec.z(0, 19 + k), 2);
    spread += std::pow(rec.z(0, 19 + k) - mean, 2);
  }
  std::printf("  rollout fed its inputs: rms %.4g, spread %.4g\n", std::sqrt(sq / 200.0),
              std::sqrt(spread / 200.0));
  EXPECT_LT(std::sqrt(sq / 200.0), 0.03 * std::sqrt(spread / 200.0));
  // The same without the t column: the same rows.
  const std::string bare = (dir_ / "bare.csv").string();
  write_inputs(bare, rec, 19, 201, false);
  CliResult same = run("rollout --model " + model + " --from-positions " + shell_quote(win) +
                       " --inputs " + shell_quote(bare) + " --h 0.05 --steps 200");
  EXPECT_EQ(same.out, r.out);
  // Refusals, each naming what was expected.
  r = run("rollout --model " + model + " --z0 0,0 --h 0.05 --steps 200");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("--inputs"), std::string::npos) << r.err;
  r = run("rollout --model " + model + " --z0 0,0 --inputs " + shell_quote(in) +
          " --h 0.05 --steps 100");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("201 rows of inputs; expected 101"), std::string::npos) << r.err;
  r = run("rollout --model " + model + " --z0 0,0 --inputs " + shell_quote(in) +
          " --h 0.05 --steps 200");
  EXPECT_NE(r.code, 0);  // the t column starts at the window's end, not at 0
  EXPECT_NE(r.err.find(":2: t = "), std::string::npos) << r.err;
  std::ofstream(dir_ / "nan.csv") << "u1\n0\nnan\n0\n";
  r = run("rollout --model " + model + " --z0 0,0 --inputs " +
          shell_quote((dir_ / "nan.csv").string()) + " --h 0.05 --steps 2");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("nan.csv:3: 'nan' is not a finite number"), std::string::npos) << r.err;
  std::ofstream(dir_ / "hdr.csv") << "force\n0\n0\n0\n";
  r = run("rollout --model " + model + " --z0 0,0 --inputs " +
          shell_quote((dir_ / "hdr.csv").string()) + " --h 0.05 --steps 2");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("hdr.csv:1: header 'force'; expected '[t,]u1'"), std::string::npos) << r.err;
  const std::string no_u = (dir_ / "no_u.csv").string();
  std::ofstream(no_u) << "t,q1\n0,0.01\n0.05,0.0\n0.1,-0.01\n";
  r = run("rollout --model " + model + " --from-positions " + shell_quote(no_u) + " --inputs " +
          shell_quote(in) + " --h 0.05 --steps 200");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("expected the window's inputs u1..u1"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace csympnet
