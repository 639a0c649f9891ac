// `csympnet fit` end to end on a small trajectory file: γ̂ with its interval on stdout and in
// report.json, wall times apart in timings.json; and a smoke run of experiments/coverage.py.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <sys/wait.h>

#include <nlohmann/json.hpp>
#include <unsupported/Eigen/MatrixFunctions>

#include "csympnet/core/error.hpp"
#include "csympnet/data/csv.hpp"
#include "csympnet/data/generate.hpp"
#include "csympnet/io/files.hpp"
#include "data/temp_dir.hpp"
#include "support/shell_and_files.hpp"

namespace csympnet {
namespace {

namespace fs = std::filesystem;

using testing::shell;
using testing::slurp;

// Six trajectories of the s1 oscillator (γ = 0.05) by expm at irregular steps.
std::vector<Trajectory> oscillator_trajectories() {
  ReferenceOptions ref;
  ref.method = Reference::kExpm;
  const System sys(SystemSpec{});
  Rng rng(7, "fit-cli-test");
  std::vector<Trajectory> trajs;
  for (int m = 0; m < 6; ++m) {
    Trajectory t;
    t.t.resize(11);
    t.z.resize(2, 11);
    t.t(0) = 0.0;
    t.z.col(0) = rng.uniform_vector(2, -1.0, 1.0);
    for (int k = 1; k <= 10; ++k) {
      const double h = rng.uniform(0.05, 0.15);
      t.t(k) = t.t(k - 1) + h;
      t.z.col(k) = expm_propagator(sys, h) * t.z.col(k - 1);
    }
    trajs.push_back(t);
  }
  return trajs;
}

// The classic recipe trains a map: γ̂ is printed as a training outcome with no interval, and
// a bootstrap asked for is reported as its spread, never as gamma_ci_low/high.
TEST(FitCli, ClassicRecipePrintsNoIntervalAndReportsTheBootstrapAsASpread) {
  testing::TempDir dir;
  const fs::path data = dir.path() / "traj.csv", out = dir.path() / "fit";
  write_trajectories_csv(data.string(), oscillator_trajectories());
  const fs::path stdout_file = dir.path() / "stdout.txt";
  ASSERT_EQ(
      shell(std::string(CSYMPNET_CLI_PATH) + " fit " + data.string() + " --out " + out.string() +
            " --recipe classic --epochs 300 --warm-start --refine auto --refine-iterations 5 "
            "--bootstrap 10 -q > " +
            stdout_file.string() + " 2>&1"),
      0)
      << slurp(stdout_file);
  const std::string printed = slurp(stdout_file);
  EXPECT_NE(printed.find("gamma_hat = "), std::string::npos) << printed;
  EXPECT_EQ(printed.find(" ± "), std::string::npos) << printed;
  EXPECT_NE(printed.find("no interval"), std::string::npos) << printed;
  EXPECT_NE(printed.find("not an interval"), std::string::npos) << printed;
  const auto rep = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_TRUE(rep["gamma_ci_low"].is_null() && rep["gamma_ci_high"].is_null()) << rep.dump();
  ASSERT_TRUE(rep["bootstrap"].is_object()) << rep.dump();
  EXPECT_EQ(rep["bootstrap"]["replicates"], 10);
  EXPECT_EQ(rep["bootstrap"]["resample"], "trajectories");
  EXPECT_LT(rep["bootstrap"]["low"].get<double>(), rep["bootstrap"]["high"].get<double>());
  EXPECT_EQ(rep["refine"]["method"], "lm");
  EXPECT_EQ(rep["warm_start"]["method"], "midpoint");
  EXPECT_LT(rep["quality"]["structure_residual_max"].get<double>(), 1e-12);
  // Wall times live in timings.json, so that the report is bit-identical run to run.
  EXPECT_FALSE(rep["refine"].contains("seconds"));
  EXPECT_FALSE(rep["bootstrap"].contains("seconds"));
  const auto timings = nlohmann::json::parse(slurp(out / "timings.json"));
  EXPECT_TRUE(timings.contains("bootstrap_seconds"));
}

TEST(FitCli, ClassicRecipeDefaults) {
  // `fit --recipe classic` with no other options: warm start, LM (s1-sized), no interval and
  // no bootstrap. `train` on the same data keeps the paper's recipe.
  testing::TempDir dir;
  const fs::path data = dir.path() / "traj.csv";
  write_trajectories_csv(data.string(), oscillator_trajectories());
  const fs::path stdout_file = dir.path() / "stdout.txt";
  const std::string cli = CSYMPNET_CLI_PATH;
  ASSERT_EQ(shell(cli + " fit " + data.string() + " --out " + (dir.path() / "fit").string() +
                  " --recipe classic --epochs 200 --refine-iterations 5 -q > " +
                  stdout_file.string() + " 2>&1"),
            0)
      << slurp(stdout_file);
  EXPECT_EQ(slurp(stdout_file).find(" ± "), std::string::npos) << slurp(stdout_file);
  auto rep = nlohmann::json::parse(slurp(dir.path() / "fit" / "report.json"));
  EXPECT_EQ(rep["refine"]["method"], "lm");
  EXPECT_EQ(rep["config"]["refine"]["linear_solver"], "dense_qr");
  EXPECT_EQ(rep["warm_start"]["method"], "midpoint");
  EXPECT_TRUE(rep["gamma_ci_low"].is_null());
  EXPECT_TRUE(rep["bootstrap"].is_null());

  ASSERT_EQ(
      shell(cli + " train --data " + data.string() + " --out " + (dir.path() / "train").string() +
            " --epochs 200 -q > " + stdout_file.string() + " 2>&1"),
      0)
      << slurp(stdout_file);
  rep = nlohmann::json::parse(slurp(dir.path() / "train" / "report.json"));
  EXPECT_EQ(rep["refine"]["method"], "none");
  EXPECT_EQ(rep["warm_start"], "off");
  EXPECT_TRUE(rep["gamma_ci_low"].is_null());

  // Any size: no interval, and the note says where one comes from; --no-warm-start and
  // --refine none switch the rest off.
  ASSERT_EQ(
      shell(cli + " fit " + data.string() + " --out " + (dir.path() / "big").string() +
            " --recipe classic --core la:3:400 --epochs 20 --refine none --no-warm-start -q > " +
            stdout_file.string() + " 2>&1"),
      0)
      << slurp(stdout_file);
  const std::string printed = slurp(stdout_file);
  EXPECT_NE(printed.find("no interval: this recipe trains a map"), std::string::npos) << printed;
  rep = nlohmann::json::parse(slurp(dir.path() / "big" / "report.json"));
  EXPECT_TRUE(rep["gamma_ci_low"].is_null());
  EXPECT_NE(rep["gamma_ci_note"].get<std::string>().find("csympnet fit"), std::string::npos);
  EXPECT_EQ(rep["warm_start"], "off");
  EXPECT_EQ(rep["refine"]["method"], "none");
}

TEST(FitCli, CoverageScriptSmoke) {
  testing::TempDir dir;
  const std::string cmd = "/usr/bin/python3 " + std::string(CSYMPNET_SOURCE_DIR) +
                          "/experiments/coverage.py --csympnet " + CSYMPNET_CLI_PATH +
                          " --sigmas 1e-2 --seeds 1 --n 40 --epochs 200 --bootstrap 10 --out " +
                          dir.path().string() + " > " + (dir.path() / "table.md").string() +
                          " 2>&1";
  ASSERT_EQ(shell(cmd), 0) << slurp(dir.path() / "table.md");
  const auto records = nlohmann::json::parse(slurp(dir.path() / "coverage.json"));
  ASSERT_EQ(records.size(), 1u);
  EXPECT_LT(records[0]["low"].get<double>(), records[0]["high"].get<double>());
  EXPECT_NE(slurp(dir.path() / "table.md").find("| s1 | 0.01 | 1 |"), std::string::npos);
}

}  // namespace
}  // namespace csympnet

