// Experiment suites as data: a suite file (experiments/NAME.json) names a grid of runs —
// presets × models × seeds × noise levels × training-set sizes — and how its results are
// tabulated. Expanding a suite gives independent runs, each fully described by its
// RunConfig, so a run's result can be cached under a key derived from that config alone and
// shared between suites (table2, table3 and table4 are the same 24 runs read three ways).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/paper/run.hpp"

namespace csympnet {

// How a suite's results are read.
//   "table"  one run per (preset, model): a table of its metrics (Tables 2–5);
//   "grid"   several seeds per cell, varied along `vary`: median and IQR per cell.
struct SuiteSpec {
  std::string name;
  std::string title;
  std::string kind = "table";        // "table" or "grid"
  std::string vary;                  // grid only: "sigma", "n_train" or "h_test"
  std::vector<std::string> columns;  // table only: metrics shown, e.g. "l2_error"
  std::vector<std::string> presets;
  std::vector<std::string> models;
  std::vector<std::uint64_t> seeds;
  std::vector<double> sigmas{0.0};
  nlohmann::json n_train;       // null, or {"s1": [10, 20], ...}
  std::vector<double> h_tests;  // empty: the preset's h_test
  nlohmann::json reference;     // "splitting" | "expm" | "rk" | {"s1": "expm", ...}
  nlohmann::json epochs;        // budgets: {"s3": {"csympnet": 20000, "*": 5000}, ...}
  bool extra_jacobians = true;  // structure diagnostics at h_tests beyond the first
};

// Reads and validates a suite file; errors name the file and the key.
SuiteSpec load_suite(const std::string& path);
// The same from a suite file's text; `where` names it in errors.
SuiteSpec suite_from_text(const std::string& text, const std::string& where);
SuiteSpec parse_suite(const nlohmann::json& doc, const std::string& where);

// One independent unit of work: train once, evaluate at each h_test.
struct SuiteRun {
  std::string key;              // cache key: readable prefix + hash of the canonical config
  RunConfig config;             // config.preset.h_test is the first of h_tests
  std::vector<double> h_tests;  // evaluation steps (at least one)
  bool extra_jacobians = true;  // structure diagnostics at h_tests[1..] too (else L2 only)
  double cost = 0.0;            // rough relative cost, for scheduling (largest first)
};

// The runs of a suite, in a deterministic order.
std::vector<SuiteRun> expand_suite(const SuiteSpec& suite);

// The epoch budget a suite gives (preset, model); lookup order preset.model, preset.*,
// *.model, *.* , else the preset's default budget for the model.
long suite_epochs(const SuiteSpec& suite, const std::string& preset, const std::string& model);

}  // namespace csympnet
