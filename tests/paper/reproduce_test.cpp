// Suites as data, the cached run executor and the summary: parsing errors, expansion,
// caching and resumption, and independence of the results from threads and ranks.
#include <gtest/gtest.h>

#include <filesystem>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "csympnet/core/error.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/paper/reproduce.hpp"
#include "csympnet/paper/suite.hpp"
#include "csympnet/paper/summary.hpp"

namespace csympnet {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

json tiny_table() {
  return json::parse(R"({"name": "tiny", "kind": "table",
    "columns": ["params", "l2_error", "gamma_abs_err"], "presets": ["s1"],
    "models": ["csympnet", "sympnet", "ode"], "seeds": [42],
    "epochs": {"*": {"*": 60}}})");
}

json tiny_grid() {
  return json::parse(R"({"name": "tgrid", "kind": "grid", "vary": "h_test",
    "presets": ["s1"], "models": ["csympnet", "dhnn2"], "seeds": [1, 2, 3],
    "sigmas": [0, 0.01], "h_tests": [0.1, 0.2], "extra_jacobians": false,
    "epochs": {"*": {"*": 40}}})");
}

void expect_suite_error(const json& doc, const std::string& fragment) {
  try {
    parse_suite(doc, "suite.json");
    ADD_FAILURE() << "accepted " << doc.dump();
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("suite.json"), std::string::npos) << msg;
    EXPECT_NE(msg.find(fragment), std::string::npos) << msg;
  }
}

// One booktabs table float of a LaTeX table file.
struct LatexFloat {
  std::string caption, label;
  std::vector<std::vector<std::string>> header, body;  // rows split into cells
};

// The cells of a tabular row "a & b & c \\" (an escaped \& is text, not a separator).
std::vector<std::string> latex_cells(std::string row) {
  const std::string end = " \\\\";
  EXPECT_TRUE(row.size() >= end.size() &&
              row.compare(row.size() - end.size(), end.size(), end) == 0)
      << row;
  row = row.substr(0, row.size() - end.size());
  std::vector<std::string> cells(1);
  for (std::size_t i = 0; i < row.size(); ++i) {
    if (row[i] == '&' && (i == 0 || row[i - 1] != '\\'))
      cells.emplace_back();
    else
      cells.back() += row[i];
  }
  for (auto& c : cells) {
    c.erase(0, c.find_first_not_of(' '));
    c.erase(c.find_last_not_of(' ') + 1);
  }
  return cells;
}

// How many columns a row spans (a \multicolumn{n} cell spans n).
std::size_t latex_span(const std::vector<std::string>& cells) {
  std::size_t n = 0;
  for (const auto& c : cells) n += c.rfind("\\multicolumn{", 0) == 0 ? std::stoul(c.substr(13)) : 1;
  return n;
}

