// The malformed-input corpus (tests/data/malformed): every file is fed to each CLI command that
// reads its kind, and each must be answered with a clear error and a nonzero exit, never a
// crash: exit 1 ("csympnet: error: ..."), the file named (with its line where one applies),
// what was expected, and nothing written to the output directory.
//
// CSYMPNET_MALFORMED_TABLE=FILE writes the table of case -> message for docs/hardening.md.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "cli_support.hpp"

namespace csympnet::testing_cli {
namespace {

namespace fs = std::filesystem;

const fs::path kCorpus = fs::path(CSYMPNET_SOURCE_DIR) / "tests" / "data" / "malformed";

// File -> a fragment the message must contain besides the file's path. A fragment starting
// with ':' is a line reference and must follow the path directly ("file.csv:3:").
const std::map<std::string, std::string> kPairs = {
    {"empty.csv", ":1: file is empty"},
    {"header_only.csv", ":1: header only, no data rows"},
    {"nan.csv", ":3: column 'q1': expected a finite number, got 'nan'"},
    {"inf.csv", ":3: column 'p1': expected a finite number, got '-inf'"},
    {"non_numeric.csv", ":3: column 'next_q1': expected a finite number, got 'abc'"},
    {"decimal_comma.csv", ":1: unrecognised header"},
    {"short_row.csv", ":3: found 4 fields; expected 5"},
    {"long_row.csv", ":2: found 6 fields; expected 5"},
    {"odd_dimension.csv", ":1: pairs header"},
    {"h_zero.csv", ":2: column 'h': expected a step h > 0"},
    {"h_subnormal.csv", ":3: column 'h': the step '1e-320' is below the smallest normal double"},
    {"h_negative.csv", ":3: column 'h': expected a step h > 0"},
    {"overflow.csv", ":2: column 'q1': expected a finite number, got '1e999', which is outside"},
    {"underflow.csv", ":2: column 'q1': expected a finite number, got '1e-999', which is outside"},
    {"near_overflow.csv", ":2: column 'q1': '1.7e308' is too large to train on"},
    {"blank_line_inside.csv", ":3: blank line"},
    {"bad_header.csv", ":1: header column 4 is 'next_p1'; expected 'next_q1'"},
    {"nul_byte.csv", ":2: NUL byte"},
    {"lone_cr.csv", ":1: carriage return not followed by a newline"},
    {"utf8_text.csv", ":2: byte 0xE2"},
    {"binary_garbage.csv", ":1: "},
};

const std::map<std::string, std::string> kTrajectories = {
    {"empty.csv", ":1: file is empty"},
    {"header_only.csv", ":1: header only, no data rows"},
    {"nan.csv", ":3: column 'q1': expected a finite number, got 'NaN'"},
    {"inf.csv", ":3: column 'p1': expected a finite number, got 'Infinity'"},
    {"non_numeric.csv", ":3: column 'p1': expected a finite number, got '-0.1x'"},
    {"short_row.csv", ":3: found 3 fields; expected 4"},
    {"odd_dimension.csv", ":1: trajectories header"},
    {"non_increasing_t.csv", ":4: column 't': got '0.1' after t = 0.2 on line 3"},
    {"repeated_t.csv", ":4: column 't': got '0.1' after t = 0.1 on line 3"},
    {"subnormal_step.csv", ":3: column 't': the step from t = 0 on line 2 to '1e-310' is below"},
    {"no_traj_repeated_t.csv", ":3: column 't': got '0' after t = 0 on line 2"},
    {"single_point.csv", "all 1 trajectories have a single row, so the file gives no pairs"},
    {"single_points_only.csv", "all 3 trajectories have a single row, so the file gives no pairs"},
    {"mismatched_ids.csv",
     ":6: mismatched trajectory ids: id 0 reappears after its rows on lines 2-3"},
    {"non_integer_id.csv", ":3: column 'traj': expected an integer trajectory id, got '1.5'"},
    {"id_overflow.csv", ":2: column 'traj': expected an integer trajectory id"},
    {"overflow.csv", ":3: column 'q1': expected a finite number, got '-1e400', which is outside"},
    {"near_overflow.csv", ":2: column 'q1': '1.7e308' is too large to train on"},
    {"time_span_overflow.csv", ":3: column 't': the step from t = -1.7e+308 on line 2"},
    {"bad_header.csv", ":1: header column 2 is 'time'; expected 't'"},
    {"binary_garbage.csv", ":1: "},
};

// `evaluate --data` reads trajectories without turning them into pairs; where its answer
// differs from fit's, it is here.
const std::map<std::string, std::string> kEvaluateData = {
    {"single_point.csv", "trajectory 1 of 1 has a single point"},
    {"single_points_only.csv", "trajectory 1 of 3 has a single point"},
    {"near_overflow.csv", "trajectory 1 has a state value beyond 1e150"},
};

const std::map<std::string, std::string> kModels = {
    {"empty.json", "not valid JSON"},
    {"truncated.json", "not valid JSON"},
    {"binary_garbage.json", "not valid JSON"},
    {"bit_flip_structure.json", "not valid JSON"},
    {"param_changed.json", "checksum mismatch"},
    {"bit_flip_param.json", "checksum mismatch"},
    {"meta_changed.json", "checksum mismatch"},
    {"bit_flip_key.json", "missing array \"params\""},
    {"wrong_version.json", "model format version 3 is not supported"},
    {"version_string.json", "missing integer \"version\""},
    {"wrong_format.json", "not a csympnet model file"},
    {"json_array.json", "expected a JSON object"},
    {"missing_checksum.json", "missing string \"checksum\""},
    {"param_count.json", "\"params\" has 114 entries but the architecture needs 115"},
    {"param_overflow.json", "not valid JSON"},
    {"param_string.json", "params[3] is not a number"},
    {"unknown_model_type.json", "unknown model type 'csympnet3'"},
    {"huge_sizes.json", "sizes multiply to"},
    {"negative_size.json", "expected an integer >= 1"},
};

struct Row {
  std::string command, file, message;
  int code;
};

std::vector<Row>& table() {
  static std::vector<Row> rows;
  return rows;
}

class Malformed : public CliTest {
 protected:
  static void TearDownTestSuite() {
    const char* path = std::getenv("CSYMPNET_MALFORMED_TABLE");
    if (!path || !*path) return;
    std::ofstream out(path);
    out << "| command | case | exit | what the user sees on stderr |\n|---|---|---|---|\n";
    for (const Row& r : table()) {
      std::string msg = r.message;
      while (!msg.empty() && msg.back() == '\n') msg.pop_back();
      std::string cell;
      for (char c : msg)
        cell += c == '|' ? std::string("\\|") : c == '\n' ? std::string("<br>") : std::string(1, c);
      out << "| `" << r.command << "` | " << r.file << " | " << r.code << " | " << cell << " |\n";
    }
  }

