#include "system_options.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <string_view>
#include <system_error>

#include "csympnet/core/error.hpp"
#include "csympnet/core/thread_team.hpp"
#include "csympnet/data/csv.hpp"
#include "csympnet/train/trainer.hpp"
#include "kernels/registry.hpp"

namespace csympnet::cli {

const CLI::Validator kFiniteNumber(
    [](std::string& input) {
      double v = 0;
      if (!CLI::detail::lexical_cast(input, v))
        return "'" + input + "' is not a number; expected a finite number";
      if (!std::isfinite(v)) return "'" + input + "' is not finite; expected a finite number";
      return std::string();
    },
    "");

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

// Digits beyond a long's range are left to the option's range check, which follows every use
// and names the range the option really has (not 9223372036854775807).
const CLI::Validator kWholeNumber(
    [](std::string& input) {
      const std::string why =
          whole_number_error(input, 18446744073709551615ULL, "a whole number such as 100");
      return why.find("the largest allowed") != std::string::npos ? std::string() : why;
    },
    "");

const CLI::Validator kSeed(
    [](std::string& input) {
      return whole_number_error(input, 18446744073709551615ULL,
                                "a seed from 0 to 18446744073709551615");
    },
    "");

namespace {
std::string range_text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.15g", v);
  return buf;
}

// Checks a number against [lo, hi] (either end may be infinite); `expected` says what is.
CLI::Validator bounded(double lo, double hi, bool lo_open, std::string expected) {
  return CLI::Validator(
      [=](std::string& input) {
        double v = 0;
        if (!CLI::detail::lexical_cast(input, v))
          return "'" + input + "' is not a number; expected " + expected;
        const bool ok = (lo_open ? v > lo : v >= lo) && v <= hi;  // false for NaN
        return ok ? std::string() : "'" + input + "' is out of range; expected " + expected;
      },
      expected);
}
}  // namespace

CLI::Validator in_range(double lo, double hi) {
  return bounded(lo, hi, false, "a number from " + range_text(lo) + " to " + range_text(hi));
}

CLI::Option* add_columns_option(CLI::App& cmd, std::string& spec) {
  return cmd
      .add_option("--columns", spec,
                  "The data file's own column names for the columns csympnet reads, e.g. "
                  "t=time_s,q1=angle,p1=velocity (traj, t, h, q1..qd, p1..pd, next_q1.., "
                  "next_p1..); other columns are ignored (default: the header must be "
                  "csympnet's own, docs/data-formats.md)")
      ->type_name("MAP")
      ->check(CLI::Validator(
          [](std::string& input) {
            try {
              parse_column_map(input, "");
            } catch (const Error& e) {
              std::string why = e.what();
              return why.rfind(": ", 0) == 0 ? why.substr(2) : why;
            }
            return std::string();
          },
          ""));
}

const OptionSpelling& cli_spelling() {
  static const OptionSpelling s{[](const std::string& key) -> std::string {
                                  if (key == "decay_damping")
                                    return "--no-beta-decay";  // a flag that turns it off
                                  if (key == "normalize") return "--no-normalize";
                                  std::string name = "--" + key;
                                  std::replace(name.begin(), name.end(), '_', '-');
                                  return name;
                                },
                                [](const std::string& key, const std::string& value) {
                                  return cli_spelling().name(key) + " " + value;
                                }};
  return s;
}

namespace {
// The library's problem with the value, as CLI11 wants it from a validator: without the
// option's name, which CLI11 puts in front.
template <class Check>
std::string library_says(Check&& check) {
  try {
    check();
  } catch (const OptionError& e) {
    return e.problem(cli_spelling());
  }
  return std::string();
}
}  // namespace

CLI::Validator library_range(const OptionRange& range) {
  return CLI::Validator(
      [range](std::string& input) {
        if (range.whole) {
          // kWholeNumber has checked the digits; a long holds them.
          long v = 0;
          if (!CLI::detail::lexical_cast(input, v))
            return "'" + input + "' is out of range; expected " + range.expected();
          return library_says([&] { range.check(v, input); });
        }
        double v = 0;
        if (!CLI::detail::lexical_cast(input, v))
          return "'" + input + "' is not a number; expected " + range.expected();
        return library_says([&] { range.check(v, input); });
      },
      range.expected());
}

CLI::Validator library_nonzero(const char* key) {
  return CLI::Validator(
      [key](std::string& input) {
        double v = 0;
        if (!CLI::detail::lexical_cast(input, v))
          return "'" + input + "' is not a number; expected a nonzero number";
        return library_says([&] { check_nonzero(key, v, input); });
      },
      "NONZERO");
}

const CLI::Validator kNonNegative =
    bounded(0.0, std::numeric_limits<double>::infinity(), false, "a number >= 0");