// Reads a LaTeX table file line by line, checking that it consists of comments and booktabs
// floats: \begin{table}, \caption, \label, \begin{tabular}{SPEC}, \toprule, header rows
// (and \cmidrule), \midrule, body rows (separated by \midrule or \addlinespace), \bottomrule,
// \end{tabular}, \end{table}; no \hline; every row spans as many columns as SPEC names.
std::vector<LatexFloat> parse_latex_tables(const std::string& tex) {
  std::vector<LatexFloat> out;
  std::istringstream in(tex);
  std::string line;
  enum { kOutside, kPreamble, kTop, kHeader, kBody, kEndTabular, kEndTable } state = kOutside;
  std::size_t columns = 0;
  auto starts = [&](const char* prefix) { return line.rfind(prefix, 0) == 0; };
  while (std::getline(in, line)) {
    EXPECT_EQ(line.find("\\hline"), std::string::npos) << line;
    switch (state) {
      case kOutside:
        if (line.empty() || starts("%")) break;
        EXPECT_EQ(line, "\\begin{table}[htbp]");
        out.emplace_back();
        state = kPreamble;
        break;
      case kPreamble:
        if (starts("\\caption{")) {
          out.back().caption = line.substr(9, line.size() - 10);
        } else if (starts("\\label{")) {
          out.back().label = line.substr(7, line.size() - 8);
        } else if (starts("\\begin{tabular}{")) {
          const std::string spec = line.substr(16, line.size() - 17);
          EXPECT_EQ(spec.find_first_not_of("lrc"), std::string::npos) << spec;
          columns = spec.size();
          state = kTop;
        } else {
          EXPECT_TRUE(line == "\\centering" || line == "\\small") << line;
        }
        break;
      case kTop:
        EXPECT_EQ(line, "\\toprule");
        state = kHeader;
        break;
      case kHeader:
        if (line == "\\midrule") {
          state = kBody;
        } else if (!starts("\\cmidrule")) {
          out.back().header.push_back(latex_cells(line));
          EXPECT_EQ(latex_span(out.back().header.back()), columns) << line;
        }
        break;
      case kBody:
        if (line == "\\bottomrule") {
          state = kEndTabular;
        } else if (line != "\\midrule" && line != "\\addlinespace") {
          out.back().body.push_back(latex_cells(line));
          EXPECT_EQ(out.back().body.back().size(), columns) << line;
        }
        break;
      case kEndTabular:
        EXPECT_EQ(line, "\\end{tabular}");
        state = kEndTable;
        break;
      case kEndTable:
        EXPECT_EQ(line, "\\end{table}");
        state = kOutside;
        break;
    }
  }
  EXPECT_EQ(state, kOutside) << "a table float is not closed";
  for (const auto& f : out) {
    EXPECT_FALSE(f.caption.empty());
    EXPECT_FALSE(f.label.empty());
    EXPECT_FALSE(f.header.empty());
    EXPECT_FALSE(f.body.empty());
  }
  return out;
}

std::vector<std::vector<std::string>> csv_rows(const std::string& csv) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream in(csv);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    rows.emplace_back();
    std::istringstream fields(line);
    std::string f;
    while (std::getline(fields, f, ',')) rows.back().push_back(f);
  }
  return rows;
}

class Reproduce : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("csympnet_reproduce_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
            std::to_string(::getpid()));
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string sub(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

std::map<std::string, std::string> record_texts(const std::string& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) {
    json rec = json::parse(read_text_file(e.path().string()));
    rec["report"].erase("train_seconds");  // wall times differ run to run
    rec["report"].erase("eval_seconds");
    out[e.path().filename().string()] = rec.dump();
  }
  return out;
}

TEST(Suite, ParsesAndExpandsTheGrid) {
  const SuiteSpec s = parse_suite(tiny_grid(), "suite.json");
  const auto runs = expand_suite(s);
  ASSERT_EQ(runs.size(), 1u * 2 * 3 * 2);  // presets x models x seeds x sigmas
  std::set<std::string> keys;
  for (const auto& r : runs) {
    keys.insert(r.key);
    EXPECT_EQ(r.h_tests, (std::vector<double>{0.1, 0.2}));
    EXPECT_EQ(r.config.preset.h_test, 0.1);
    EXPECT_EQ(r.config.train.epochs, 40);
    EXPECT_FALSE(r.extra_jacobians);
  }
  EXPECT_EQ(keys.size(), runs.size());
  // Deterministic: expanding again gives the same keys in the same order.
  const auto again = expand_suite(s);
  for (std::size_t i = 0; i < runs.size(); ++i) EXPECT_EQ(runs[i].key, again[i].key);
}

