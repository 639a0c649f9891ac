// `csympnet fit --dissipation` end to end on an exact stick-slip record
// (tests/support/friction_oscillator.hpp): the printed "dissipation:" line, report.json's
// "dissipation" and the model file's core agree; a bad choice is refused by CLI11 (exit 2)
// naming the option; a forced term with an LA core is refused by name (exit 2).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <sys/wait.h>

#include <nlohmann/json.hpp>

#include "csympnet/data/csv.hpp"
#include "data/temp_dir.hpp"
#include "support/friction_oscillator.hpp"
#include "support/shell_and_files.hpp"

namespace csympnet {
namespace {

namespace fs = std::filesystem;

using testing::shell;
using testing::slurp;

TEST(FitFrictionCli, PrintsReportsAndSavesTheFriction) {
  testing::TempDir dir;
  const fs::path data = dir.path() / "friction.csv", out = dir.path() / "fit";
  testing::FrictionOscillator o;
  o.omega = 2.0;
  o.gamma = 0.1;
  o.mu = 0.1;
  write_trajectories_csv(
      data.string(),
      testing::friction_records(o, {{1.0, 0.0}, {-1.6, 0.4}, {2.0, 0.0}}, 301, 0.1, 2e-3, 5));
  const fs::path printed = dir.path() / "stdout.txt";
  const std::string cli = CSYMPNET_CLI_PATH;
  ASSERT_EQ(shell(cli + " fit " + data.string() + " --out " + out.string() + " --no-figures -q > " +
                  printed.string() + " 2>&1"),
            0)
      << slurp(printed);
  const std::string text = slurp(printed);
  const auto rep = nlohmann::json::parse(slurp(out / "report.json"));
  ASSERT_EQ(rep["dissipation"]["terms"].size(), 2u) << rep["dissipation"].dump();
  EXPECT_EQ(rep["dissipation"]["terms"][1]["kind"], "coulomb");
  const std::string sentence = rep["dissipation"]["sentence"].get<std::string>();
  EXPECT_NE(text.find("dissipation: " + sentence), std::string::npos) << text;
  const auto model = nlohmann::json::parse(slurp(out / "model.json"));
  EXPECT_EQ(model["model"]["core"]["dissipation"], nlohmann::json({"coulomb(p1)"}))
      << model["model"].dump();

  const fs::path bad = dir.path() / "bad.txt";
  EXPECT_EQ(shell(cli + " fit " + data.string() + " --out " + (dir.path() / "b").string() +
                  " --dissipation coulomb > " + bad.string() + " 2>&1"),
            2);
  EXPECT_NE(slurp(bad).find("--dissipation"), std::string::npos) << slurp(bad);
  EXPECT_EQ(shell(cli + " fit " + data.string() + " --out " + (dir.path() / "c").string() +
                  " --dissipation viscous+coulomb --core la:2:2 > " + bad.string() + " 2>&1"),
            2);
  EXPECT_NE(slurp(bad).find("--dissipation"), std::string::npos) << slurp(bad);
}

}  // namespace
}  // namespace csympnet
