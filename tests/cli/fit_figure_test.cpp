// `fit`'s figure (apps/csympnet/fit_figure.cpp): drawn by default beside report.json, none
// with --no-figures; a figure that cannot be drawn leaves the fit's exit code and says why in
// one line; an output path no shell may see; Ctrl-C while it is drawn stops promptly.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "cli_support.hpp"
#include "support/driven_oscillator.hpp"

namespace csympnet::testing_cli {
namespace {

namespace fs = std::filesystem;

const std::string kRecord = std::string(CSYMPNET_SOURCE_DIR) + "/examples/pendulum_record.csv";
const std::string kColumns = " --columns t=time_s,q1=angle_deg,p1=angular_velocity_deg_s";

// Whether the figure can be drawn here: Debian's python3 with matplotlib, and the csympnet
// package beside the CLI (a build with -DCSYMPNET_BUILD_PYTHON=OFF, as the sanitizer suite's,
// has none, and its fit says "figure not drawn").
bool python_with_matplotlib() {
  const fs::path package =
      fs::path(CSYMPNET_CLI_PATH).parent_path().parent_path() / "python" / "csympnet";
  std::error_code ec;
  return fs::is_regular_file(package / "fit_figure.py", ec) &&
         std::system("/usr/bin/python3 -c 'import matplotlib' >/dev/null 2>&1") == 0;
}

std::size_t lines(const std::string& s) {
  std::size_t n = 0;
  for (char c : s) n += c == '\n';
  return n;
}

class FitFigureCli : public CliTest {
 protected:
  std::string fit(const fs::path& out, const std::string& more = "") const {
    return "fit " + shell_quote(kRecord) + kColumns + " --force --out " +
           shell_quote(out.string()) + more;
  }
  static bool has_figure(const fs::path& out) {
    std::error_code ec;
    return fs::file_size(out / "fit.png", ec) > 10000 && fs::file_size(out / "fit.pdf", ec) > 10000;
  }
};

TEST_F(FitFigureCli, DrawnByDefaultAndNamedInTheWroteLine) {
  if (!python_with_matplotlib())
    GTEST_SKIP() << "no csympnet package beside the CLI, or no python3 with matplotlib";
  const fs::path out = dir_ / "out";
  const CliResult r = run(fit(out));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(has_figure(out));
  EXPECT_NE(r.out.find("wrote " + out.string() +
                       "/{report.json,model.json,timings.json,fit.png,fit.pdf}"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(r.err.find("figure not drawn"), std::string::npos) << r.err;
}

TEST_F(FitFigureCli, NoFiguresDrawsNoneAndRemovesAnEarlierOne) {
  if (!python_with_matplotlib())
    GTEST_SKIP() << "no csympnet package beside the CLI, or no python3 with matplotlib";
  const fs::path out = dir_ / "out";
  ASSERT_EQ(run(fit(out, " -q")).code, 0);
  ASSERT_TRUE(has_figure(out));
  const CliResult r = run(fit(out, " --no-figures"));
  ASSERT_EQ(r.code, 0) << r.err;
  // An earlier fit's figure would not show this fit.
  EXPECT_FALSE(fs::exists(out / "fit.png"));
  EXPECT_FALSE(fs::exists(out / "fit.pdf"));
  EXPECT_NE(r.out.find("/{report.json,model.json,timings.json}\n"), std::string::npos) << r.out;
  EXPECT_EQ(r.err.find("figure"), std::string::npos) << r.err;
}

TEST_F(FitFigureCli, AFigureThatCannotBeDrawnLeavesTheExitCodeAndSaysWhyInOneLine) {
  const fs::path out = dir_ / "out";
  for (const char* python : {"/nonexistent", "/bin/false"}) {
    const CliResult r = run(fit(out, " -q"), std::string("CSYMPNET_PYTHON=") + python);
    EXPECT_EQ(r.code, 0) << python << ": " << r.err;
    EXPECT_TRUE(fs::exists(out / "report.json"));
    EXPECT_FALSE(fs::exists(out / "fit.png")) << python;
    EXPECT_EQ(r.err.rfind("fit: figure not drawn: ", 0), 0u) << r.err;
    EXPECT_EQ(lines(r.err), 1u) << r.err;
    EXPECT_NE(r.err.find(python), std::string::npos) << "names the interpreter: " << r.err;
  }
  // A figure module that fails: the last line it wrote is the reason.
  const fs::path failing = dir_ / "failing-python";
  std::ofstream(failing) << "#!/bin/sh\necho 'a warning first' >&2\n"
                            "echo 'fit_figure: the record is gone' >&2\nexit 1\n";
  fs::permissions(failing, fs::perms::owner_all);
  const CliResult r = run(fit(out, " -q"), "CSYMPNET_PYTHON=" + shell_quote(failing.string()));
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err, "fit: figure not drawn: the record is gone (--no-figures skips it)\n");
  // Standard input is no file the figure could read again: said, not tried.
  const fs::path err = dir_ / "piped-err.txt";
  const std::string cmd = std::string(CSYMPNET_CLI_PATH) + " fit -" + kColumns +
                          " -q --force --out " + shell_quote(out.string()) + " < " +
                          shell_quote(kRecord) + " >/dev/null 2>" + shell_quote(err.string());
  const int status = std::system(cmd.c_str());
  CliResult piped;
  piped.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  piped.err = slurp(err);
  EXPECT_EQ(piped.code, 0) << piped.err;
  EXPECT_NE(piped.err.find("figure not drawn: the data were read from standard input"),
            std::string::npos)
      << piped.err;
  EXPECT_EQ(lines(piped.err), 1u) << piped.err;
}

TEST_F(FitFigureCli, AnUnidentifiedFitKeepsExitCode4) {
  std::string text = "t,q1,p1\n";
  for (int i = 0; i < 30; ++i)  // 3 time units of a slow, noisy motion: γ not identified
    text += std::to_string(0.1 * i) + "," + std::to_string(1.0 + ((i * 7) % 5) * 0.1) + "," +
            std::to_string(((i * 3) % 4) * 0.1 - 0.15) + "\n";
  std::ofstream(dir_ / "short.csv") << text;
  const CliResult r = run("fit " + shell_quote((dir_ / "short.csv").string()) + " -q --out " +
                              shell_quote((dir_ / "out").string()),
                          "CSYMPNET_PYTHON=/nonexistent");
  EXPECT_EQ(r.code, 4) << r.err;
  EXPECT_NE(r.err.find("fit: figure not drawn: "), std::string::npos) << r.err;
}

TEST_F(FitFigureCli, AnOutputPathReachesNoShell) {
  if (!python_with_matplotlib())
    GTEST_SKIP() << "no csympnet package beside the CLI, or no python3 with matplotlib";
  const fs::path out = dir_ / "a b;touch pwned;'$(touch pwned2)'";
  const CliResult r = run(fit(out, " -q"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(has_figure(out)) << r.err;
  EXPECT_FALSE(fs::exists("pwned"));
  EXPECT_FALSE(fs::exists("pwned2"));
  EXPECT_FALSE(fs::exists(dir_ / "pwned"));
}

// A driven record (t,q1,u1) gets its figure too: the free run fed the record's inputs, and the
// linearised frequency response in place of the free decay's envelope.
TEST_F(FitFigureCli, ADrivenRecordIsDrawnWithItsFrequencyResponse) {
  if (!python_with_matplotlib())
    GTEST_SKIP() << "no csympnet package beside the CLI, or no python3 with matplotlib";
  const Trajectory tr = testing::driven_record(600, 0.05, 0.005, 11);
  const fs::path data = dir_ / "driven.csv", out = dir_ / "out";
  testing::write_positions_with_input(data.string(), tr);
  const CliResult r =
      run("fit " + shell_quote(data.string()) + " --out " + shell_quote(out.string()) + " -q");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(has_figure(out)) << r.err;
  EXPECT_EQ(r.err.find("figure not drawn"), std::string::npos) << r.err;
}

TEST_F(FitFigureCli, CtrlCWhileTheFigureIsDrawnStopsPromptlyWithTheInterruptCode) {
  // An interpreter that never finishes stands for a slow figure.
  const fs::path slow = dir_ / "slow-python";
  std::ofstream(slow) << "#!/bin/sh\nexec sleep 60\n";
  fs::permissions(slow, fs::perms::owner_all);
  const fs::path out = dir_ / "out", err = dir_ / "err.txt";
  const std::string cmd = "CSYMPNET_PYTHON=" + shell_quote(slow.string()) + " " +
                          CSYMPNET_CLI_PATH + " " + fit(out, " -q") + " >/dev/null 2>" +
                          shell_quote(err.string()) + " </dev/null & pid=$!; i=0; " +
                          "while [ ! -e " + shell_quote((out / "model.json").string()) +
                          " ] && [ $i -lt 600 ]; do sleep 0.05; i=$((i+1)); done; sleep 0.5; " +
                          "kill -INT $pid; wait $pid";
  const auto start = std::chrono::steady_clock::now();
  const int status = std::system(cmd.c_str());
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130) << slurp(err);
  EXPECT_LT(seconds, 20.0);  // the sleeping child was stopped, not waited for (60 s)
  EXPECT_NE(slurp(err).find("stopped while drawing the figure"), std::string::npos) << slurp(err);
  EXPECT_TRUE(fs::exists(out / "report.json"));
  EXPECT_FALSE(fs::exists(out / "fit.png"));
}

}  // namespace
}  // namespace csympnet::testing_cli