TEST(Suite, BudgetLookupOrderAndDefaults) {
  json doc = tiny_table();
  doc["epochs"] = json::parse(R"({"s1": {"ode": 7, "*": 9}, "*": {"sympnet": 11, "*": 13}})");
  doc["presets"] = {"s1", "s2"};
  const SuiteSpec s = parse_suite(doc, "suite.json");
  EXPECT_EQ(suite_epochs(s, "s1", "ode"), 7);
  EXPECT_EQ(suite_epochs(s, "s1", "sympnet"), 9);
  EXPECT_EQ(suite_epochs(s, "s2", "sympnet"), 11);
  EXPECT_EQ(suite_epochs(s, "s2", "ode"), 13);
  doc.erase("epochs");
  const SuiteSpec plain = parse_suite(doc, "suite.json");
  EXPECT_EQ(suite_epochs(plain, "s1", "csympnet"),
            train_options_for(preset_by_name("s1"), "csympnet").epochs);
}

TEST(Suite, KeysChangeWithEveryConfigChoice) {
  const auto base = expand_suite(parse_suite(tiny_table(), "suite.json")).front().key;
  json doc = tiny_table();
  doc["epochs"]["*"]["*"] = 61;
  EXPECT_NE(expand_suite(parse_suite(doc, "suite.json")).front().key, base);
  doc = tiny_table();
  doc["reference"] = "expm";
  EXPECT_NE(expand_suite(parse_suite(doc, "suite.json")).front().key, base);
  doc = tiny_table();
  doc["seeds"] = {43};
  EXPECT_NE(expand_suite(parse_suite(doc, "suite.json")).front().key, base);
}

// A suite's text: a key given twice (JSON readers keep the last, silently) and a title or kind
// that is not a string are refused by name (both found by fuzz_suite_file).
TEST(Suite, RefusesRepeatedKeysAndNonStringTitles) {
  std::string text = tiny_table().dump();
  EXPECT_NO_THROW(suite_from_text(text, "suite.json"));
  const std::string twice_title = R"({"title": "a", "title": [1, 2], )" + text.substr(1);
  try {
    suite_from_text(twice_title, "suite.json");
    ADD_FAILURE() << "accepted " << twice_title;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("suite.json: key 'title' appears twice"),
              std::string::npos)
        << e.what();
  }
  for (const char* key : {"title", "kind", "comment"})
    for (const json& v : {json(3), json::array({"a"}), json::object({{"x", 1}})}) {
      json d = tiny_table();
      d[key] = v;
      expect_suite_error(d, std::string("key '") + key + "' = " + v.dump() + ", expected a string");
    }
  // Nested objects are checked too; equal keys in different objects are fine.
  json d = tiny_table();
  d["epochs"] = json::parse(R"({"s1": {"*": 5}})");
  text = d.dump();
  const std::size_t at = text.find(R"({"*":5})");
  ASSERT_NE(at, std::string::npos) << text;
  const std::string twice = text.substr(0, at) + R"({"*":5,"*":6})" + text.substr(at + 7);
  try {
    suite_from_text(twice, "suite.json");
    ADD_FAILURE() << "accepted " << twice;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("key '*' appears twice"), std::string::npos) << e.what();
  }
}

TEST(Suite, RejectsBadFilesWithNamedKeys) {
  json d = tiny_table();
  d["models"] = {"csympnet", "hnn"};
  expect_suite_error(d, "'hnn'");
  d = tiny_table();
  d["presets"] = {"s4"};
  expect_suite_error(d, "'s4'");
  d = tiny_table();
  d["kind"] = "plot";
  expect_suite_error(d, "'kind'");
  d = tiny_table();
  d["seeds"] = {1, 2};
  expect_suite_error(d, "one seed");
  d = tiny_table();
  d["sigma"] = {0.1};
  expect_suite_error(d, "unknown key 'sigma'");
  d = tiny_table();
  d["sigmas"] = {-1.0};
  expect_suite_error(d, "'sigmas'");
  d = tiny_table();
  d["epochs"] = json::parse(R"({"s1": {"*": -5}})");
  expect_suite_error(d, "epochs.s1.*");
  d = tiny_grid();
  d.erase("vary");
  expect_suite_error(d, "'vary'");
  d = tiny_grid();
  d["n_train"] = json::parse(R"({"s1": [2]})");
  expect_suite_error(d, "n_train.s1");
  d = tiny_table();
  d["name"] = "../x";
  expect_suite_error(d, "name");
  d = tiny_table();
  d["reference"] = json::parse(R"({"s1": "euler"})");
  expect_suite_error(d, "reference.s1");
}