  // Runs `args` (which read `file`), and checks the answer; `fragment` as in kPairs.
  void expect_clear_refusal(const std::string& command, const std::string& args,
                            const fs::path& file, const std::string& fragment,
                            const fs::path& out_dir) {
    const CliResult r = run(args);
    const std::string name =
        file.parent_path().filename().string() + "/" + file.filename().string();
    table().push_back({command, name, r.err, r.code});
    SCOPED_TRACE(command + " on " + name + ": " + r.err);
    EXPECT_FALSE(r.signalled);
    EXPECT_EQ(r.code, 1);
    EXPECT_EQ(r.err.rfind("csympnet: error: ", 0), 0u);
    EXPECT_EQ(r.err.find("internal error"), std::string::npos);
    // Plain text even for a binary file: no raw bytes copied from the input.
    EXPECT_TRUE(std::all_of(r.err.begin(), r.err.end(), [](char c) {
      return c == '\n' ||
             (static_cast<unsigned char>(c) >= 0x20 && static_cast<unsigned char>(c) < 0x7f);
    })) << "stderr is printable ASCII";
    EXPECT_NE(r.err.find(file.string()), std::string::npos) << "the message names the file";
    if (!fragment.empty() && fragment[0] == ':') {
      EXPECT_NE(r.err.find(file.string() + fragment), std::string::npos);
    } else {
      EXPECT_NE(r.err.find(fragment), std::string::npos);
    }
    EXPECT_TRUE(r.err.find("expected") != std::string::npos ||
                r.err.find("valid types") != std::string::npos)
        << "the message says what was expected";
    // Nothing written: no output directory, or (fit and train make it before reading) an
    // empty one.
    if (fs::exists(out_dir)) {
      EXPECT_TRUE(fs::is_empty(out_dir)) << out_dir;
    }
  }