namespace csympnet {
namespace {

TEST(FitCli, IdentifyRecipeWritesAVerdictAndAnInterval) {
  testing::TempDir dir;
  const fs::path data = dir.path() / "traj.csv", out = dir.path() / "fit";
  write_trajectories_csv(data.string(), oscillator_trajectories());
  const fs::path stdout_file = dir.path() / "stdout.txt";
  ASSERT_EQ(
      shell(std::string(CSYMPNET_CLI_PATH) + " fit " + data.string() + " --out " + out.string() +
            " --epochs 300 --lm-iterations 30 -q > " + stdout_file.string() + " 2>&1"),
      0)
      << slurp(stdout_file);
  const std::string printed = slurp(stdout_file);
  EXPECT_EQ(printed.rfind("gamma_hat = ", 0), 0u) << printed;
  const auto rep = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_EQ(rep["identified"], true);
  EXPECT_TRUE(rep["not_identified_reason"].is_null());
  const double g = rep["gamma_hat"].get<double>();
  EXPECT_LT(rep["gamma_ci_low"].get<double>(), g);
  EXPECT_GT(rep["gamma_ci_high"].get<double>(), g);
  // The library core's fit continues over the whole record, q and p observed.
  EXPECT_EQ(rep["gamma_ci_method"],
            "cluster-robust sandwich over blocks of the whole-record fit (q and p observed)");
  EXPECT_TRUE(rep["choices"]["whole_record"]["linking"].is_object());
  // The library core is fitted first; on a clean linear oscillator its q1^2 term is the exact
  // force, so it explains the held-out data to the rounding floor and the neural cores are not
  // trained. The choice, its reason and the Hamiltonian are recorded.
  const auto& cands = rep["choices"]["core_candidates"];
  ASSERT_EQ(cands.size(), 1u);
  EXPECT_EQ(cands[0]["core"]["type"], "library");
  EXPECT_EQ(rep["choices"]["core"], cands[0]["core"]);
  EXPECT_EQ(rep["architecture"]["core"], cands[0]["core"]);
  EXPECT_NE(rep["choices"]["core_reason"].get<std::string>().find("clean data explained"),
            std::string::npos)
      << rep["choices"]["core_reason"];
  ASSERT_TRUE(rep["hamiltonian"].is_object());
  bool quadratic = false;
  for (const auto& t : rep["hamiltonian"]["terms"])
    if (t["term"] == "q1^2") {
      quadratic = true;
      const auto& iv = t["interval"];
      EXPECT_LE(iv[0].get<double>(), t["coefficient"].get<double>());
      EXPECT_GE(iv[1].get<double>(), t["coefficient"].get<double>());
    }
  EXPECT_TRUE(quadratic) << rep["hamiltonian"].dump();
  EXPECT_EQ(rep["choices"]["blocks"]["kind"], "segments of trajectories");
  EXPECT_LT(rep["quality"]["structure_residual_max"].get<double>(), 1e-12);
  EXPECT_TRUE(rep["normalization"]["time_scale"].is_number());
  EXPECT_FALSE(rep["training"].contains("seconds"));
  EXPECT_TRUE(fs::exists(out / "timings.json"));
  // The saved model carries its units: rollout reads it in the file's units.
  const auto model = nlohmann::json::parse(slurp(out / "model.json"));
  EXPECT_TRUE(model.dump().find("normalization") != std::string::npos);
}

TEST(FitCli, NotIdentifiedIsADistinctExitWithTheReasonInTheReport) {
  testing::TempDir dir;
  const fs::path data = dir.path() / "noise.csv", out = dir.path() / "fit";
  std::vector<Trajectory> noise(1);
  Rng rng(5, "noise-cli");
  noise[0].z = rng.normal_matrix(2, 120, 1.0);
  noise[0].t = Vector::LinSpaced(120, 0.0, 11.9);
  write_trajectories_csv(data.string(), noise);
  const fs::path stdout_file = dir.path() / "stdout.txt";
  const int code =
      shell(std::string(CSYMPNET_CLI_PATH) + " fit " + data.string() + " --out " + out.string() +
            " --epochs 200 --lm-iterations 10 -q > " + stdout_file.string() + " 2>&1");
  EXPECT_EQ(code, 4) << slurp(stdout_file);
  const std::string printed = slurp(stdout_file);
  EXPECT_NE(printed.find("gamma_hat: not identified"), std::string::npos) << printed;
  EXPECT_NE(printed.find("csympnet: not identified: "), std::string::npos) << printed;
  const auto rep = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_EQ(rep["identified"], false);
  EXPECT_FALSE(rep["not_identified_reason"].get<std::string>().empty());
}

TEST(FitCli, ClassicOptionsNeedTheClassicRecipe) {
  testing::TempDir dir;
  const fs::path data = dir.path() / "traj.csv";
  write_trajectories_csv(data.string(), oscillator_trajectories());
  const fs::path err = dir.path() / "err.txt";
  EXPECT_EQ(shell(std::string(CSYMPNET_CLI_PATH) + " fit " + data.string() + " --out " +
                  (dir.path() / "o").string() + " --bootstrap 10 -q > " + err.string() + " 2>&1"),
            2);
  EXPECT_NE(slurp(err).find("--recipe classic"), std::string::npos) << slurp(err);
}

}  // namespace
}  // namespace csympnet