TEST(Summary, QuantileMatchesLinearInterpolation) {
  EXPECT_DOUBLE_EQ(quantile({3, 1, 2}, 0.5), 2.0);
  EXPECT_DOUBLE_EQ(quantile({1, 2, 3, 4}, 0.5), 2.5);
  EXPECT_DOUBLE_EQ(quantile({1, 2, 3, 4}, 0.25), 1.75);
  EXPECT_DOUBLE_EQ(quantile({1, 2, 3, 4}, 0.75), 3.25);
  EXPECT_DOUBLE_EQ(quantile({5}, 0.25), 5.0);
  EXPECT_THROW(quantile({}, 0.5), Error);
}

TEST_F(Reproduce, CachesResumesAndIgnoresThreadCount) {
  const auto runs = expand_suite(parse_suite(tiny_table(), "suite.json"));
  const ExecuteStats first = execute_runs(runs, sub("a"), 1, {});
  EXPECT_EQ(first.executed, runs.size());
  EXPECT_EQ(first.failed, 0u);
  // A second call finds every record and executes nothing.
  const ExecuteStats again = execute_runs(runs, sub("a"), 2, {});
  EXPECT_EQ(again.executed, 0u);
  EXPECT_EQ(again.cached, runs.size());
  // Deleting one record reruns that one only, and it comes back identical.
  const auto before = record_texts(sub("a"));
  fs::remove(fs::path(sub("a")) / (runs[1].key + ".json"));
  EXPECT_EQ(execute_runs(runs, sub("a"), 2, {}).executed, 1u);
  EXPECT_EQ(record_texts(sub("a")), before);
  // Two threads give the same records as one.
  execute_runs(runs, sub("b"), 2, {});
  EXPECT_EQ(record_texts(sub("b")), before);
}

TEST_F(Reproduce, RanksSplitTheWorkAndTogetherMatchOneProcess) {
  const auto runs = expand_suite(parse_suite(tiny_grid(), "suite.json"));
  const ExecuteStats r0 = execute_runs(runs, sub("ranks"), 1, {0, 2});
  EXPECT_EQ(r0.executed + r0.other_ranks, runs.size());
  EXPECT_GT(r0.other_ranks, 0u);
  const ExecuteStats r1 = execute_runs(runs, sub("ranks"), 1, {1, 2});
  EXPECT_EQ(r1.executed, r0.other_ranks);
  execute_runs(runs, sub("single"), 2, {});
  EXPECT_EQ(record_texts(sub("ranks")), record_texts(sub("single")));
}

TEST_F(Reproduce, ACorruptOrForeignRecordIsRedone) {
  const auto runs = expand_suite(parse_suite(tiny_table(), "suite.json"));
  fs::create_directories(sub("c"));
  write_text_atomic((fs::path(sub("c")) / (runs[0].key + ".json")).string(), "{ truncated");
  write_text_atomic((fs::path(sub("c")) / (runs[1].key + ".json")).string(),
                    json{{"key", runs[1].key}, {"config", "something else"}}.dump());
  EXPECT_FALSE(load_record(sub("c"), runs[0]));
  EXPECT_FALSE(load_record(sub("c"), runs[1]));
  EXPECT_EQ(execute_runs(runs, sub("c"), 1, {}).executed, runs.size());
  EXPECT_TRUE(load_record(sub("c"), runs[0]));
}

