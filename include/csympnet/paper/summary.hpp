// From cached run records to the reproduction's outputs: summary.json, and per suite a
// Markdown, CSV and LaTeX table with the paper's numbers and the ratios beside ours.
// Everything here is a pure function of the records, so the outputs are identical however
// the runs were scheduled. Wall times vary run to run and go to timings.json only.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/paper/suite.hpp"

namespace csympnet {

// Linear-interpolation quantile (NumPy's default), q in [0, 1]; values need not be sorted.
double quantile(std::vector<double> values, double q);

using RecordLookup = std::function<std::optional<nlohmann::json>(const SuiteRun&)>;

// summary.json: {"suites": [...names], SUITE: {PRESET: {MODEL: ...}}, "checks": {...}}.
//   table suites: MODEL → the run's metrics plus "paper": the paper's numbers, if any;
//   grid suites:  MODEL → a list of cells {sigma, n_train, h_test, seeds, failed,
//                 l2_error: {median, q1, q3, values}, gamma_abs_err, lambda_hat, lambda_abs_err}
//                 with `values` the per-seed numbers in seed order (null where non-finite).
// "checks": per table suite and preset, the model with the smallest L2 error.
// Throws Error naming the first run without a record.
nlohmann::json summarize(const std::vector<SuiteSpec>& suites, const RecordLookup& record_of);

// Wall times of every run, by suite, preset and model (not deterministic, kept apart).
nlohmann::json timings(const std::vector<SuiteSpec>& suites, const RecordLookup& record_of);

struct TableFiles {
  std::string markdown, csv, latex;
};
// The tables of one suite from the summary.
TableFiles render_tables(const SuiteSpec& suite, const nlohmann::json& summary);

}  // namespace csympnet
