#include "system_options.hpp"

#include <cmath>

#include "csympnet/core/thread_team.hpp"

namespace csympnet::cli {

const CLI::Validator kFiniteNumber(
    [](std::string& input) {
      double v = 0;
      if (!CLI::detail::lexical_cast(input, v)) return "'" + input + "' is not a number";
      if (!std::isfinite(v)) return "'" + input + "' is not finite; expected a finite number";
      return std::string();
    },
    "FINITE");

const CLI::Validator kNonZero(
    [](std::string& input) {
      double v = 0;
      if (!CLI::detail::lexical_cast(input, v)) return "'" + input + "' is not a number";
      if (v == 0.0) return std::string("must be nonzero");
      return std::string();
    },
    "NONZERO");

CLI::Option* add_threads_option(CLI::App& cmd, int& threads) {
  return cmd
      .add_option("--threads", threads,
                  "Threads for each training epoch of CSympNet-ID with d > 1 (other models train "
                  "on one); results are identical for any value (default 1)")
      ->check(CLI::Range(1, ThreadTeam::kMaxThreads));
}

void SystemOverrides::add_to(CLI::App& cmd) {
  cmd.add_option("--d", d, "Degrees of freedom (overrides the preset)")
      ->check(CLI::Range(1, 100000));
  cmd.add_option("--gamma", gamma, "Damping rate gamma >= 0 (default 0.05)")
      ->check(kFiniteNumber)
      ->check(CLI::NonNegativeNumber);
  cmd.add_option("--omega", omega, "Frequency omega > 0 (oscillator, cubic)")
      ->check(kFiniteNumber)
      ->check(CLI::PositiveNumber);
  cmd.add_option("--k", k, "Spring stiffness k >= 0 (chain)")
      ->check(kFiniteNumber)
      ->check(CLI::NonNegativeNumber);
  cmd.add_option("--alpha", alpha, "Cubic coefficient alpha (cubic)")->check(kFiniteNumber);
}

void SystemOverrides::apply(Preset& p) const {
  if (d) p.system.d = *d;
  if (gamma) p.system.gamma = *gamma;
  if (omega) p.system.omega = *omega;
  if (k) p.system.k = *k;
  if (alpha) p.system.alpha = *alpha;
}

}  // namespace csympnet::cli