TEST_F(Reproduce, SummaryAndTablesFollowTheRecords) {
  const SuiteSpec table = parse_suite(tiny_table(), "suite.json");
  const SuiteSpec grid = parse_suite(tiny_grid(), "suite.json");
  std::vector<SuiteRun> runs = expand_suite(table);
  for (auto& r : expand_suite(grid)) runs.push_back(r);
  execute_runs(runs, sub("s"), 2, {});
  const RecordLookup lookup = [&](const SuiteRun& r) { return load_record(sub("s"), r); };
  const json summary = summarize({table, grid}, lookup);

  // Table entries are the records' numbers, with the paper's beside them.
  const json& e = summary["tiny"]["s1"]["csympnet"];
  const json rec = *load_record(sub("s"), expand_suite(table).front());
  EXPECT_EQ(e["l2_error"], rec["by_h_test"][0]["l2_error"]);
  EXPECT_EQ(e["params"], 115);
  EXPECT_EQ(e["paper"]["l2_error"], 2.175e-4);
  EXPECT_TRUE(summary["tiny"]["s1"]["sympnet"]["gamma_abs_err"].is_null());
  // The check names the model with the smallest L2 error.
  std::string best;
  double best_l2 = 1e300;
  for (const char* m : {"csympnet", "sympnet", "ode"}) {
    const double l2 = summary["tiny"]["s1"][m]["l2_error"].get<double>();
    if (l2 < best_l2) best_l2 = l2, best = m;
  }
  EXPECT_EQ(summary["checks"]["tiny"]["s1"]["best_l2_model"], best);

  // Grid cells: one per (sigma, h_test), medians over the three seeds.
  const json& cells = summary["tgrid"]["s1"]["dhnn2"];
  ASSERT_EQ(cells.size(), 4u);
  std::vector<double> l2;
  for (const auto& r : expand_suite(grid)) {
    if (r.config.model != "dhnn2" || r.config.sigma != 0.0) continue;
    l2.push_back(load_record(sub("s"), r)->at("by_h_test")[1]["l2_error"].get<double>());
  }
  ASSERT_EQ(l2.size(), 3u);
  std::sort(l2.begin(), l2.end());
  const json& cell = cells[1];
  EXPECT_EQ(cell["sigma"], 0.0);
  EXPECT_EQ(cell["h_test"], 0.2);
  EXPECT_EQ(cell["l2_error"]["median"], l2[1]);
  EXPECT_TRUE(cell["lambda_hat"].is_null());  // no Jacobians at the extra h_test
  EXPECT_FALSE(cells[0]["lambda_hat"].is_null());
  EXPECT_FALSE(cell["gamma_abs_err"].is_null());

  // Rendering is a pure function of the summary.
  const TableFiles t1 = render_tables(table, summary), t2 = render_tables(table, summary);
  EXPECT_EQ(t1.markdown, t2.markdown);
  EXPECT_NE(t1.markdown.find("CSympNet-ID"), std::string::npos);
  EXPECT_NE(t1.csv.find("s1,csympnet,l2_error,"), std::string::npos);
  const TableFiles g = render_tables(grid, summary);
  EXPECT_NE(g.csv.find("s1,dhnn2,0.01,80,0.2,"), std::string::npos);

  // LaTeX: booktabs floats with a caption and a label. The table suite's body holds, per
  // preset and model, the CSV's numbers (ours, paper, ratio per column) as the same text.
  const auto floats = parse_latex_tables(t1.latex);
  ASSERT_EQ(floats.size(), 1u);
  EXPECT_EQ(floats[0].label, "tab:tiny");
  ASSERT_EQ(floats[0].header.size(), 2u);
  EXPECT_EQ(floats[0].header[0][2], "\\multicolumn{3}{c}{params}");
  EXPECT_EQ(floats[0].header[0][3], "\\multicolumn{3}{c}{$L^2$}");
  EXPECT_EQ(floats[0].header[1][0], "Preset");
  EXPECT_NE(t1.latex.find("\\cmidrule(lr){3-5}\\cmidrule(lr){6-8}\\cmidrule(lr){9-11}\n"),
            std::string::npos);
  const auto csv = csv_rows(t1.csv);
  const auto& body = floats[0].body;
  ASSERT_EQ(body.size(), table.presets.size() * table.models.size());
  ASSERT_EQ(csv.size(), body.size() * table.columns.size());
  for (std::size_t r = 0; r < body.size(); ++r) {
    EXPECT_EQ(body[r][0], r == 0 ? "s1" : "");  // the preset on its first row only
    EXPECT_EQ(body[r][1], r == 0 ? "CSympNet-ID" : r == 1 ? "SympNet" : "ODEBaseline");
    for (std::size_t c = 0; c < table.columns.size(); ++c) {
      const auto& want = csv[r * table.columns.size() + c];
      for (std::size_t k = 0; k < 3; ++k)
        EXPECT_EQ(body[r][2 + 3 * c + k], want[3 + k] == "-" ? "--" : want[3 + k])
            << "row " << r << ", " << want[2];
    }
  }
  EXPECT_EQ(body[1][2 + 3 * 2], "--");  // SympNet has no gamma: an en dash
  // The grid: one float per preset, a row per cell, its L2 median as in the CSV (3 digits).
  const auto gfloats = parse_latex_tables(g.latex);
  ASSERT_EQ(gfloats.size(), grid.presets.size());
  EXPECT_EQ(gfloats[0].label, "tab:tgrid-s1");
  EXPECT_NE(gfloats[0].caption.find("over 3 seeds"), std::string::npos) << gfloats[0].caption;
  const auto gcsv = csv_rows(g.csv);
  ASSERT_EQ(gfloats[0].body.size(), gcsv.size());
  for (std::size_t r = 0; r < gcsv.size(); ++r) {
    const auto& row = gfloats[0].body[r];
    EXPECT_EQ(row[1], gcsv[r][2]);  // sigma
    EXPECT_EQ(row[3], gcsv[r][4]);  // h_test
    if (gcsv[r][5] == "-")
      EXPECT_EQ(row[4], "--");
    else
      EXPECT_NEAR(std::stod(row[4]), std::stod(gcsv[r][5]), 5e-3 * std::stod(gcsv[r][5]));
  }
  EXPECT_EQ(gfloats[0].body[0][0], "CSympNet-ID");
  // The caption: the title, escaped, with the paper's table number moved to its end.
  SuiteSpec titled = table;
  titled.title = "Table 2: L2 error_x & 5% of #1";
  EXPECT_EQ(parse_latex_tables(render_tables(titled, summary).latex).at(0).caption,
            "L2 error\\_x \\& 5\\% of \\#1 (the paper's Table 2). Each metric: ours, the paper's "
            "value where it reports one, and ours / paper.");
  titled.title = "Table 2 with {braces}";
  EXPECT_EQ(parse_latex_tables(render_tables(titled, summary).latex).at(0).caption.substr(0, 23),
            "Table 2 with \\{braces\\}");
  EXPECT_EQ(gfloats[0].body[1][0], "");
  // Every Markdown table row has as many cell separators (unescaped '|') as its header.
  for (const std::string& md : {t1.markdown, g.markdown}) {
    std::istringstream lines(md);
    std::string line;
    long header = -1;
    while (std::getline(lines, line)) {
      if (line.empty() || line[0] != '|') {
        header = -1;
        continue;
      }
      long bars = 0;
      for (std::size_t i = 0; i < line.size(); ++i)
        bars += line[i] == '|' && (i == 0 || line[i - 1] != '\\');
      if (header < 0) header = bars;
      EXPECT_EQ(bars, header) << line;
    }
  }

  // A missing record is an error naming the run.
  fs::remove(fs::path(sub("s")) / (runs[0].key + ".json"));
  try {
    summarize({table}, lookup);
    ADD_FAILURE() << "no error";
  } catch (const Error& err) {
    EXPECT_NE(std::string(err.what()).find(runs[0].key), std::string::npos);
  }
}

}  // namespace
}  // namespace csympnet
