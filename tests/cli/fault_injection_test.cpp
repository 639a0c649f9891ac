// Fault injection in the manner of SQLite's I/O-error tests (docs/hardening.md, "Fault
// injection"): `fit` replaces an earlier result in its --out while an LD_PRELOAD shim
// (tests/fault/fault_inject.c) makes its N-th file operation (a write, fsync or rename) fail,
// or kills the process just before it, for every N until the command gets through untouched.
// After each, the next csympnet to take the directory (here the library's OutputDir, as any
// command would) must find either the old complete result or the new complete one, byte for
// byte: never a mix, never a file missing, never a leftover temporary or journal. A failed
// operation must end in a clear error naming the file, never a crash.
#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "cli/cli_support.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/models/model_file.hpp"

namespace csympnet {
namespace {

namespace fs = std::filesystem;
using testing_cli::CliResult;
using testing_cli::CliTest;
using testing_cli::shell_quote;
using testing_cli::slurp;

class FaultInjection : public CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    data_ = dir_ / "pairs.csv";
    ASSERT_EQ(run("generate --preset s1 --n 40 --out " + data_.string()).code, 0);
    ASSERT_EQ(run(fit_args(1, dir_ / "old")).code, 0);
    ASSERT_EQ(run(fit_args(2, dir_ / "new")).code, 0);
    ASSERT_NE(slurp(dir_ / "old" / "model.json"), slurp(dir_ / "new" / "model.json"));
  }

  std::string fit_args(int seed, const fs::path& out) const {
    return "fit " + data_.string() +
           " --recipe classic --epochs 20 --refine none --bootstrap 0 "
           "-q --force --seed " +
           std::to_string(seed) + " --out " + shell_quote(out.string());
  }

  // A report without its wall times (any key ending in "seconds"), which differ run to run.
  static nlohmann::json timeless(const fs::path& report) {
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(slurp(report));
    } catch (const nlohmann::json::exception&) {
      return nullptr;  // missing or torn: matches no complete result
    }
    const std::function<void(nlohmann::json&)> strip = [&strip](nlohmann::json& v) {
      if (!v.is_object()) return;
      for (auto it = v.begin(); it != v.end();) {
        const std::string& k = it.key();
        if (k.size() >= 7 && k.compare(k.size() - 7, 7, "seconds") == 0) {
          it = v.erase(it);
        } else {
          strip(*it);
          ++it;
        }
      }
    };
    strip(j);
    return j;
  }

  // The result files a directory shows match `want`'s: the model byte for byte, the report
  // but for its wall times, the timings by presence (they are all wall times).
  bool holds(const fs::path& dir, const fs::path& want) const {
    return slurp(dir / "model.json") == slurp(want / "model.json") &&
           !timeless(dir / "report.json").is_null() &&
           timeless(dir / "report.json") == timeless(want / "report.json") &&
           fs::exists(dir / "timings.json");
  }

  void sweep(const std::string& mode) {
    int injected = 0;
    for (int n = 1; n <= 200; ++n) {
      const fs::path out = dir_ / (mode + std::to_string(n)), mark = dir_ / "mark";
      fs::remove(mark);
      fs::copy(dir_ / "old", out, fs::copy_options::recursive);
      const std::string env = "LD_PRELOAD=" + shell_quote(CSYMPNET_FAULT_SHIM) +
                              " ASAN_OPTIONS=verify_asan_link_order=0:detect_leaks=0" +
                              " CSYMPNET_FAULT_MODE=" + mode +
                              " CSYMPNET_FAULT_AT=" + std::to_string(n) +
                              " CSYMPNET_FAULT_MARK=" + shell_quote(mark.string());
      const CliResult r = run(fit_args(2, out), env);
      const bool hit = fs::exists(mark);
      if (!hit) {  // past the last file operation: the command ran untouched
        EXPECT_EQ(r.code, 0) << r.err;
        EXPECT_TRUE(holds(out, dir_ / "new"));
        EXPECT_GT(injected, 5) << "the sweep reached too few operations to mean anything";
        return;
      }
      ++injected;
      if (mode == "kill") {
        EXPECT_EQ(r.code, 128 + 9) << "operation " << n << ": " << r.err;
      } else {
        EXPECT_EQ(r.code, 1) << "operation " << n << ": " << r.err;
        EXPECT_EQ(r.err.rfind("csympnet: error: ", 0), 0u) << r.err;
        EXPECT_NE(r.err.find(out.string()), std::string::npos) << r.err;  // names the file
      }
      { const OutputDir next = prepare_output_dir(out.string(), true); }  // the next command
      const bool old_set = holds(out, dir_ / "old"), new_set = holds(out, dir_ / "new");
      EXPECT_TRUE(old_set || new_set) << mode << " at operation " << n << " left a mixed set";
      EXPECT_NO_THROW(load_model((out / "model.json").string())) << mode << " at " << n;
      std::set<std::string> names;
      for (const auto& e : fs::directory_iterator(out)) names.insert(e.path().filename());
      EXPECT_EQ(names, (std::set<std::string>{"model.json", "report.json", "timings.json"}))
          << mode << " at operation " << n;
    }
    ADD_FAILURE() << "the command still hit a fault after 200 operations";
  }

  fs::path data_;
};

TEST_F(FaultInjection, EveryFailedFileOperationLeavesTheOldOrTheNewResult) {
  sweep("fail");
}

TEST_F(FaultInjection, AKillAtEveryFileOperationLeavesTheOldOrTheNewResult) {
  sweep("kill");
}

}  // namespace
}  // namespace csympnet
