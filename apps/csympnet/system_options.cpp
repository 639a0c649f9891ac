#include "system_options.hpp"

#include <charconv>
#include <cmath>
#include <string_view>
#include <system_error>

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

// Digits only (an optional leading '+'), parsed exactly: CLI11's own messages for these
// ("Value abc not in range", a seed of 2^64 silently clamped) say neither what was wrong nor
// what was expected.
namespace {
std::string whole_number_error(const std::string& input, unsigned long long max, const char* what) {
  std::string_view v = input;
  if (!v.empty() && v.front() == '+') v.remove_prefix(1);
  if (!v.empty() && v.front() == '-') return "'" + input + "' is negative; expected " + what;
  unsigned long long out = 0;
  const auto [ptr, ec] = std::from_chars(v.data(), v.data() + v.size(), out);
  if (v.empty() || ptr != v.data() + v.size() ||
      (ec != std::errc() && ec != std::errc::result_out_of_range))
    return "'" + input + "' is not a whole number; expected " + what;
  if (ec == std::errc::result_out_of_range || out > max)
    return "'" + input + "' is above " + std::to_string(max) + ", the largest allowed; expected " +
           what;
  return std::string();
}
}  // namespace

const CLI::Validator kWholeNumber(
    [](std::string& input) {
      return whole_number_error(input, 9223372036854775807ULL, "a whole number such as 100");
    },
    "INT");

const CLI::Validator kSeed(
    [](std::string& input) {
      return whole_number_error(input, 18446744073709551615ULL,
                                "a seed from 0 to 18446744073709551615");
    },
    "SEED");

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
      ->check(kWholeNumber)
      ->check(CLI::Range(1, ThreadTeam::kMaxThreads));
}

void SystemOverrides::add_to(CLI::App& cmd) {
  cmd.add_option("--d", d, "Degrees of freedom (overrides the preset)")
      ->check(kWholeNumber)
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