namespace csympnet {
namespace {

// One record of a linear oscillator, dq/dt = p, dp/dt = −q − gamma p, exact flow, 1% noise.
std::vector<Trajectory> linear_record(double gamma, int points, double h, std::uint64_t seed) {
  Matrix a(2, 2);
  a << 0.0, 1.0, -1.0, -gamma;
  const Matrix step = (a * h).exp();
  Rng rng(seed, "fit-cli-record");
  Trajectory t;
  t.t.resize(points);
  t.z.resize(2, points);
  t.t(0) = 0.0;
  t.z.col(0) << 0.5, 0.0;
  for (int k = 1; k < points; ++k) {
    t.t(k) = k * h;
    t.z.col(k) = step * t.z.col(k - 1);
  }
  for (int k = 0; k < points; ++k)
    for (int i = 0; i < 2; ++i) t.z(i, k) += 0.01 * 0.3 * rng.normal();
  return {t};
}

// `csympnet fit` with a small budget on the record, in a temporary directory: its exit code,
// what it printed and its report.
struct SmallFit {
  int code = -1;
  std::string printed;
  nlohmann::json report;
};
// `csympnet fit` on a CSV of this text, with these options after the data and --out.
SmallFit small_fit_text(
    const std::string& text,
    const std::string& options = " --core la:2:4 --epochs 300 --lm-iterations 40") {
  testing::TempDir dir;
  const fs::path data = dir.path() / "record.csv", out = dir.path() / "fit";
  const fs::path stdout_file = dir.path() / "stdout.txt";
  write_text_atomic(data.string(), text);
  SmallFit f;
  f.code = shell(std::string(CSYMPNET_CLI_PATH) + " fit " + data.string() + " --out " +
                 out.string() + options + " -q > " + stdout_file.string() + " 2>&1");
  f.printed = slurp(stdout_file);
  if (fs::exists(out / "report.json")) f.report = nlohmann::json::parse(slurp(out / "report.json"));
  return f;
}
SmallFit small_fit(const std::vector<Trajectory>& rec) {
  return small_fit_text(trajectories_csv_text(rec));
}

// Growing motion: not "no damping" but the model rejected, named as growth, with a rate whose
// interval (from the fit in reversed time) covers the truth; exit 5 and the checks in the report.
TEST(FitCli, GrowingMotionIsRejectedAndNamedWithItsRate) {
  const SmallFit f = small_fit(linear_record(-0.1, 160, 0.1, 3));
  EXPECT_EQ(f.code, 5) << f.printed;
  const std::string& printed = f.printed;
  EXPECT_NE(printed.find("gamma_hat: model rejected"), std::string::npos) << printed;
  EXPECT_NE(printed.find("the motion grows"), std::string::npos) << printed;
  EXPECT_EQ(printed.find("from no damping"), std::string::npos) << printed;
  ASSERT_TRUE(f.report.is_object()) << f.printed;
  const nlohmann::json& rep = f.report;
  EXPECT_EQ(rep["verdict"], "model rejected");
  EXPECT_EQ(rep["identified"], false);
  EXPECT_TRUE(rep["gamma_ci_low"].is_null());
  ASSERT_EQ(rep["checks"].size(), 5u);
  EXPECT_EQ(rep["checks"][0]["name"], "measured_momenta");
  EXPECT_EQ(rep["checks"][0]["passed"], true);
  const auto& g = rep["checks"][1];
  EXPECT_EQ(g["name"], "dissipation");
  EXPECT_EQ(g["passed"], false);
  const auto& rev = g["details"]["reversed_time_fit"];
  ASSERT_TRUE(rev.contains("interval")) << rev.dump();
  EXPECT_LT(rev["interval"][0].get<double>(), 0.1);
  EXPECT_GT(rev["interval"][1].get<double>(), 0.1);
}

// The record's positions alone, as a positions file '[traj,]t,q1..qd'.
SmallFit small_fit_positions(const std::vector<Trajectory>& rec) {
  std::string text = "t,q1\n";
  for (Index k = 0; k < rec.front().t.size(); ++k)
    text += round_trip_text(rec.front().t(k)) + "," + round_trip_text(rec.front().z(0, k)) + "\n";
  return small_fit_text(text);
}

// The same from positions alone: rejected as growth, and the growth rate from the positions
// fitted in reversed time, with an interval that covers the truth (it once printed the forward
// fit's biased signed rate).
TEST(FitCli, GrowingPositionsAreRejectedAndNamedWithTheirRate) {
  const SmallFit f = small_fit_positions(linear_record(-0.1, 300, 0.1, 3));
  EXPECT_EQ(f.code, 5) << f.printed;
  EXPECT_NE(f.printed.find("the motion grows"), std::string::npos) << f.printed;
  ASSERT_TRUE(f.report.is_object()) << f.printed;
  EXPECT_EQ(f.report["observed"], "positions");
  EXPECT_EQ(f.report["verdict"], "model rejected");
  const nlohmann::json* g = nullptr;
  for (const auto& k : f.report["checks"])
    if (k["name"] == "dissipation") g = &k;
  ASSERT_NE(g, nullptr);
  EXPECT_EQ((*g)["passed"], false);
  const auto& rev = (*g)["details"]["reversed_time_fit"];
  ASSERT_TRUE(rev.contains("interval")) << rev.dump();
  EXPECT_LT(rev["interval"][0].get<double>(), 0.1);
  EXPECT_GT(rev["interval"][1].get<double>(), 0.1);
}

// Positions alone are fitted with the momenta as hidden states: identified, an interval that
// covers the truth, "observed": "positions". Momenta computed from the same noisy positions by
// central differences (numpy.gradient) are recognised and set aside: the same answer, to the
// bit, with the reason in the measured_momenta check.
TEST(FitCli, PositionsAloneAndDifferencedMomentaGiveOneAnswer) {
  std::vector<Trajectory> rec = linear_record(0.1, 300, 0.2, 5);
  const SmallFit pos = small_fit_positions(rec);
  EXPECT_EQ(pos.code, 0) << pos.printed;
  ASSERT_TRUE(pos.report.is_object()) << pos.printed;
  EXPECT_EQ(pos.report["observed"], "positions");
  EXPECT_EQ(pos.report["verdict"], "identified") << pos.report["reasons"].dump();
  EXPECT_LT(pos.report["gamma_ci_low"].get<double>(), 0.1);
  EXPECT_GT(pos.report["gamma_ci_high"].get<double>(), 0.1);
  EXPECT_EQ(pos.report["checks"][0]["applicable"], false);
  EXPECT_GT(pos.report["choices"]["positions"]["training_segments"].get<long>(), 0);

  Trajectory& t = rec.front();
  const Index n = t.t.size();
  for (Index k = 0; k < n; ++k) {
    const Index a = std::max<Index>(0, k - 1), b = std::min<Index>(n - 1, k + 1);
    t.z(1, k) = (t.z(0, b) - t.z(0, a)) / (t.t(b) - t.t(a));
  }
  const SmallFit f = small_fit(rec);
  EXPECT_EQ(f.code, 0) << f.printed;
  ASSERT_TRUE(f.report.is_object()) << f.printed;
  const nlohmann::json& rep = f.report;
  EXPECT_EQ(rep["observed"], "positions");
  EXPECT_EQ(rep["checks"][0]["name"], "measured_momenta");
  EXPECT_EQ(rep["checks"][0]["passed"], true);
  EXPECT_NE(rep["checks"][0]["sentence"].get<std::string>().find("set aside"), std::string::npos);
  EXPECT_TRUE(rep["choices"].contains("momenta_set_aside"));
  EXPECT_EQ(rep["gamma_hat"], pos.report["gamma_hat"]);
  EXPECT_EQ(rep["gamma_ci_low"], pos.report["gamma_ci_low"]);
}

// A valid record passes every check and keeps its interval.
TEST(FitCli, ValidDampedRecordPassesTheChecks) {
  const SmallFit f = small_fit(linear_record(0.1, 300, 0.2, 4));
  EXPECT_EQ(f.code, 0) << f.printed;
  ASSERT_TRUE(f.report.is_object()) << f.printed;
  const nlohmann::json& rep = f.report;
  EXPECT_EQ(rep["verdict"], "identified");
  for (const auto& c : rep["checks"]) EXPECT_EQ(c["passed"], true) << c.dump();
  EXPECT_LT(rep["gamma_ci_low"].get<double>(), 0.1);
  EXPECT_GT(rep["gamma_ci_high"].get<double>(), 0.1);
}

}  // namespace
}  // namespace csympnet

