// The hostile-input suite (docs/hardening.md, "The hostile-input suite"): hundreds of cases a
// careless or hostile user could give the built CLI, in four classes (CSV files, model files,
// options, output targets), each run as its own process under a time limit. For every case:
//   * no crash: the process exits (no signal, no exit code >= 128) with a code the case allows;
//   * no hang: it ends within kLimitSeconds;
//   * no silent wrong result: a refusal starts "csympnet: error:" (exit 1) or names the
//     option (usage, exit 2) and says what it expected; an acceptance prints no NaN or
//     infinity anywhere;
//   * nothing lost: the user's files in the case's directory are byte-identical afterwards,
//     and a refused command leaves no output directory and nothing a payload could create.
// Signals, concurrent writers, a full disk and kills between renames have their own tests
// (tests/cli/cli_test.cpp, tests/cli/signal_test.cpp, tests/io/files_test.cpp).
#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "cli/cli_support.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/core/types.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/models/model.hpp"
#include "csympnet/models/model_file.hpp"
#include "support/sanitizers.hpp"

namespace csympnet {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using testing_cli::slurp;

constexpr double kLimitSeconds = 60.0;

struct Outcome {
  int code = -1;
  bool signalled = false, hung = false;
  std::string out, err;
};

// Runs the CLI with an argument vector (no shell), in `cwd`, stdin from /dev/null.
Outcome spawn(const std::vector<std::string>& args, const fs::path& cwd) {
  const fs::path out = cwd / ".hostile_stdout", err = cwd / ".hostile_stderr";
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (::chdir(cwd.c_str()) != 0) ::_exit(127);
    const int in = ::open("/dev/null", O_RDONLY);
    const int o = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int e = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (in < 0 || o < 0 || e < 0) ::_exit(127);
    ::dup2(in, 0);
    ::dup2(o, 1);
    ::dup2(e, 2);
    std::vector<std::string> all{CSYMPNET_CLI_PATH};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv(CSYMPNET_CLI_PATH, argv.data());
    ::_exit(127);
  }
  Outcome r;
  int status = 0;
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    const pid_t done = ::waitpid(pid, &status, WNOHANG);
    if (done == pid) break;
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() >
        kLimitSeconds) {
      r.hung = true;
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  r.signalled = WIFSIGNALED(status) || (WIFEXITED(status) && WEXITSTATUS(status) >= 128);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.out = slurp(out);
  r.err = slurp(err);
  fs::remove(out);
  fs::remove(err);
  return r;
}

void write_file(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << text;
}

// ----- the valid inputs every mutation starts from --------------------------------------------

// 24 pairs of a damped oscillator (gamma 0.1, omega 1), steps of 0.1: enough for a short
// `train`, small enough that every accepted case runs in milliseconds.
std::string base_pairs() {
  std::ostringstream s;
  s.precision(17);
  s << "h,q1,p1,next_q1,next_p1\n";
  for (int i = 0; i < 24; ++i) {
    const double q = std::cos(0.7 * i), p = std::sin(0.7 * i), h = 0.1;
    const double a = std::exp(-0.05 * h);
    const double q1 = a * (q * std::cos(h) + p * std::sin(h)) * a;
    const double p1 = a * (p * std::cos(h) - q * std::sin(h)) * a;
    s << h << ',' << q << ',' << p << ',' << q1 << ',' << p1 << '\n';
  }
  return s.str();
}

std::string base_trajectories() {
  std::ostringstream s;
  s.precision(17);
  s << "traj,t,q1,p1\n";
  for (int k = 0; k < 3; ++k)
    for (int i = 0; i < 8; ++i) {
      const double t = 0.1 * i, e = std::exp(-0.05 * t);
      s << k << ',' << t << ',' << e * std::cos(t + k) << ',' << -e * std::sin(t + k) << '\n';
    }
  return s.str();
}

// A model file made by the CLI itself (train on base_pairs), once per test process.
const std::string& base_model() {
  static const std::string text = [] {
    const fs::path dir =
        fs::temp_directory_path() / ("csympnet_hostile_base_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    write_file(dir / "d.csv", base_pairs());
    const Outcome r = spawn({"train", "--data", "d.csv", "--epochs", "3", "-q", "--out", "m"}, dir);
    EXPECT_EQ(r.code, 0) << r.err;
    std::string model = slurp(dir / "m" / "model.json");
    fs::remove_all(dir);
    return model;
  }();
  return text;
}

// Rewrites a model document's checksum so that the mutation reaches the checks behind it
// (the checksum detects accidents; a hostile user can recompute it).
std::string resigned(json doc) {
  try {
    Vector theta(static_cast<Index>(doc.at("params").size()));
    for (Index i = 0; i < theta.size(); ++i)
      theta(i) = doc.at("params").at(static_cast<std::size_t>(i)).get<double>();
    doc["checksum"] = model_checksum(doc.at("model"), doc.at("meta"), theta);
  } catch (const std::exception&) {
    // params unreadable: the mutation is refused before the checksum anyway
  }
  return doc.dump(1);
}

// A Hamiltonian-library model file (d = 1: q1^2 and q1^4; `substeps` and `order` of its
// integrator), made by the library itself.
std::string library_model(Index substeps = 1, int order = 4) {
  const Model m = make_model({{"type", "csympnet"},
                              {"d", 1},
                              {"core",
                               {{"type", "library"},
                                {"terms", {"q1^2", "q1^4"}},
                                {"order", order},
                                {"substeps", substeps}}}});
  Vector theta(m.n_params());
  Rng rng(1, "unused");  // the map draws nothing
  m.init_params(rng, theta);
  return model_file_text(m, theta, json::object());
}

// ----- a case ----------------------------------------------------------------------------------

struct Case {
  std::string name;
  std::function<void(const fs::path&)> setup;  // writes the case's input files
  std::vector<std::string> args;
  std::set<int> codes;                    // allowed exit codes
  std::vector<std::string> say;           // fragments a refusal must contain
  std::vector<std::string> absent;        // paths (relative) that must not exist afterwards
  std::vector<std::string> say_any = {};  // a refusal must contain at least one of these
  std::vector<std::string> unsaid = {};   // a refusal must contain none of these
};

// gtest prints a failing case by its name, not its bytes.
void PrintTo(const Case& c, std::ostream* os) {
  *os << c.name;
}

std::string gtest_name(std::string s) {
  for (char& c : s)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return s;
}

// Every file of a directory tree with its bytes.
std::map<std::string, std::string> snapshot(const fs::path& dir) {
  std::map<std::string, std::string> files;
  std::error_code ec;  // a loop of symbolic links is no regular file
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file(ec) && e.path().filename().string().rfind(".hostile_", 0) != 0 &&
        !is_atomic_write_temp(e.path().filename().string()))  // a stale one may be cleaned
      files[fs::relative(e.path(), dir).string()] = slurp(e.path());
  return files;
}

bool mentions_non_finite(const std::string& text) {
  static const std::regex bad(R"((^|[^A-Za-z_])(-?nan|-?inf|infinity)([^A-Za-z_]|$))",
                              std::regex::icase);
  return std::regex_search(text, bad);
}

