// Command-line overrides of a preset's system constants (d, γ, ω, k, α), and the finite-number
// check the numeric options share.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "csympnet/core/options.hpp"
#include "csympnet/paper/preset.hpp"

namespace csympnet::cli {

// Accepts only finite numbers. CLI11's Range and PositiveNumber let NaN through (every
// comparison with NaN is false), so numeric options take this check first.
extern const CLI::Validator kFiniteNumber;
// A whole number written in digits, named in the message when it is not one ("abc", "1.5").
extern const CLI::Validator kWholeNumber;
// A seed: a whole number from 0 to 2^64 - 1, refused (not clamped) above.
extern const CLI::Validator kSeed;

// A number in [lo, hi]; the message gives the range in plain digits (CLI11's Range prints
// DBL_MAX in 309 digits and 1e-12 as 0.000000). For the options of the commands that have no
// library range (generate, rollout, reproduce, the system constants).
CLI::Validator in_range(double lo, double hi);

// How the command line spells the library's option keys (core/options.hpp): "val_fraction"
// is --val-fraction, "decay_damping" --no-beta-decay; an option given a value reads
// "--refine lm".
const OptionSpelling& cli_spelling();
// The library's range of an option (kValFractionRange, ...), checked while parsing, after the
// syntax checks (kWholeNumber, kFiniteNumber), so that a value out of it is refused before any
// work with the library's message; the help shows what it expects. The range is written once,
// in the library, which checks it again when the configuration is built.
CLI::Validator library_range(const OptionRange& range);
// The library's nonzero rule (check_nonzero) for `key`, the same way.
CLI::Validator library_nonzero(const char* key);
// Runs `build` (make_fit_config, make_identify_config, RunConfig::validate): an option the
// library refuses becomes a usage error (exit 2) naming the option as spelt here.
template <class Build>
auto at_boundary(Build&& build) -> decltype(build()) {
  try {
    return build();
  } catch (const OptionError& e) {
    throw CLI::ValidationError(cli_spelling().name(e.key()), e.problem(cli_spelling()));
  }
}
// A number >= 0, and one > 0.
extern const CLI::Validator kNonNegative;
extern const CLI::Validator kPositive;

// A time step: finite, > 0 and a normal double.
extern const CLI::Validator kStep;
// One of `names`, exactly (CLI11's IsMember says neither that it is a choice nor what was
// expected).
CLI::Validator one_of(const std::vector<std::string>& names);
// An existing file (not a directory), or directory; kInputFile also takes "-" (stdin).
extern const CLI::Validator kExistingFile;
extern const CLI::Validator kExistingDirectory;
extern const CLI::Validator kInputFile;
// A non-empty output path.
extern const CLI::Validator kOutputPath;

// --columns t=time,q1=theta,p1=omega: a data file's own header names (data/csv.hpp ColumnMap),
// checked as it is parsed.
CLI::Option* add_columns_option(CLI::App& cmd, std::string& spec);

// --threads N of the training commands: TrainOptions::threads.
CLI::Option* add_threads_option(CLI::App& cmd, int& threads);
// --arithmetic sse2|fma: sets the process's arithmetic of the cores' products
// (kernels::set_arithmetic) as it is parsed.
CLI::Option* add_arithmetic_option(CLI::App& cmd);

struct SystemOverrides {
  std::optional<int> d;
  std::optional<double> gamma, omega, k, alpha;

  void add_to(CLI::App& cmd);
  bool any() const { return d || gamma || omega || k || alpha; }
  // Applies the given overrides; a changed d keeps the preset's core type and sizes.
  void apply(Preset& preset) const;
};

}  // namespace csympnet::cli
