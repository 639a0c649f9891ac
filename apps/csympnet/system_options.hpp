// Command-line overrides of a preset's system constants (d, γ, ω, k, α), and the finite-number
// check the numeric options share.
#pragma once

#include <optional>

#include <CLI/CLI.hpp>

#include "csympnet/experiments/preset.hpp"

namespace csympnet::cli {

// Accepts only finite numbers. CLI11's Range and PositiveNumber let NaN through (every
// comparison with NaN is false), so numeric options take this check first.
extern const CLI::Validator kFiniteNumber;
// A whole number written in digits, named in the message when it is not one ("abc", "1.5").
extern const CLI::Validator kWholeNumber;
// A seed: a whole number from 0 to 2^64 - 1, refused (not clamped) above.
extern const CLI::Validator kSeed;
// Refuses exactly zero (with kFiniteNumber first): CSympNet-ID's beta starts away from 0, where
// |beta| has no derivative.
extern const CLI::Validator kNonZero;

// --threads N of the training commands: TrainOptions::threads.
CLI::Option* add_threads_option(CLI::App& cmd, int& threads);

struct SystemOverrides {
  std::optional<int> d;
  std::optional<double> gamma, omega, k, alpha;

  void add_to(CLI::App& cmd);
  // Applies the given overrides; a changed d keeps the preset's core type and sizes.
  void apply(Preset& preset) const;
};

}  // namespace csympnet::cli