  static void expect_corpus_matches(const std::string& kind,
                                    const std::map<std::string, std::string>& cases) {
    std::set<std::string> on_disk;
    for (const auto& e : fs::directory_iterator(kCorpus / kind))
      on_disk.insert(e.path().filename().string());
    std::set<std::string> listed;
    for (const auto& [name, fragment] : cases) listed.insert(name);
    EXPECT_EQ(on_disk, listed) << "every file in tests/data/malformed/" << kind
                               << " needs an expected message here, and vice versa";
  }
};

TEST_F(Malformed, PairsFilesAreRefusedByFitAndTrain) {
  expect_corpus_matches("pairs", kPairs);
  int k = 0;
  for (const auto& [name, fragment] : kPairs) {
    const fs::path file = kCorpus / "pairs" / name;
    const fs::path o1 = dir_ / ("fit" + std::to_string(k)),
                   o2 = dir_ / ("train" + std::to_string(k++));
    expect_clear_refusal(
        "fit", "fit " + shell_quote(file.string()) + " --epochs 20 -q --out " + o1.string(), file,
        fragment, o1);
    expect_clear_refusal(
        "train",
        "train --data " + shell_quote(file.string()) + " --epochs 20 -q --out " + o2.string(), file,
        fragment, o2);
  }
}

TEST_F(Malformed, TrajectoryFilesAreRefusedByFitTrainAndEvaluate) {
  expect_corpus_matches("trajectories", kTrajectories);
  const fs::path m = dir_ / "m";
  ASSERT_EQ(run("run --preset s1 --epochs 2 -q --out " + m.string()).code, 0);
  int k = 0;
  for (const auto& [name, fragment] : kTrajectories) {
    const fs::path file = kCorpus / "trajectories" / name;
    const std::string q = shell_quote(file.string()), n = std::to_string(k++);
    const fs::path o1 = dir_ / ("fit" + n), o2 = dir_ / ("train" + n), o3 = dir_ / ("eval" + n);
    expect_clear_refusal("fit", "fit " + q + " --epochs 20 -q --out " + o1.string(), file, fragment,
                         o1);
    expect_clear_refusal("train", "train --data " + q + " --epochs 20 -q --out " + o2.string(),
                         file, fragment, o2);
    const auto e = kEvaluateData.find(name);
    expect_clear_refusal("evaluate",
                         "evaluate --model " + (m / "model.json").string() + " --data " + q +
                             " --out " + o3.string(),
                         file, e == kEvaluateData.end() ? fragment : e->second, o3);
  }
}

TEST_F(Malformed, ModelFilesAreRefusedByEvaluateAndRollout) {
  expect_corpus_matches("model", kModels);
  int k = 0;
  for (const auto& [name, fragment] : kModels) {
    const fs::path file = kCorpus / "model" / name;
    const std::string q = shell_quote(file.string());
    const fs::path o = dir_ / ("eval" + std::to_string(k++));
    expect_clear_refusal("evaluate", "evaluate --model " + q + " --preset s1 --out " + o.string(),
                         file, fragment, o);
    expect_clear_refusal("rollout", "rollout --model " + q + " --z0 0.5,0 --h 0.1 --steps 2", file,
                         fragment, dir_ / "none");
  }
}

}  // namespace
}  // namespace csympnet::testing_cli
