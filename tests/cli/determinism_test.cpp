// Same inputs, same bits: repeated commands, and a reproduction with one thread or two, write
// identical files apart from wall-clock fields. (`run` twice is checked in cli_test.cpp.)
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "cli_support.hpp"

namespace csympnet::testing_cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Every regular file under `root`, by relative path, as text.
std::map<std::string, std::string> tree(const fs::path& root) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(root))
    if (e.is_regular_file()) files[fs::relative(e.path(), root).string()] = slurp(e.path());
  return files;
}

// Removes the wall-clock fields ("seconds", "*_seconds") at any depth.
void drop_wall_times(json& j) {
  if (!j.is_object()) return;
  for (auto it = j.begin(); it != j.end();) {
    const std::string& k = it.key();
    if (k == "seconds" || (k.size() > 8 && k.compare(k.size() - 8, 8, "_seconds") == 0)) {
      it = j.erase(it);
    } else {
      drop_wall_times(*it);
      ++it;
    }
  }
}

class Determinism : public CliTest {};

TEST_F(Determinism, GenerateAndFitTwiceGiveIdenticalFiles) {
  const std::string data = (dir_ / "data.csv").string();
  ASSERT_EQ(run("generate --preset s2 --n 40 --sigma 0.01 --out " + data).code, 0);
  ASSERT_EQ(
      run("generate --preset s2 --n 40 --sigma 0.01 --out " + (dir_ / "again.csv").string()).code,
      0);
  EXPECT_EQ(slurp(data), slurp(dir_ / "again.csv"));

  for (const char* out : {"a", "b"})
    ASSERT_NE(run("fit " + data + " --epochs 60 --lm-iterations 3 --core la:2:2 -q --out " +
                  (dir_ / out).string())
                  .code,
              1);
  // fit's report holds no wall time (those are in timings.json): byte-identical files.
  EXPECT_EQ(slurp(dir_ / "a" / "model.json"), slurp(dir_ / "b" / "model.json"));
  EXPECT_EQ(slurp(dir_ / "a" / "report.json"), slurp(dir_ / "b" / "report.json"));
  const json ra = json::parse(slurp(dir_ / "a" / "report.json"));
  EXPECT_TRUE(ra["gamma_hat"].is_number());
  EXPECT_TRUE(ra["identified"].is_boolean());
}

// A positions-only record fitted with OpenBLAS on one thread and on two: the same model and
// report, byte for byte (the fit runs OpenBLAS on one thread, whose threaded dsyrk and dpotrf
// would round differently), and the report holds no wall time at all (the stages' records keep
// theirs in timings.json, "choices_seconds").
TEST_F(Determinism, APositionsFitIsTheSameWhateverOpenBlasThreadCount) {
  const fs::path data = dir_ / "positions.csv";
  {
    std::ofstream f(data);
    f << "t,q1\n";
    for (int k = 0; k < 300; ++k) {
      const double t = 0.1 * k;
      // A damped oscillator with a deterministic wobble of 0.5 % in place of noise.
      f << t << "," << std::exp(-0.05 * t) * std::cos(2.0 * t) + 0.005 * std::sin(12.345 * k * k)
        << "\n";
    }
  }
  for (const char* threads : {"1", "2"}) {
    // A G core: its positions fit factors a matrix large enough for OpenBLAS to thread (before
    // the fit held OpenBLAS to one thread, the two reports differed from the 12th digit).
    const CliResult r = run("fit " + data.string() +
                                " -q --no-figures --core g:4:32 --epochs 100 --lm-iterations 10 "
                                "--out " +
                                (dir_ / (std::string("b") + threads)).string(),
                            std::string("OPENBLAS_NUM_THREADS=") + threads);
    ASSERT_TRUE(r.code == 0 || r.code == 4) << r.code << ": " << r.err;
  }
  EXPECT_EQ(slurp(dir_ / "b1" / "model.json"), slurp(dir_ / "b2" / "model.json"));
  const std::string report = slurp(dir_ / "b1" / "report.json");
  EXPECT_EQ(report, slurp(dir_ / "b2" / "report.json"));
  EXPECT_EQ(report.find("\"seconds\""), std::string::npos);
  const json timings = json::parse(slurp(dir_ / "b1" / "timings.json"));
  EXPECT_TRUE(timings["choices_seconds"].contains("choices.positions.seconds")) << timings.dump(1);
  EXPECT_GT(timings["stages"].size(), 3u) << timings.dump(1);
}

// `reproduce --jobs 1` and `--jobs 2` on a small suite: the same run records (apart from their
// wall times), and byte-identical summary and tables.
TEST_F(Determinism, ReproduceWithOneOrTwoThreadsWritesTheSameResults) {
  const fs::path suites = dir_ / "suites";
  fs::create_directories(suites);
  std::ofstream(suites / "dtiny.json")
      << R"({"name": "dtiny", "kind": "table", "columns": ["params", "l2_error", "gamma_abs_err"],
             "presets": ["s1"], "models": ["csympnet", "sympnet", "dhnn"], "seeds": [5],
             "epochs": {"*": {"*": 40}}})";
  std::ofstream(suites / "dgrid.json")
      << R"({"name": "dgrid", "kind": "grid", "vary": "sigma", "presets": ["s1"],
             "models": ["csympnet"], "seeds": [1, 2], "sigmas": [0, 0.01],
             "epochs": {"*": {"*": 40}}})";
  std::map<std::string, std::map<std::string, std::string>> outs;
  for (const char* jobs : {"1", "2"}) {
    const fs::path out = dir_ / (std::string("j") + jobs);
    const CliResult r =
        run("reproduce --suites-dir " + suites.string() +
            " --no-figures -q --suite dtiny,dgrid --jobs " + jobs + " --out " + out.string());
    ASSERT_EQ(r.code, 0) << r.err;
    outs[jobs] = tree(out);
  }
  const auto& one = outs["1"];
  const auto& two = outs["2"];
  ASSERT_EQ(one.size(), two.size());
  std::size_t records = 0;
  for (const auto& [path, text] : one) {
    ASSERT_TRUE(two.count(path)) << path;
    if (path == "timings.json") continue;  // wall times, kept apart on purpose
    if (path.rfind("runs/", 0) == 0) {
      json a = json::parse(text), b = json::parse(two.at(path));
      for (json* rec : {&a, &b}) {
        ASSERT_TRUE(rec->contains("report")) << path;
        drop_wall_times(*rec);
      }
      EXPECT_EQ(a.dump(), b.dump()) << path;
      ++records;
    } else {
      EXPECT_EQ(text, two.at(path)) << path;
    }
  }
  EXPECT_EQ(records, 3u + 4u);
  EXPECT_TRUE(one.count("summary.json"));
  EXPECT_TRUE(one.count("tables/dtiny.md"));
  EXPECT_TRUE(one.count("tables/dgrid.csv"));
}

}  // namespace
}  // namespace csympnet::testing_cli