class Hostile : public ::testing::TestWithParam<Case> {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("csympnet_hostile_" + std::to_string(::getpid()) + "_" +
            gtest_name(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  fs::path dir_;
};

TEST_P(Hostile, EndsCleanlyAndLosesNothing) {
  const Case& c = GetParam();
  if (c.setup) c.setup(dir_);
  const std::map<std::string, std::string> before = snapshot(dir_);
  const Outcome r = spawn(c.args, dir_);
  SCOPED_TRACE("args: " + ::testing::PrintToString(c.args) + "\nstderr: " + r.err);
  ASSERT_FALSE(r.hung) << "no exit within " << kLimitSeconds << " s";
  ASSERT_FALSE(r.signalled) << "exit code " << r.code;
  EXPECT_TRUE(c.codes.count(r.code)) << "exit code " << r.code;
  EXPECT_EQ(r.err.find('\0'), std::string::npos) << "a NUL byte in the message";
  EXPECT_EQ(r.err.find("internal error"), std::string::npos);
  if (r.code == 1) {
    EXPECT_EQ(r.err.rfind("csympnet: error: ", 0), 0u);
    EXPECT_NE(r.err.find("expected"), std::string::npos) << "does not say what was expected";
  }
  if (r.code == 2) {
    EXPECT_FALSE(r.err.empty());
    EXPECT_NE(r.err.find("expected"), std::string::npos) << "does not say what was expected";
  }
  if (r.code != 0 && r.code != 4) {
    for (const std::string& s : c.say)
      EXPECT_NE(r.err.find(s), std::string::npos) << "does not name '" << s << "'";
    for (const std::string& s : c.unsaid)
      EXPECT_EQ(r.err.find(s), std::string::npos) << "names '" << s << "'";
    if (!c.say_any.empty()) {
      bool named = false;
      for (const std::string& s : c.say_any) named = named || r.err.find(s) != std::string::npos;
      EXPECT_TRUE(named) << "names none of " << ::testing::PrintToString(c.say_any);
    }
  }
  if (r.code == 0 || r.code == 4) {
    EXPECT_FALSE(mentions_non_finite(r.out)) << "stdout: " << r.out;
    std::error_code ec;
    for (const auto& e : fs::recursive_directory_iterator(dir_)) {
      if (e.is_regular_file(ec) && e.path().extension() == ".json") {
        EXPECT_FALSE(mentions_non_finite(slurp(e.path()))) << e.path();
      }
    }
  }
  // Nothing lost: every file the user had is still there with the same bytes (a successful
  // command may add files, never change or remove one).
  const std::map<std::string, std::string> after = snapshot(dir_);
  for (const auto& [name, bytes] : before) {
    const auto it = after.find(name);
    ASSERT_NE(it, after.end()) << name << " was removed";
    EXPECT_EQ(it->second, bytes) << name << " was changed";
  }
  for (const std::string& p : c.absent) EXPECT_FALSE(fs::exists(dir_ / p)) << p << " exists";
  EXPECT_FALSE(fs::exists(dir_ / "INJECTED")) << "a payload ran";
}

std::string case_name(const ::testing::TestParamInfo<Case>& info) {
  return gtest_name(info.param.name) + "_" + std::to_string(info.index);
}

// ----- class 1: CSV files ----------------------------------------------------------------------

// Commands that read a CSV, in their fastest form (a few epochs, no second stage).
std::vector<std::vector<std::string>> csv_commands(const std::string& file) {
  return {
      {"train", "--data", file, "--epochs", "2", "-q", "--out", "out"},
      {"fit", file, "--recipe", "classic", "--epochs", "2", "--refine", "none", "--bootstrap", "0",
       "-q", "--out", "out"},
  };
}

// Replaces field `col` of data line `line` (1-based, the header is line 1) of a CSV text.
std::string with_field(const std::string& text, int line, int col, const std::string& value) {
  std::vector<std::string> lines;
  std::stringstream s(text);
  for (std::string l; std::getline(s, l);) lines.push_back(l);
  std::vector<std::string> fields;
  std::stringstream f(lines[static_cast<std::size_t>(line - 1)]);
  for (std::string x; std::getline(f, x, ',');) fields.push_back(x);
  fields[static_cast<std::size_t>(col)] = value;
  std::string joined;
  for (std::size_t i = 0; i < fields.size(); ++i) joined += (i ? "," : "") + fields[i];
  lines[static_cast<std::size_t>(line - 1)] = joined;
  std::string out;
  for (const auto& l : lines) out += l + "\n";
  return out;
}

std::vector<Case> csv_cases() {
  std::vector<Case> cases;
  const auto add = [&](const std::string& name, const std::string& text, std::set<int> codes,
                       std::vector<std::string> say) {
    for (const auto& cmd : csv_commands("d.csv")) {
      say.insert(say.begin(), "d.csv");
      cases.push_back(
          {"csv_" + cmd[0] + "_" + name,
           [text](const fs::path& d) { write_file(d / "d.csv", text); }, cmd, codes, say,
           codes.count(0) ? std::vector<std::string>{} : std::vector<std::string>{"out"}});
      say.erase(say.begin());
    }
  };
  const std::string pairs = base_pairs(), trajs = base_trajectories();
  // Values no reader may accept, in a state column and in the step column.
  const std::vector<std::pair<std::string, std::string>> bad_values = {
      {"empty", ""},
      {"space", " "},
      {"nan", "nan"},
      {"NaN", "NaN"},
      {"minus_nan", "-nan"},
      {"inf", "inf"},
      {"minus_Infinity", "-Infinity"},
      {"overflow", "1e999"},
      {"underflow", "1e-999"},
      {"hexfloat", "0x1p3"},
      {"decimal_comma", "1;5"},
      {"two_points", "1.2.3"},
      {"double_minus", "--1"},
      {"plus_minus", "+-1"},
      {"bare_exponent", "1e"},
      {"exponent_only", "e5"},
      {"point", "."},
      {"minus", "-"},
      {"underscore", "1_000"},
      {"quoted", "\"0.5\""},
      {"single_quoted", "'0.5'"},
      {"word", "TRUE"},
      {"null", "null"},
      {"printf", "%s%n"},
      {"subshell", "$(touch INJECTED)"},
      {"backticks", "`touch INJECTED`"},
      {"arabic_digit", "\xD9\xA3"},
      {"huge_digits", std::string(400, '9')},
      {"near_dbl_max", "1.7e308"},
      {"too_large_to_square", "1e151"},
  };
  for (const auto& [name, v] : bad_values) {
    add("q_" + name, with_field(pairs, 3, 1, v), {1}, {":3:"});
    add("traj_p_" + name, with_field(trajs, 4, 3, v), {1}, {":4:"});
  }
  const std::vector<std::pair<std::string, std::string>> bad_steps = {
      {"zero", "0"},  {"minus_zero", "-0"}, {"negative", "-0.1"}, {"subnormal", "1e-320"},
      {"nan", "nan"}, {"inf", "inf"},       {"huge", "1e300"}};
  for (const auto& [name, v] : bad_steps)
    add("h_" + name, with_field(pairs, 2, 0, v), {1}, {"d.csv"});
  // Steps so small or states so tiny that nothing can be identified: refused or "not
  // identified", never a confident number.
  cases.push_back({"csv_fit_h_tiny",
                   [t = with_field(with_field(pairs, 2, 0, "1e-15"), 3, 0, "1e-16")](
                       const fs::path& d) { write_file(d / "d.csv", t); },
                   csv_commands("d.csv")[1],
                   {0, 1, 4},
                   {},
                   {}});
  // Structure.
  const std::string body = pairs.substr(pairs.find('\n') + 1);
  const std::vector<std::pair<std::string, std::string>> bad_texts = {
      {"upper_header", "H,Q1,P1,NEXT_Q1,NEXT_P1\n" + body},
      {"duplicate_column", "h,q1,q1,next_q1,next_p1\n" + body},
      {"missing_column", "h,q1,p1,next_q1\n" + body},
      {"trailing_comma", "h,q1,p1,next_q1,next_p1,\n" + body},
      {"tabs", "h\tq1\tp1\tnext_q1\tnext_p1\n" + body},
      {"semicolons", "h;q1;p1;next_q1;next_p1\n" + body},
      {"lone_cr", "h,q1,p1,next_q1,next_p1\r" + body},
      {"nul_in_header", std::string("h,q1\0,p1,next_q1,next_p1\n", 25) + body},
      {"only_newlines", "\n\n\n"},
      {"empty", ""},
      {"header_only", "h,q1,p1,next_q1,next_p1\n"},
      {"blank_line_inside", "h,q1,p1,next_q1,next_p1\n" + body.substr(0, body.find('\n') + 1) +
                                "\n" + body.substr(body.find('\n') + 1)},
      {"long_line", "h,q1,p1,next_q1,next_p1\n" + std::string(2000000, '1') + "\n"},
      {"many_columns",
       [] {
         std::string h = "h";
         for (int k = 1; k <= 3000; ++k) h += ",q" + std::to_string(k);
         return h + "\n0.1\n";
       }()},
      {"odd_dimension", "h,q1,q2,p1,next_q1,next_q2,next_p1\n0.1,1,2,3,4,5,6\n"},
      {"binary", std::string("\x89PNG\r\n\x1a\n\0\0\0\rIHDR", 16)},
      {"utf16", std::string("\xFF\xFEh\0,\0q\0", 8)},
      {"traj_time_backwards", "t,q1,p1\n0,1,0\n0.2,0.9,0.1\n0.1,0.8,0.2\n"},
      {"traj_repeated_time", "t,q1,p1\n0,1,0\n0.1,0.9,0.1\n0.1,0.8,0.2\n"},
      {"traj_single_rows", "traj,t,q1,p1\n0,0,1,0\n1,0,1,0\n"},
      {"traj_id_float", "traj,t,q1,p1\n0,0,1,0\n0.5,0.1,1,0\n"},
      {"traj_id_huge", "traj,t,q1,p1\n99999999999999999999999,0,1,0\n"},
      {"traj_split_ids", "traj,t,q1,p1\n0,0,1,0\n0,0.1,1,0\n1,0,1,0\n1,0.1,1,0\n0,0.2,1,0\n"},
      {"traj_time_overflow", "t,q1,p1\n-1.7e308,1,0\n1.7e308,1,0\n"},
      {"short_row", "h,q1,p1,next_q1,next_p1\n0.1,1,0,1\n"},
      {"long_row", "h,q1,p1,next_q1,next_p1\n0.1,1,0,1,0,7\n"},
  };
  for (const auto& [name, text] : bad_texts) add(name, text, {1}, {});
  // Inputs that are unusual but valid: accepted, with finite results.
  add("crlf", std::regex_replace(pairs, std::regex("\n"), "\r\n"), {0}, {});
  add("trailing_blank_lines", pairs + "\n\n", {0}, {});
  add("no_final_newline", pairs.substr(0, pairs.size() - 1), {0}, {});
  add("trajectories_no_id",
      "t,q1,p1\n" +
          [] {
            std::string s;
            for (int i = 0; i < 20; ++i)
              s += std::to_string(0.1 * i) + "," + std::to_string(std::cos(0.1 * i)) + "," +
                   std::to_string(-std::sin(0.1 * i)) + "\n";
            return s;
          }(),
      {0}, {});
  add("subnormal_state", with_field(pairs, 3, 1, "4.9e-324"), {0}, {});
  // Lenient but unambiguous: a byte-order mark (spreadsheet exports), spaces after commas in
  // the header, a leading tab before a number.
  add("bom", "\xEF\xBB\xBF" + pairs, {0}, {});
  add("spaced_header", "h, q1, p1, next_q1, next_p1\n" + body, {0}, {});
  add("tab_before_number", with_field(pairs, 3, 1, "\t0.5"), {0}, {});
  return cases;
}

// ----- class 2: model files --------------------------------------------------------------------

std::vector<Case> model_cases() {
  std::vector<Case> cases;
  // A mutation of the base model's document (re-signed, so the checks behind the checksum
  // are reached too), or of its text.
  using DocEdit = std::function<void(json&)>;
  using TextEdit = std::function<std::string(const std::string&)>;
  const auto commands = [](const std::string& file) {
    return std::vector<std::vector<std::string>>{
        {"rollout", "--model", file, "--z0", "0.1,0.2", "--h", "0.1", "--steps", "3"},
        {"evaluate", "--model", file, "--preset", "s1", "--data", "t.csv"},
    };
  };
  const auto add_text = [&](const std::string& name, TextEdit edit, std::set<int> codes) {
    for (const auto& cmd : commands("m.json"))
      cases.push_back(
          {"model_" + cmd[0] + "_" + name,
           [edit](const fs::path& d) {
             write_file(d / "m.json", edit(base_model()));
             write_file(d / "t.csv", base_trajectories());
           },
           cmd,
           codes,
           codes.count(0) ? std::vector<std::string>{} : std::vector<std::string>{"m.json"},
           {}});
  };
  // Edits of the architecture are re-signed after the edit, so they reach the checks behind
  // the checksum; edits of the file's own fields (version, checksum, params) are made after
  // signing, as a user editing the file would.
  const auto add_doc = [&](const std::string& name, DocEdit edit, std::set<int> codes,
                           bool resign_after = true) {
    add_text(
        name,
        [edit, resign_after](const std::string& text) {
          json doc = json::parse(text);
          if (!resign_after) doc = json::parse(resigned(doc));
          edit(doc);
          return resign_after ? resigned(doc) : doc.dump(1);
        },
        codes);
  };
  // Every key of the document and of its "model" part: removed, or replaced by each JSON type.
  const std::vector<std::pair<std::string, json>> replacements = {
      {"null", nullptr}, {"string", "x"}, {"negative", -1},         {"zero", 0},
      {"fraction", 2.5}, {"huge", 1e300}, {"array", json::array()}, {"object", json::object()},
      {"true", true}};
  for (const std::string key : {"format", "version", "model", "params", "n_params", "checksum"}) {
    // n_params is redundant (the architecture gives the count): a file without it is read,
    // one whose count disagrees is refused.
    add_doc(
        "drop_" + key, [key](json& d) { d.erase(key); },
        key == "n_params" ? std::set<int>{0, 1} : std::set<int>{1}, false);
    for (const auto& [rn, v] : replacements)
      add_doc(
          key + "_" + rn, [key, v = v](json& d) { d[key] = v; }, {1}, false);
  }
  for (const std::string key : {"type", "d", "beta_init", "core"}) {
    add_doc(
        "drop_model_" + key, [key](json& d) { d["model"].erase(key); },
        key == "beta_init" ? std::set<int>{0, 1} : std::set<int>{1});
    for (const auto& [rn, v] : replacements) {
      // A beta_init of any finite nonzero value is a valid (if odd) model.
      const bool valid = key == "beta_init" && v.is_number() && v.get<double>() != 0.0;
      add_doc(
          "model_" + key + "_" + rn, [key, v = v](json& d) { d["model"][key] = v; },
          valid ? std::set<int>{0} : std::set<int>{1});
    }
  }
  for (const std::string key : {"layers", "sublayers", "type"})
    for (const auto& [rn, v] : replacements)
      add_doc("core_" + key + "_" + rn, [key, v = v](json& d) { d["model"]["core"][key] = v; },
              {1});
  add_doc(
      "version_1", [](json& d) { d["version"] = 1; }, {1}, false);
  add_doc(
      "version_3", [](json& d) { d["version"] = 3; }, {1}, false);
  add_doc("params_short", [](json& d) { d["params"].erase(d["params"].size() - 1); }, {1});
  add_doc("params_long", [](json& d) { d["params"].push_back(0.5); }, {1});
  add_doc(
      "param_string", [](json& d) { d["params"][0] = "0.5"; }, {1}, false);
  add_doc(
      "param_null", [](json& d) { d["params"][0] = nullptr; }, {1}, false);
  add_doc("param_huge", [](json& d) { d["params"][0] = 1e300; }, {0, 1});
  add_doc(
      "unknown_key", [](json& d) { d["extra"] = 1; }, {0, 1}, false);
  add_doc("unknown_model_key", [](json& d) { d["model"]["extra"] = 1; }, {1});
  add_doc("d_mismatch", [](json& d) { d["model"]["d"] = 2; }, {1});
  add_doc(
      "edited_param_unsigned",
      [](json& d) {
        const std::string sum = d["checksum"];
        d["params"][0] = d["params"][0].get<double>() + 1.0;
        d["checksum"] = sum;  // kept: the edit must be detected
      },
      {1}, false);
  for (const double frac : {0.0, 0.1, 0.5, 0.9, 0.999})
    add_text("truncated_" + std::to_string(static_cast<int>(frac * 1000)),
             [frac](const std::string& t) {
               return t.substr(0, static_cast<std::size_t>(frac * static_cast<double>(t.size())));
             },
             {1});
  // Library models (the base model has an LA core): hostile terms and masses, re-signed.
  // A name of 50,000 digits overflowed the stack (exit 139), 20 digits escaped as
  // "internal error: stol" (exit 3); a zero or negative inverse mass rolled out silently.
  const auto add_library = [&](const std::string& name, DocEdit edit, std::set<int> codes,
                               std::vector<std::string> say) {
    if (!codes.count(0)) say.insert(say.begin(), "m.json");
    for (const auto& cmd : commands("m.json"))
      cases.push_back({"model_" + cmd[0] + "_library_" + name,
                       [edit](const fs::path& d) {
                         json doc = json::parse(library_model());
                         edit(doc);
                         write_file(d / "m.json", resigned(doc));
                         write_file(d / "t.csv", base_trajectories());
                       },
                       cmd,
                       codes,
                       say,
                       {}});
  };
  add_library("valid", [](json&) {}, {0}, {});
  add_library(
      "term_of_50000_digits",
      [](json& d) { d["model"]["core"]["terms"][0] = "q" + std::string(50000, '1'); }, {1},
      {"m.json: model spec.core.terms: term 'q1111111111", "\u2026': coordinate", "out of range"});
  add_library("term_index_of_20_digits",
              [](json& d) { d["model"]["core"]["terms"][1] = "q99999999999999999999^4"; }, {1},
              {"term 'q99999999999999999999^4': coordinate 99999999999999999999 out of range",
               "I, J in 1..1"});
  add_library("term_not_a_string",
              [](json& d) { d["model"]["core"]["terms"][0] = json::array({5}); }, {1},
              {"model spec.core.terms[0] = [5], expected a term name"});
  for (const auto& [label, w] : std::vector<std::pair<std::string, double>>{
           {"zero", 0.0}, {"negative", -1.0}, {"negative_zero", -0.0}, {"tiny_negative", -1e-300}})
    add_library(
        "inverse_mass_" + label, [w = w](json& d) { d["params"][0] = w; }, {1},
        {"m.json: params[0] = ", " is W[1,1] (the inverse mass W = M^-1 of core 'mass': \"full\")",
         "expected a positive inverse mass"});
  add_text("garbage_after", [](const std::string& t) { return t + "}}garbage"; }, {1});
  add_text("deep_nesting",
           [](const std::string&) { return std::string(100000, '[') + std::string(100000, ']'); },
           {1});
  add_text("binary", [](const std::string&) { return std::string("\x1f\x8b\x08\0\0\0", 6); }, {1});
  add_text("number_overflow",
           [](const std::string& t) {
             return std::regex_replace(t, std::regex("\"version\": ?2"), "\"version\": 1e999");
           },
           {1});
  return cases;
}

// ----- class 3: options ------------------------------------------------------------------------

std::vector<Case> option_cases() {
  std::vector<Case> cases;
  const auto setup = [](const fs::path& d) {
    write_file(d / "d.csv", base_pairs());
    write_file(d / "t.csv", base_trajectories());
    write_file(d / "m.json", base_model());
  };
  // The command each option is tried on, with everything else valid and fast.
  const std::map<std::string, std::vector<std::string>> base = {
      {"train", {"train", "--data", "d.csv", "--epochs", "2", "-q", "--out", "out"}},
      {"fit",
       {"fit", "d.csv", "--recipe", "classic", "--refine", "none", "--bootstrap", "0", "--epochs",
        "2", "-q", "--out", "out"}},
      {"fit_identify", {"fit", "d.csv", "-q", "--out", "out"}},
      {"run", {"run", "--preset", "s1", "--epochs", "2", "-q", "--out", "out"}},
      {"generate", {"generate", "--preset", "s1", "--n", "2", "--out", "g.csv"}},
      {"rollout",
       {"rollout", "--model", "m.json", "--z0", "0.1,0.2", "--h", "0.1", "--steps", "2"}},
      {"describe", {"describe", "--preset", "s1"}},
      {"evaluate", {"evaluate", "--model", "m.json", "--preset", "s1", "--data", "t.csv"}},
  };
  const auto add = [&](const std::string& cmd, const std::string& opt,
                       const std::vector<std::string>& values) {
    for (const std::string& v : values) {
      std::vector<std::string> args = base.at(cmd);
      // Replace the option's value when the base command already sets it.
      bool replaced = false;
      for (std::size_t i = 0; i + 1 < args.size(); ++i)
        if (args[i] == opt) {
          args[i + 1] = v;
          replaced = true;
        }
      if (!replaced) {
        args.push_back(opt);
        args.push_back(v);
      }
      std::vector<std::string> named{opt};
      if (!v.empty()) named.push_back(v);
      cases.push_back(
          {"opt_" + cmd + opt + "_" + v, setup, args, {1, 2}, {}, {"out", "g.csv"}, named});
    }
  };
  const std::vector<std::string> not_numbers = {"",   "abc",  "nan", "inf", "-inf", "1e400",
                                                "0x", "1..2", "1,5", "--",  "7abc"};
  std::vector<std::string> not_whole = not_numbers;
  for (const char* v : {"1.5", "-1", "1e3", "99999999999999999999999", "+-3", "\xD9\xA3"})
    not_whole.push_back(v);
  const auto with = [](std::vector<std::string> a, std::vector<std::string> b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
  };
  for (const std::string cmd : {"train", "fit"}) {
    add(cmd, "--epochs", with(not_whole, {"0"}));
    add(cmd, "--val-every", with(not_whole, {"0"}));
    add(cmd, "--seed", with(not_whole, {"18446744073709551616"}));
    add(cmd, "--bootstrap", with(not_whole, {"5"}));
    add(cmd, "--refine-iterations", with(not_whole, {"0"}));
    add(cmd, "--threads", with(not_whole, {"0", "100000"}));
    add(cmd, "--chunk-pairs", with(not_whole, {"1000000001"}));
    add(cmd, "--batch-size", with(not_whole, {"1000000000001"}));
    add(cmd, "--lr", with(not_numbers, {"0", "-1", "20", "1e-300"}));
    add(cmd, "--val-fraction", with(not_numbers, {"0", "1", "-0.5", "2"}));
    add(cmd, "--beta-init", with(not_numbers, {"0", "-0"}));
    add(cmd, "--model", {"", "CSYMPNET", "csympnet ", "dhnn", "$(touch INJECTED)"});
    add(cmd, "--core",
        {"", "la", "la:", "la:0:10", "la:-1:10", "la:1:0", "g:1:1.5", "la:4:10:9", "LA:4:10",
         "x:1:2", "la:99999999999999999999:1", "la:100000:100000", "g:100000:100000"});
    add(cmd, "--refine", {"", "LM", "newton"});
    add(cmd, "--refine-solver", {"", "qr", "$(id)"});
    add(cmd, "--lr-schedule", {"", "linear"});
    add(cmd, "--val", {"missing.csv", "", "/dev/null", "m.json"});
  }
  // With no warm start, a beta_init that shrinks every state to 0 in one step is refused (fit
  // starts from the warm start's estimate, so there it is unused).
  add("train", "--beta-init", {"1e300", "-1e4"});
  add("fit_identify", "--level", with(not_numbers, {"0.1", "1", "0.99999"}));
  add("fit_identify", "--window", with(not_whole, {"65"}));
  add("fit_identify", "--blocks", with(not_whole, {"2", "10001"}));
  add("fit_identify", "--lm-iterations", with(not_whole, {"100001"}));
  add("fit", "--recipe", {"", "paper", "IDENTIFY"});
  add("fit_identify", "--loss", {"", "mse2"});
  add("fit_identify", "--dof-scales", {"0", "-1", "a", "nan", "1,2,3", ""});
  add("run", "--preset", {"", "s4", "S1", "../s1"});
  add("run", "--sigma", with(not_numbers, {"-1", "11"}));
  add("run", "--gamma", with(not_numbers, {"-1"}));
  add("run", "--omega", with(not_numbers, {"0"}));
  add("run", "--d", with(not_whole, {"0", "100001"}));
  add("run", "--model", {"", "pinn", "dhnn3"});
  add("generate", "--n", with(not_whole, {"0", "100000000"}));
  add("generate", "--split", {"", "validation", "TEST"});
  add("rollout", "--z0", {"", "1", "1,2,3", "a,b", "nan,0", "1e400,0", ",", "1,,2"});
  add("rollout", "--h", with(not_numbers, {"0", "-0.1", "1e300", "1e-320"}));
  add("rollout", "--steps", with(not_whole, {"0", "100000001"}));
  add("describe", "--model", {"", "x"});
  add("describe", "--d", with(not_whole, {"0"}));
  add("evaluate", "--data", {"missing.csv", "d.csv", "m.json", ""});
  return cases;
}

// ----- class 4: output targets -----------------------------------------------------------------

std::vector<Case> output_cases() {
  std::vector<Case> cases;
  const auto data = [](const fs::path& d) { write_file(d / "d.csv", base_pairs()); };
  const auto train_to = [](const std::string& out, std::vector<std::string> extra = {}) {
    std::vector<std::string> a = {"train", "--data", "d.csv", "--epochs", "2", "-q", "--out", out};
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  // Names a shell would act on: written literally, and no payload runs.
  for (const std::string& name : std::vector<std::string>{
           "bob's run", "a b", "x';touch INJECTED;'", "$(touch INJECTED)", "`touch INJECTED`",
           "a;touch INJECTED", "a|touch INJECTED", "a&&touch INJECTED", "line\nbreak", "*", "-",
           "--force", "..x", "caf\xC3\xA9", std::string("tab\there")}) {
    // A name that starts with '-' may be read as an option: a usage error is fine too.
    const std::set<int> codes = name[0] == '-' ? std::set<int>{0, 2} : std::set<int>{0};
    cases.push_back({"out_name_" + name, data, train_to(name), codes, {}, {}});
    cases.push_back({"generate_name_" + name,
                     nullptr,
                     {"generate", "--preset", "s1", "--n", "2", "--out", name},
                     codes,
                     {},
                     {}});
  }
  // Targets that cannot be written: refused with the path, nothing of the user's changed.
  const auto file_there = [data](const fs::path& d) {
    data(d);
    write_file(d / "f", "the user's file\n");
  };
  const auto user_dir = [data](const fs::path& d) {
    data(d);
    write_file(d / "res" / "notes.txt", "the user's notes\n");
    write_file(d / "res" / "report.json", "{\"mine\": true}\n");
  };
  const std::vector<
      std::tuple<std::string, std::function<void(const fs::path&)>, std::string, std::set<int>>>
      targets = {
          {"regular_file", file_there, "f", {1}},
          {"under_a_file", file_there, "f/sub", {1}},
          {"empty", data, "", {1, 2}},
          {"dev_null", data, "/dev/null", {1}},
          {"proc", data, "/proc/self/x", {1}},
          {"long_component", data, std::string(300, 'a'), {1}},
          {"long_path",
           data,
           [] {
             std::string p;
             for (int i = 0; i < 40; ++i) p.append(120, 'b').append(1, '/');
             return p;
           }(),
           {1}},
          {"user_dir_no_force", user_dir, "res", {1}},
          {"dangling_symlink",
           [data](const fs::path& d) {
             data(d);
             fs::create_symlink(d / "nowhere" / "x", d / "link");
           },
           "link",
           {0, 1}},
      };
  for (const auto& [name, setup, out, codes] : targets) {
    cases.push_back({"train_out_" + name,
                     setup,
                     train_to(out),
                     codes,
                     out.empty() ? std::vector<std::string>{"--out"} : std::vector<std::string>{},
                     {}});
    cases.push_back({"run_out_" + name,
                     setup,
                     {"run", "--preset", "s1", "--epochs", "2", "-q", "--out", out},
                     codes,
                     out.empty() ? std::vector<std::string>{"--out"} : std::vector<std::string>{},
                     {}});
  }
  // --force writes its own files and keeps the user's others.
  cases.push_back({"user_dir_force_keeps_notes",
                   [user_dir](const fs::path& d) {
                     user_dir(d);
                     fs::remove(d / "res" / "report.json");
                   },
                   train_to("res", {"--force"}),
                   {0},
                   {},
                   {}});
  // generate never overwrites an existing file without --force.
  cases.push_back({"generate_over_user_file",
                   file_there,
                   {"generate", "--preset", "s1", "--n", "2", "--out", "f"},
                   {1},
                   {"f"},
                   {}});
  // A stale temporary file of a killed writer does not make a directory count as non-empty.
  cases.push_back({"stale_temp_only",
                   [data](const fs::path& d) {
                     data(d);
                     // A dead writer's: the pid of a child that has exited (a fixed number
                     // could be a running process, whose temporary counts as content).
                     const pid_t dead = ::fork();
                     if (dead == 0) ::_exit(0);
                     ::waitpid(dead, nullptr, 0);
                     write_file(d / "res" / (".report.json.tmp." + std::to_string(dead) + ".0.1"),
                                "partial");
                   },
                   train_to("res"),
                   {0},
                   {},
                   {}});
  return cases;
}

// ----- class 5: special files, standard streams, signals, temporaries, commits, parser memory --
//
// Cases that need more than an argument vector: a FIFO or device where a file goes, standard
// output on a full device or closed, a signal during a long stage, a memory limit, a half-done
// commit. Each is its own test (named Hostile*, so it runs in cli.hostile_suite).

struct SpawnOptions {
  std::string stdout_path;  // empty: a file in the case's directory
  bool close_stdout = false;
  // Standard output a pipe whose reader has gone (`| head` once head has exited), with
  // SIGPIPE ignored as some shells and Python's subprocess leave it: the write fails, EPIPE.
  bool broken_pipe = false;
  double signal_after = -1;  // seconds; < 0: none
  int signal = SIGINT;
  long address_space_kb = 0;  // RLIMIT_AS, 0: unlimited
};

struct Timed : Outcome {
  double after_signal = -1;  // seconds from the signal to the exit
};

Timed spawn_with(const std::vector<std::string>& args, const fs::path& cwd, const SpawnOptions& o) {
  const fs::path out = o.stdout_path.empty() ? cwd / ".hostile_stdout" : fs::path(o.stdout_path);
  const fs::path err = cwd / ".hostile_stderr";
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (::chdir(cwd.c_str()) != 0) ::_exit(127);
    const int in = ::open("/dev/null", O_RDONLY);
    const int e = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (in < 0 || e < 0) ::_exit(127);
    ::dup2(in, 0);
    ::dup2(e, 2);
    if (o.close_stdout) {
      ::close(1);
    } else if (o.broken_pipe) {
      int fds[2];
      if (::pipe(fds) != 0) ::_exit(127);
      ::close(fds[0]);
      ::dup2(fds[1], 1);
      ::close(fds[1]);
      ::signal(SIGPIPE, SIG_IGN);
    } else {
      const int fd = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd < 0) ::_exit(127);
      ::dup2(fd, 1);
      ::close(fd);
    }
    ::close(in);
    ::close(e);
    if (o.address_space_kb > 0) {
      const rlim_t bytes = static_cast<rlim_t>(o.address_space_kb) * 1024;
      const struct rlimit lim { bytes, bytes };
      ::setrlimit(RLIMIT_AS, &lim);
    }
    std::vector<std::string> all{CSYMPNET_CLI_PATH};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv(CSYMPNET_CLI_PATH, argv.data());
    ::_exit(127);
  }
  Timed r;
  int status = 0;
  const auto start = std::chrono::steady_clock::now();
  std::chrono::steady_clock::time_point signalled_at{};
  bool sent = false;
  for (;;) {
    const pid_t done = ::waitpid(pid, &status, WNOHANG);
    const auto now = std::chrono::steady_clock::now();
    if (done == pid) {
      if (sent) r.after_signal = std::chrono::duration<double>(now - signalled_at).count();
      break;
    }
    const double elapsed = std::chrono::duration<double>(now - start).count();
    if (!sent && o.signal_after >= 0 && elapsed >= o.signal_after) {
      ::kill(pid, o.signal);
      signalled_at = now;
      sent = true;
    }
    if (elapsed > kLimitSeconds) {
      r.hung = true;
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  r.signalled = WIFSIGNALED(status);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  if (!o.close_stdout && o.stdout_path.empty()) r.out = slurp(out);
  r.err = slurp(err);
  std::error_code ec;
  if (o.stdout_path.empty()) fs::remove(out, ec);
  fs::remove(err, ec);
  return r;
}

class HostileFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("csympnet_hostile_files_" + std::to_string(::getpid()) + "_" +
            gtest_name(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    write_file(dir_ / "d.csv", base_pairs());
    write_file(dir_ / "t.csv", base_trajectories());
    write_file(dir_ / "m.json", base_model());
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  // No temporary and no journal left anywhere under the case's directory.
  void expect_no_leftovers() const {
    for (const auto& e : fs::recursive_directory_iterator(dir_)) {
      const std::string name = e.path().filename().string();
      EXPECT_FALSE(is_atomic_write_temp(name)) << e.path() << " left behind";
      EXPECT_NE(name, ".csympnet.commit") << e.path() << " left behind";
    }
  }
  fs::path dir_;
};

void expect_refusal(const Outcome& r, const std::vector<std::string>& say) {
  EXPECT_FALSE(r.hung);
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_EQ(r.err.rfind("csympnet: error: ", 0), 0u) << r.err;
  EXPECT_NE(r.err.find("expected"), std::string::npos) << r.err;
  for (const std::string& s : say) EXPECT_NE(r.err.find(s), std::string::npos) << r.err;
}

bool names_a_fifo(const fs::path& p) {
  std::error_code ec;
  return fs::symlink_status(p, ec).type() == fs::file_type::fifo;
}

// An atomic rename would turn a FIFO, a device or a symbolic link into a regular file: each is
// refused by name and stays what it was.
TEST_F(HostileFiles, GenerateRefusesAFifoADeviceAndASymlinkAsItsOutput) {
  ASSERT_EQ(::mkfifo((dir_ / "fifo").c_str(), 0644), 0);
  Timed r = spawn_with(
      {"generate", "--preset", "s1", "--split", "train", "--n", "2", "--out", "fifo", "--force"},
      dir_, {});
  expect_refusal(r, {"'fifo'", "FIFO", "regular file"});
  EXPECT_TRUE(names_a_fifo(dir_ / "fifo"));
  fs::create_symlink("d.csv", dir_ / "link");
  r = spawn_with({"generate", "--preset", "s1", "--n", "2", "--out", "link", "--force"}, dir_, {});
  expect_refusal(r, {"'link'", "symbolic link"});
  EXPECT_TRUE(fs::is_symlink(dir_ / "link"));
  EXPECT_EQ(slurp(dir_ / "d.csv"), base_pairs());
  if (::geteuid() == 0 && ::mknod((dir_ / "null").c_str(), S_IFCHR | 0666, makedev(1, 3)) == 0) {
    r = spawn_with({"generate", "--preset", "s1", "--n", "2", "--out", "null", "--force"}, dir_,
                   {});
    expect_refusal(r, {"'null'", "character device"});
    EXPECT_EQ(fs::symlink_status(dir_ / "null").type(), fs::file_type::character);
  }
  expect_no_leftovers();
}

// A result file of an output directory that is a FIFO or a directory: the whole set is
// refused before anything is written, and the earlier result stays whole.
TEST_F(HostileFiles, ASpecialFileInAResultSetIsRefusedBeforeAnythingIsWritten) {
  const std::vector<std::string> train = {"train", "--data", "d.csv", "--epochs", "2",
                                          "-q",    "--out",  "res",   "--force"};
  ASSERT_EQ(spawn_with(train, dir_, {}).code, 0);
  const std::string report = slurp(dir_ / "res" / "report.json");
  fs::remove(dir_ / "res" / "model.json");
  ASSERT_EQ(::mkfifo((dir_ / "res" / "model.json").c_str(), 0644), 0);
  Timed r = spawn_with(train, dir_, {});
  expect_refusal(r, {"model.json", "FIFO"});
  EXPECT_TRUE(names_a_fifo(dir_ / "res" / "model.json"));
  EXPECT_EQ(slurp(dir_ / "res" / "report.json"), report);
  fs::remove(dir_ / "res" / "model.json");
  fs::create_directory(dir_ / "res" / "model.json");
  r = spawn_with(train, dir_, {});
  expect_refusal(r, {"model.json", "directory"});
  EXPECT_EQ(slurp(dir_ / "res" / "report.json"), report);
  expect_no_leftovers();
}

// A commit a killed writer left, whose target became a directory: the roll-forward says so
// and keeps its journal (it used to ignore the failed rename and delete the journal).
TEST_F(HostileFiles, ARollForwardThatCannotRenameKeepsItsJournalAndSaysSo) {
  fs::create_directories(dir_ / "res" / "model.json");
  const std::string tmp = ".model.json.tmp.1.0.1";  // pid 1: not the test's to remove
  write_file(dir_ / "res" / tmp, "{}\n");
  write_file(dir_ / "res" / ".csympnet.commit", tmp + "\tmodel.json\n");
  const std::vector<std::string> train = {"train", "--data", "d.csv", "--epochs", "2",
                                          "-q",    "--out",  "res",   "--force"};
  for (int attempt = 0; attempt < 2; ++attempt) {
    const Timed r = spawn_with(train, dir_, {});
    expect_refusal(r, {"model.json", ".csympnet.commit", "is kept"});
    EXPECT_TRUE(fs::exists(dir_ / "res" / ".csympnet.commit"));
    EXPECT_TRUE(fs::exists(dir_ / "res" / tmp));
    EXPECT_FALSE(fs::exists(dir_ / "res" / "report.json"));
  }
  // Once the directory is moved away, the next command completes the old set, then writes.
  fs::remove_all(dir_ / "res" / "model.json");
  EXPECT_EQ(spawn_with(train, dir_, {}).code, 0);
  EXPECT_FALSE(fs::exists(dir_ / "res" / ".csympnet.commit"));
  EXPECT_TRUE(fs::exists(dir_ / "res" / "report.json"));
  expect_no_leftovers();
}

// A name is no proof that csympnet made a file: a refused command removes nothing, and a
// temporary of a live writer is never touched.
TEST_F(HostileFiles, ARefusedCommandDeletesNoFileThatLooksLikeATemporary) {
  write_file(dir_ / "u" / ".notes.tmp.1.2.3", "precious\n");
  write_file(dir_ / "u" / "data.txt", "x\n");
  Timed r = spawn_with({"fit", "d.csv", "--recipe", "classic", "--epochs", "2", "--refine", "none",
                        "--bootstrap", "0", "-q", "--out", "u"},
                       dir_, {});
  expect_refusal(r, {"not empty"});
  EXPECT_EQ(slurp(dir_ / "u" / ".notes.tmp.1.2.3"), "precious\n");
  // A live writer's temporary (this test's pid) counts as content, and --force keeps it.
  const std::string live = ".model.json.tmp." + std::to_string(::getpid()) + ".0.1";
  write_file(dir_ / "v" / live, "in flight");
  r = spawn_with({"train", "--data", "d.csv", "--epochs", "2", "-q", "--out", "v"}, dir_, {});
  expect_refusal(r, {"not empty"});
  r = spawn_with({"train", "--data", "d.csv", "--epochs", "2", "-q", "--out", "v", "--force"}, dir_,
                 {});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(slurp(dir_ / "v" / live), "in flight");
  EXPECT_EQ(slurp(dir_ / "u" / ".notes.tmp.1.2.3"), "precious\n");
  // A dead writer's temporary does not count, and goes once the command writes there.
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  ::waitpid(child, nullptr, 0);
  const std::string dead = ".model.json.tmp." + std::to_string(child) + ".0.1";
  write_file(dir_ / "w" / dead, "partial");
  r = spawn_with({"train", "--data", "d.csv", "--epochs", "2", "-q", "--out", "w"}, dir_, {});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "w" / dead));
}

// Standard output that cannot be written: exit 1 with the system's reason, as coreutils do.
TEST_F(HostileFiles, WriteErrorsOnStandardOutputFailTheCommand) {
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full";
  const std::vector<std::vector<std::string>> commands = {
      {"rollout", "--model", "m.json", "--z0", "0.1,0.2", "--h", "0.1", "--steps", "3"},
      {"rollout", "--model", "m.json", "--z0", "0.1,0.2", "--h", "0.1", "--steps", "1000000"},
      {"evaluate", "--model", "m.json", "--preset", "s1", "--data", "t.csv"},
      {"describe", "--preset", "s1"},
      {"kernels"},
      {"--help"},
      {"rollout", "--help"},
  };
  for (const auto& args : commands) {
    SCOPED_TRACE(::testing::PrintToString(args));
    SpawnOptions full;
    full.stdout_path = "/dev/full";
    Timed r = spawn_with(args, dir_, full);
    expect_refusal(r, {"write error on standard output", "No space left on device"});
    SpawnOptions closed;
    closed.close_stdout = true;
    r = spawn_with(args, dir_, closed);
    expect_refusal(r, {"write error on standard output", "Bad file descriptor"});
    // A closed pipe is named as the system names it, not guessed to be a full disk.
    SpawnOptions pipe;
    pipe.broken_pipe = true;
    r = spawn_with(args, dir_, pipe);
    expect_refusal(r, {"write error on standard output: Broken pipe"});
    EXPECT_EQ(r.err.find("disk"), std::string::npos) << r.err;
  }
  // With standard output closed, what the command prints goes nowhere near its files (the
  // lock file or a result would otherwise get descriptor 1).
  SpawnOptions closed;
  closed.close_stdout = true;
  const Timed r = spawn_with(
      {"evaluate", "--model", "m.json", "--preset", "s1", "--data", "t.csv", "--out", "ev"}, dir_,
      closed);
  expect_refusal(r, {"write error on standard output"});
  const std::string report = slurp(dir_ / "ev" / "report.json");
  EXPECT_TRUE(json::accept(report)) << report;
}

// Long stages with no loop of their own stop within a second of SIGINT or SIGTERM: the
// adaptive integrators (a stiff reference, a vector-field model over a huge span), test-set
// generation, and reading a large file; the command then stops, it does not go on.
TEST_F(HostileFiles, LongStagesStopWithinASecondOfASignal) {
  // A vector-field model, for the dopri5 cases.
  ASSERT_EQ(
      spawn_with({"run", "--preset", "s1", "--model", "ode", "--epochs", "1", "-q", "--out", "ode"},
                 dir_, {})
          .code,
      0);
  {
    // Steps of 1e11: dopri5 integrates each whole span (up to its budget, seconds each).
    write_file(dir_ / "far.csv",
               "t,q1,p1\n0,0.1,0.2\n1e11,0.3,0.1\n2e11,-0.2,0.05\n3e11,0.1,-0.3\n");
  }
  const std::vector<std::vector<std::string>> stages = {
      {"generate", "--preset", "s1", "--split", "train", "--reference", "rk", "--omega", "1e10",
       "--n", "2", "--out", "g.csv"},
      {"generate", "--preset", "s2", "--split", "test", "--d", "100000", "--n", "1", "--out",
       "g2.csv"},
      {"run", "--preset", "s1", "--reference", "rk", "--omega", "1e10", "--epochs", "2", "-q",
       "--out", "r"},
      {"rollout", "--model", "ode/model.json", "--z0", "0.1,0.2", "--h", "1e12", "--steps", "2"},
      {"evaluate", "--model", "ode/model.json", "--data", "far.csv"},
      // A library map of 4,000,000 substeps of order 6 (seconds a step): rollout ran to the
      // end after SIGINT and exited 0.
      {"rollout", "--model", "slow.json", "--z0", "0.1,0.2", "--h", "0.1", "--steps", "100"},
      {"evaluate", "--model", "slow.json", "--data", "slow.csv"},
  };
  write_file(dir_ / "slow.json", library_model(4000000, 6));
  write_file(dir_ / "slow.csv", base_trajectories());
  for (const auto& args : stages)
    for (const int sig : {SIGINT, SIGTERM}) {
      SCOPED_TRACE(::testing::PrintToString(args) + " signal " + std::to_string(sig));
      SpawnOptions o;
      o.signal_after = 1.0;
      o.signal = sig;
      const Timed r = spawn_with(args, dir_, o);
      ASSERT_FALSE(r.hung);
      EXPECT_FALSE(r.signalled) << "killed by the signal instead of stopping";
      EXPECT_EQ(r.code, 128 + sig) << r.err;
      EXPECT_LT(r.after_signal, 1.0) << "took " << r.after_signal << " s to stop";
      EXPECT_NE(r.err.find("interrupted by"), std::string::npos) << r.err;
      EXPECT_FALSE(fs::exists(dir_ / "r")) << "an interrupted run left its directory";
      EXPECT_FALSE(fs::exists(dir_ / "g.csv"));
      EXPECT_FALSE(fs::exists(dir_ / "g2.csv"));
    }
}

TEST_F(HostileFiles, ReadingALargeFileStopsOnASignalAndTheCommandEnds) {
  // About 60 MB of pairs: seconds to read and parse on a busy machine.
  {
    std::ofstream f(dir_ / "big.csv", std::ios::binary);
    f << "h,q1,p1,next_q1,next_p1\n";
    const std::string row = "0.1,0.123456789012345,0.234567890123456,0.12345678901234,0.2345\n";
    for (int i = 0; i < 900000; ++i) f << row;
  }
  SpawnOptions o;
  o.signal_after = 0.3;
  const Timed r =
      spawn_with({"train", "--data", "big.csv", "--epochs", "100000", "--out", "o"}, dir_, o);
  ASSERT_FALSE(r.hung);
  EXPECT_EQ(r.code, 130) << r.err;
  EXPECT_LT(r.after_signal, 1.0);
  EXPECT_FALSE(fs::exists(dir_ / "o")) << "it went on to train";
  // A model file of 6 million parameters (about 80 MB): its parse polls too (SIGINT acted
  // after 43.6 s on a 100 MB model file).
  {
    json doc = json::parse(base_model());
    std::string text = doc.dump();
    std::string params = "\"params\":[";
    params.reserve(80000000);
    for (int i = 0; i < 6000000; ++i) params += i ? ",0.12345678901234" : "0.12345678901234";
    params += "],";
    text.insert(1, params);
    const std::size_t dup = text.rfind("\"params\"");  // the original key: renamed
    text.replace(dup, 8, "\"unused\"");
    write_file(dir_ / "big.json", text);
  }
  const Timed m = spawn_with(
      {"rollout", "--model", "big.json", "--z0", "0.1,0.2", "--h", "0.1", "--steps", "2"}, dir_, o);
  ASSERT_FALSE(m.hung);
  EXPECT_EQ(m.code, 130) << m.err;
  EXPECT_LT(m.after_signal, 1.0);
}

// A model file is bounded by what a model can hold, checked while it is parsed: a 30 MB file
// whose "meta" holds 15 million numbers is refused by name under a 600 MB memory limit
// (it took 20 times its size and died with std::bad_alloc), and so is deep nesting.
TEST_F(HostileFiles, ModelFilesBeyondWhatAModelHoldsAreRefusedUnderAMemoryLimit) {
  json doc = json::parse(base_model());
  {
    std::string text = doc.dump();
    const std::string big = "\"meta\":{\"junk\":[" + [] {
      std::string s;
      s.reserve(30000000);
      for (int i = 0; i < 15000000; ++i) s += i ? ",0" : "0";
      return s;
    }() + "]},";
    text.insert(1, big);
    write_file(dir_ / "big.json", text);
  }
  SpawnOptions o;
#if !defined(CSYMPNET_UNDER_ASAN)
  // AddressSanitizer reserves terabytes of address space for its shadow memory, so a limit on
  // the address space stops it before main(); under it the refusals alone are checked.
  o.address_space_kb = 600000;
#endif
  Timed r = spawn_with(
      {"rollout", "--model", "big.json", "--z0", "0.1,0.2", "--h", "0.1", "--steps", "2"}, dir_, o);
  expect_refusal(r, {"big.json", "1000000 values outside \"params\""});
  write_file(dir_ / "deep.json",
             "{\"meta\":" + std::string(1000, '[') + std::string(1000, ']') + "}");
  r = spawn_with(
      {"rollout", "--model", "deep.json", "--z0", "0.1,0.2", "--h", "0.1", "--steps", "2"}, dir_,
      o);
  expect_refusal(r, {"deep.json", "nested deeper than 64"});
}

// Messages whose cases need an environment or a fitted model.
TEST_F(HostileFiles, MessagesNameTheRealCause) {
  // CSYMPNET_KERNELS is checked like CSYMPNET_ARITHMETIC (it was ignored silently).
  ::setenv("CSYMPNET_KERNELS", "garbage", 1);
  Timed r = spawn_with({"describe", "--preset", "s1"}, dir_, {});
  ::unsetenv("CSYMPNET_KERNELS");
  expect_refusal(r, {"CSYMPNET_KERNELS", "'garbage'", "portable"});
  // --init with a time scale of 1e-308, or a beta of 0: the init file is named, not the data.
  ASSERT_LT(spawn_with({"fit", "d.csv", "-q", "--epochs", "20", "--out", "f0"}, dir_, {}).code, 5);
  const json fitted = json::parse(slurp(dir_ / "f0" / "model.json"));
  ASSERT_TRUE(fitted["model"].contains("normalization"));
  {
    json doc = fitted;
    doc["model"]["normalization"]["time_scale"] = 1e-308;
    write_file(dir_ / "tau.json", resigned(doc));
    r = spawn_with({"fit", "d.csv", "-q", "--init", "tau.json", "--out", "f1"}, dir_, {});
    expect_refusal(r, {"--init", "tau.json", "time scale"});
    EXPECT_EQ(r.err.find("d.csv:"), std::string::npos) << r.err;
  }
  {
    json doc = fitted;
    const Model m = model_from_spec(doc["model"], "spec");
    ASSERT_TRUE(m.damping_param_index().has_value());
    doc["params"][static_cast<std::size_t>(*m.damping_param_index())] = 0.0;
    write_file(dir_ / "beta.json", resigned(doc));
    r = spawn_with({"fit", "d.csv", "-q", "--init", "beta.json", "--out", "f2"}, dir_, {});
    // Read while the options are parsed: a usage error (exit 2), like --beta-init 0.
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_NE(r.err.find("--init: beta.json: its damping parameter beta is 0"), std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find("expected a nonzero beta"), std::string::npos) << r.err;
  }
  // A rollout's step is printed as the number it is, not as %f's 0.000000.
  json blowup = json::parse(base_model());
  for (auto& v : blowup["params"]) v = 1e300;
  write_file(dir_ / "blowup.json", resigned(blowup));
  r = spawn_with(
      {"rollout", "--model", "blowup.json", "--z0", "0.1,0.2", "--h", "1e-7", "--steps", "3"}, dir_,
      {});
  expect_refusal(r, {"--h 1e-07"});  // and t = 1e-07, not 0.000000
  EXPECT_EQ(r.err.find("0.000000"), std::string::npos) << r.err;
}

// ----- class 6: messages that misled ----------------------------------------------------------
// Each refusal names what is wrong and the way out, in the user's own terms.

std::vector<Case> message_cases() {
  std::vector<Case> cases;
  const auto files = [](std::map<std::string, std::string> named) {
    return [named](const fs::path& d) {
      for (const auto& [name, text] : named) write_file(d / name, text);
    };
  };
  const std::string pairs = base_pairs(), trajs = base_trajectories();
  const std::string traj_body = trajs.substr(trajs.find('\n') + 1);
  const std::string pairs_body = pairs.substr(pairs.find('\n') + 1);
  const auto train = [](const std::string& file, std::vector<std::string> extra = {}) {
    std::vector<std::string> a = {"train", "--data", file, "--epochs", "2", "-q", "--out", "out"};
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  // One extra column: named, with --columns to drop it.
  cases.push_back(
      {"msg_extra_column",
       files({{"d.csv",
               [&] {
                 std::string out = "traj,t,q1,p1,temp\n";
                 std::stringstream in(traj_body);
                 for (std::string l; std::getline(in, l);) out += l + ",20\n";
                 return out;
               }()}}),
       train("d.csv"),
       {1},
       {"header column 5 'temp' is not a column", "--columns traj=traj,t=t,q1=q1,p1=p1"},
       {"out"},
       {},
       {"the same number"}});
  cases.push_back({"msg_trailing_comma",
                   files({{"d.csv", "h,q1,p1,next_q1,next_p1,\n" + pairs_body}}),
                   train("d.csv"),
                   {1},
                   {"header column 6 is empty (a trailing comma?)",
                    "--columns h=h,q1=q1,p1=p1,next_q1=next_q1,next_p1=next_p1"},
                   {"out"}});
  // An unrecognised header: --columns, with the user's own names.
  cases.push_back({"msg_unrecognised_header",
                   files({{"d.csv", "time_s,angle_deg,omega_degps\n0,1,0\n0.1,0.9,0.1\n"}}),
                   train("d.csv"),
                   {1},
                   {"--columns t=time_s,q1=angle_deg,p1=omega_degps"},
                   {"out"}});
  // A repeated column is not a second q.
  cases.push_back({"msg_duplicate_column",
                   files({{"d.csv", "h,q1,q1,next_q1,next_p1\n" + pairs_body}}),
                   train("d.csv"),
                   {1},
                   {"header column 3 'q1' repeats column 2"},
                   {"out"},
                   {},
                   {"2 q"}});
  // A loop of symbolic links is not a missing file.
  cases.push_back({"msg_symlink_loop",
                   [](const fs::path& d) { fs::create_symlink("loop", d / "loop"); },
                   train("loop"),
                   {1, 2},
                   {"symbolic links"},
                   {"out"},
                   {},
                   {"does not exist"}});
  // --epochs far beyond a long: the option's own range, not 2^63 - 1.
  for (const std::string v : {"99999999999999999999", "9223372036854775808"})
    cases.push_back({"msg_epochs_huge_" + v,
                     files({{"d.csv", pairs}}),
                     train("d.csv", {"--epochs", v}),
                     {2},
                     {"--epochs", "100000000"},
                     {"out"},
                     {},
                     {"9223372036854775807"}});
  cases.push_back({"msg_steps_huge",
                   files({{"m.json", base_model()}}),
                   {"rollout", "--model", "m.json", "--z0", "0.1,0.2", "--h", "0.1", "--steps",
                    "99999999999999999999"},
                   {2},
                   {"--steps", "100000000"},
                   {},
                   {},
                   {"9223372036854775807"}});
  // A system that blows up: the options to check, not the library's internals.
  cases.push_back(
      {"msg_generate_omega_huge",
       nullptr,
       {"generate", "--preset", "s1", "--split", "test", "--omega", "1e308", "--out", "g.csv"},
       {1},
       {"--omega"},
       {"g.csv"},
       {},
       {"generate_test_set", "max_redraws"}});
  // --columns: the user's header is quoted, not the one the mapping built.
  cases.push_back({"msg_columns_quotes_the_users_header",
                   files({{"d.csv", "t,q1,p1\n0,1,0\n0.1,0.9,0.1\n"}}),
                   train("d.csv", {"--columns", "traj=t"}),
                   {1},
                   {"'t,q1,p1'"},
                   {"out"}});
  // Ids -0 and 0 are one integer: said so, not reported as a time error.
  cases.push_back({"msg_minus_zero_id",
                   files({{"d.csv",
                           "traj,t,q1,p1\n0,0,1,0\n0,0.1,0.9,0.1\n-0,0,1,0\n"
                           "-0,0.1,0.9,0.1\n"}}),
                   train("d.csv"),
                   {1},
                   {"d.csv:4:", "'-0' is the same integer as '0'"},
                   {"out"},
                   {},
                   {"column 't'"}});
  // States scaled by 1e-170: their squares underflow, which is not "does not vary".
  cases.push_back({"msg_tiny_states",
                   files({{"d.csv",
                           [] {
                             std::ostringstream s;
                             s.precision(17);
                             s << "t,q1,p1\n";
                             for (int i = 0; i < 40; ++i)
                               s << 0.1 * i << ',' << 1e-170 * std::cos(0.1 * i) << ','
                                 << -1e-170 * std::sin(0.1 * i) << '\n';
                             return s.str();
                           }()}}),
                   {"fit", "d.csv", "-q", "--out", "out"},
                   {1, 4},
                   {"underflows"},
                   {"out"},
                   {},
                   {"does not vary"}});
  // Positions-only records (docs/hardening.md): the file's own columns are named, never a p.
  const auto positions = [](double unit, const std::string& q2) {
    std::ostringstream s;
    s.precision(17);
    s << "t,q1" << (q2.empty() ? "" : ",q2") << '\n';
    for (int i = 0; i < 60; ++i)
      s << 0.2 * i * unit << ',' << std::exp(-0.01 * i) * std::cos(0.2 * i)
        << (q2.empty() ? "" : "," + q2) << '\n';
    return s.str();
  };
  for (double unit : {1e-200, 1e200})
    cases.push_back({std::string("msg_positions_time_unit_") + (unit < 1.0 ? "tiny" : "huge"),
                     files({{"d.csv", positions(unit, "")}}),
                     {"fit", "d.csv", "-q", "--out", "out"},
                     {1},
                     {"median step", "q1", "rescale t"},
                     {"out"},
                     {},
                     {"p1"}});
  cases.push_back({"msg_positions_constant_q2",
                   files({{"d.csv", positions(1.0, "0.7")}}),
                   {"fit", "d.csv", "-q", "--out", "out"},
                   {1},
                   {"q2 does not vary"},
                   {"out"}});
  // 300 trajectories of 2 positions: not identified with a report, never an internal-looking
  // "Gauss-Newton matrix could not be factored" (exit 1).
  cases.push_back({"msg_positions_two_samples_each",
                   files({{"d.csv",
                           [] {
                             std::string s = "traj,t,q1\n";
                             for (int j = 0; j < 300; ++j)
                               s += std::to_string(j) + ",0," + std::to_string(j % 7) + "\n" +
                                    std::to_string(j) + ",0.1," + std::to_string(j % 5) + "\n";
                             return s;
                           }()}}),
                   {"fit", "d.csv", "-q", "--no-figures", "--out", "out"},
                   {4},
                   {},
                   {}});
  // --init with a model whose map overflows on the data at its parameters (a coefficient of
  // 1e300): the model file is the cause, not the data ("windows: non-finite value").
  const std::string huge_init = [] {
    json doc = json::parse(library_model());
    for (std::size_t i = 0; i + 1 < doc["params"].size(); ++i) doc["params"][i] = 1e300;
    return resigned(doc);
  }();
  cases.push_back({"msg_init_huge_coefficients_states",
                   files({{"d.csv", trajs}, {"m.json", huge_init}}),
                   {"fit", "d.csv", "-q", "--init", "m.json", "--out", "out"},
                   {1},
                   {"--init", "m.json", "non-finite"},
                   {"out"},
                   {},
                   {"windows", "Gauss-Newton"}});
  cases.push_back({"msg_init_huge_coefficients_positions",
                   files({{"d.csv", positions(1.0, "")}, {"m.json", huge_init}}),
                   {"fit", "d.csv", "-q", "--init", "m.json", "--out", "out"},
                   {1},
                   {"--init", "m.json", "non-finite"},
                   {"out"},
                   {},
                   {"windows", "Gauss-Newton"}});
  // evaluate --data with a model whose meta.system is a label, not a system: evaluated on
  // the data, no --preset asked for.
  cases.push_back({"msg_evaluate_meta_system_string",
                   files({{"t.csv", trajs},
                          {"m.json",
                           [] {
                             json doc = json::parse(base_model());
                             doc["meta"]["system"] = "pendulum rig 3";
                             return resigned(doc);
                           }()}}),
                   {"evaluate", "--model", "m.json", "--data", "t.csv"},
                   {0},
                   {},
                   {}});
  return cases;
}

INSTANTIATE_TEST_SUITE_P(Messages, Hostile, ::testing::ValuesIn(message_cases()), case_name);
INSTANTIATE_TEST_SUITE_P(Csv, Hostile, ::testing::ValuesIn(csv_cases()), case_name);
INSTANTIATE_TEST_SUITE_P(ModelFile, Hostile, ::testing::ValuesIn(model_cases()), case_name);
INSTANTIATE_TEST_SUITE_P(Option, Hostile, ::testing::ValuesIn(option_cases()), case_name);
INSTANTIATE_TEST_SUITE_P(Output, Hostile, ::testing::ValuesIn(output_cases()), case_name);

// The suite is as large as it claims.
TEST(HostileSuite, HasAtLeast300Cases) {
  const std::size_t n = csv_cases().size() + model_cases().size() + option_cases().size() +
                        output_cases().size() + message_cases().size();
  std::printf(
      "hostile cases: %zu csv, %zu model files, %zu options, %zu output targets, %zu messages\n",
      csv_cases().size(), model_cases().size(), option_cases().size(), output_cases().size(),
      message_cases().size());
  EXPECT_GE(n, 300u);
}

}  // namespace
}  // namespace csympnet