const CLI::Validator kPositive =
    bounded(0.0, std::numeric_limits<double>::infinity(), true, "a number > 0");

const CLI::Validator kStep(
    [](std::string& input) {
      double v = 0;
      if (!CLI::detail::lexical_cast(input, v) || !(v > 0.0) || !std::isfinite(v))
        return "'" + input + "' is not a step; expected a finite number > 0";
      if (v < std::numeric_limits<double>::min())
        return "'" + input +
               "' is below the smallest normal double (2.2e-308), where steps lose their "
               "digits; expected a larger step (rescale time)";
      return std::string();
    },
    "STEP");

CLI::Validator one_of(const std::vector<std::string>& names) {
  std::string list;
  for (const std::string& n : names) list += (list.empty() ? "" : ", ") + n;
  return CLI::Validator(
      [names, list](std::string& input) {
        for (const std::string& n : names)
          if (input == n) return std::string();
        return "'" + input + "' is not a choice; expected one of " + list;
      },
      "{" + list + "}");
}

namespace {
std::string existing(const std::string& path, bool directory) {
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  const char* what = directory ? "an existing directory" : "an existing file";
  if (path.empty()) return std::string("the path is empty; expected ") + what;
  // A loop of symbolic links, a component that is a file, a directory that may not be
  // searched: the system's reason, not "does not exist".
  if (ec && ec != std::errc::no_such_file_or_directory)
    return "'" + path + "' cannot be reached: " + ec.message() + "; expected " + what;
  if (ec || !std::filesystem::exists(st)) return "'" + path + "' does not exist; expected " + what;
  if (directory != std::filesystem::is_directory(st))
    return "'" + path + "' is " + (directory ? "not a directory" : "a directory") + "; expected " +
           what;
  return std::string();
}
}  // namespace

const CLI::Validator kExistingFile([](std::string& s) { return existing(s, false); }, "FILE");
const CLI::Validator kExistingDirectory([](std::string& s) { return existing(s, true); }, "DIR");
const CLI::Validator kInputFile(
    [](std::string& s) { return s == "-" ? std::string() : existing(s, false); }, "FILE|-");
const CLI::Validator kOutputPath(
    [](std::string& s) {
      return s.empty() ? std::string("the path is empty; expected a file or directory name")
                       : std::string();
    },
    "PATH");

CLI::Option* add_threads_option(CLI::App& cmd, int& threads) {
  return cmd
      .add_option("--threads", threads,
                  "Threads for each training epoch of CSympNet-ID with d > 1 (other models train "
                  "on one); results are identical for any value (default 1)")
      ->check(kWholeNumber)
      ->check(library_range(kThreadsRange));
}

CLI::Option* add_arithmetic_option(CLI::App& cmd) {
  return cmd
      .add_option_function<std::string>(
          "--arithmetic",
          [](const std::string& v) {
            kernels::set_arithmetic(kernels::parse_arithmetic(v, "--arithmetic"));
          },
          std::string("Arithmetic of the SympNet cores' matrix products: sse2 (Eigen's SSE2 "
                      "order) or fma (one fused multiply-add chain per entry: the same bits on "
                      "every CPU); overrides CSYMPNET_ARITHMETIC (default: ") +
              kernels::to_string(kernels::kDefaultArithmetic) + ")")
      ->check(CLI::IsMember({"sse2", "fma"}));
}

void SystemOverrides::add_to(CLI::App& cmd) {
  cmd.add_option("--d", d, "Degrees of freedom (overrides the preset)")
      ->check(kWholeNumber)
      ->check(in_range(1, 100000));
  cmd.add_option("--gamma", gamma,
                 "Damping rate gamma >= 0 of the preset's system (default: the preset's own, "
                 "0.05 for all five)")
      ->check(kFiniteNumber)
      ->check(kNonNegative);
  cmd.add_option("--omega", omega, "Frequency omega > 0 (oscillator, cubic; default: the preset's)")
      ->check(kFiniteNumber)
      ->check(kPositive);
  cmd.add_option("--k", k, "Spring stiffness k >= 0 (chain; default: the preset's)")
      ->check(kFiniteNumber)
      ->check(kNonNegative);
  cmd.add_option("--alpha", alpha, "Cubic coefficient alpha (cubic; default: the preset's)")
      ->check(kFiniteNumber);
}

void SystemOverrides::apply(Preset& p) const {
  if (d) p.system.d = *d;
  if (gamma) p.system.gamma = *gamma;
  if (omega) p.system.omega = *omega;
  if (k) p.system.k = *k;
  if (alpha) p.system.alpha = *alpha;
}

}  // namespace csympnet::cli
