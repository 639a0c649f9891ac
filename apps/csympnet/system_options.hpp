// Command-line overrides of a preset's system constants (d, γ, ω, k, α).
#pragma once

#include <optional>

#include <CLI/CLI.hpp>

#include "csympnet/experiments/preset.hpp"

namespace csympnet::cli {

struct SystemOverrides {
  std::optional<int> d;
  std::optional<double> gamma, omega, k, alpha;

  void add_to(CLI::App& cmd);
  // Applies the given overrides; a changed d keeps the preset's core type and sizes.
  void apply(Preset& preset) const;
};

}  // namespace csympnet::cli