namespace csympnet {
namespace {

// The same positions with the times in units of 1e-20 and 1e20 of the original: the same
// answer in the new unit (the local-velocity start once fitted its quadratic in raw time
// offsets, whose powers spanned 40 decades: it dropped the slope, and the fit refused with
// "p1 does not vary", a column the file does not have).
TEST(FitCli, PositionsTimesIn1e20UnitsGiveTheSameAnswer) {
  const std::vector<Trajectory> rec = linear_record(0.1, 300, 0.2, 5);
  const SmallFit ref = small_fit_positions(rec);
  ASSERT_EQ(ref.code, 0) << ref.printed;
  const double g = ref.report["gamma_hat"].get<double>();
  const double width =
      ref.report["gamma_ci_high"].get<double>() - ref.report["gamma_ci_low"].get<double>();
  for (double unit : {1e-20, 1e20}) {
    std::vector<Trajectory> scaled = rec;
    scaled.front().t *= unit;
    const SmallFit f = small_fit_positions(scaled);
    EXPECT_EQ(f.code, 0) << unit << ": " << f.printed;
    ASSERT_TRUE(f.report.is_object()) << f.printed;
    // γ per time unit of the file: γ / unit.
    EXPECT_LE(std::abs(f.report["gamma_hat"].get<double>() * unit - g), 1e-4 * width) << unit;
    EXPECT_LE(std::abs(f.report["gamma_ci_low"].get<double>() * unit -
                       ref.report["gamma_ci_low"].get<double>()),
              1e-3 * width)
        << unit;
  }
}

// Steps of 1e-200 time units: velocities whose squares overflow. Refused at once, in the
// file's own columns (t and q1), never naming a p1 the file does not have.
TEST(FitCli, PositionsWithStepsBeyondComputationAreRefusedInTheirColumns) {
  std::vector<Trajectory> rec = linear_record(0.1, 100, 0.2, 5);
  rec.front().t *= 1e-200;
  const SmallFit f = small_fit_positions(rec);
  EXPECT_EQ(f.code, 1) << f.printed;
  EXPECT_NE(f.printed.find("median step"), std::string::npos) << f.printed;
  EXPECT_NE(f.printed.find("q1"), std::string::npos) << f.printed;
  EXPECT_NE(f.printed.find("rescale t"), std::string::npos) << f.printed;
  EXPECT_EQ(f.printed.find("p1"), std::string::npos) << f.printed;
}

// A constant coordinate is refused before any fit, named, with exit 1 as the states route
// refuses one (it once ran half a minute to "not identified").
TEST(FitCli, PositionsWithAConstantCoordinateAreRefusedAtOnce) {
  const std::vector<Trajectory> rec = linear_record(0.1, 300, 0.2, 5);
  std::string positions = "t,q1,q2\n", states = "t,q1,q2,p1,p2\n";
  for (Index k = 0; k < rec.front().t.size(); ++k) {
    const std::string t = round_trip_text(rec.front().t(k));
    const std::string q = round_trip_text(rec.front().z(0, k));
    positions += t + "," + q + ",0.7\n";
    // 0.7 is not the mean of 300 copies of 0.7 to the bit: the states' check once missed it.
    states += t + "," + q + ",0.7," + round_trip_text(rec.front().z(1, k)) + ",0.01\n";
  }
  const auto t0 = std::chrono::steady_clock::now();
  const SmallFit f = small_fit_text(positions);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 5.0);
  EXPECT_EQ(f.code, 1) << f.printed;
  EXPECT_NE(f.printed.find("q2 does not vary"), std::string::npos) << f.printed;
  const SmallFit s = small_fit_text(states);
  EXPECT_EQ(s.code, 1) << s.printed;
  EXPECT_NE(s.printed.find("q2 does not vary"), std::string::npos) << s.printed;
}

// The library core's Hamiltonian line says what report.json holds: from positions alone H is
// known up to one factor and its terms carry no intervals (it once pointed to intervals that
// were all null); with momenta, each term has one.
TEST(FitCli, TheHamiltonianLineSaysWhetherItsTermsHaveIntervals) {
  const std::vector<Trajectory> rec = linear_record(0.1, 300, 0.2, 5);
  std::string positions = "t,q1\n";
  for (Index k = 0; k < rec.front().t.size(); ++k)
    positions +=
        round_trip_text(rec.front().t(k)) + "," + round_trip_text(rec.front().z(0, k)) + "\n";
  for (const std::string& text : {positions, trajectories_csv_text(rec)}) {
    const bool alone = text == positions;
    testing::TempDir dir;
    const fs::path data = dir.path() / "record.csv", out = dir.path() / "fit";
    const fs::path stdout_file = dir.path() / "stdout.txt";
    write_text_atomic(data.string(), text);
    const int code =
        shell(std::string(CSYMPNET_CLI_PATH) + " fit " + data.string() + " --out " + out.string() +
              " --core library --no-figures -q > " + stdout_file.string() + " 2>&1");
    const std::string printed = slurp(stdout_file);
    ASSERT_EQ(code, 0) << printed;
    const auto rep = nlohmann::json::parse(slurp(out / "report.json"));
    ASSERT_TRUE(rep["hamiltonian"].is_object()) << rep.dump();
    for (const auto& term : rep["hamiltonian"]["terms"])
      EXPECT_EQ(term["interval"].is_null(), alone) << term.dump();
    EXPECT_EQ(printed.find("report.json has each term's interval") != std::string::npos, !alone)
        << printed;
    EXPECT_EQ(printed.find("from positions alone H is known up to one common factor: its terms "
                           "carry no intervals") != std::string::npos,
              alone)
        << printed;
  }
}

// 300 trajectories of 2 positions each (times 0 and 0.1, positions normal), as CSV text.
std::string two_sample_trajectories(std::uint64_t seed) {
  Rng rng(seed, "two-sample-trajectories");
  std::string text = "traj,t,q1\n";
  for (int j = 0; j < 300; ++j)
    for (int k = 0; k < 2; ++k)
      text += std::to_string(j) + "," + round_trip_text(0.1 * k) + "," +
              round_trip_text(rng.normal()) + "\n";
  return text;
}

// Trajectories of 2 positions each: each fits its hidden start state exactly and leaves
// nothing for the dynamics. Not identified, with that reason, and a report (exit 4); it once
// ended in "the Gauss-Newton matrix could not be factored" (exit 1).
TEST(FitCli, PositionsTrajectoriesOfTwoSamplesAreNotIdentifiedWithTheReason) {
  const SmallFit f = small_fit_text(two_sample_trajectories(11));
  EXPECT_EQ(f.code, 4) << f.printed;
  ASSERT_TRUE(f.report.is_object()) << f.printed;
  EXPECT_EQ(f.report["verdict"], "not identified");
  const std::string why = f.report["not_identified_reason"].get<std::string>();
  EXPECT_NE(why.find("3 positions in a row"), std::string::npos) << why;
  EXPECT_EQ(f.printed.find("Gauss-Newton"), std::string::npos) << f.printed;
}

// The same record with the default cores: the answer cannot depend on the core, so the library
// core is fitted and no neural core is trained for nothing (7 CPU s here, 55 under the
// sanitizers, before); the answer and its reason are those above.
TEST(FitCli, PositionsTooShortForAnySegmentTrainNoNeuralCore) {
  const SmallFit f = small_fit_text(two_sample_trajectories(12), "");
  EXPECT_EQ(f.code, 4) << f.printed;
  ASSERT_TRUE(f.report.is_object()) << f.printed;
  EXPECT_EQ(f.report["verdict"], "not identified");
  EXPECT_NE(f.report["not_identified_reason"].get<std::string>().find("3 positions in a row"),
            std::string::npos);
  const nlohmann::json& choices = f.report["choices"];
  EXPECT_EQ(choices["core"]["type"], "library") << choices.dump();
  EXPECT_NE(choices.value("core_reason", "").find("neural cores were not trained"),
            std::string::npos)
      << choices.dump();
}

}  // namespace
}  // namespace csympnet
