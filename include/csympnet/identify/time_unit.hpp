// The unit of a record's clock: named by the user (`fit --time-unit ms`, Python's time_unit=)
// or recognised from the time column's name (t_ms, time_ms, timestamp_s, t[s], t (ms)). It
// changes only how γ̂ is reported, never the fit: the fit is in the data's own time units, and
// the report adds γ̂, its interval and the amplitude decay rate γ̂/2 per second.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace csympnet {

struct TimeUnit {
  std::string name;      // "s", "ms", "us", "ns", "min" or "h"
  double seconds = 1.0;  // seconds in one unit
  std::string source;    // "--time-unit", "time_unit", or "column 't_ms'"
};

// The accepted names, in the order the help lists them.
const std::vector<std::string>& time_unit_names();
// The unit of that name; an OptionError with key "time_unit" for any other text.
TimeUnit parse_time_unit(std::string_view name, std::string source);
// The unit a time column's name states, as a suffix or a bracketed part after a time word
// (t_ms, time_ms, timestamp_s, t[s], t (ms), Time_US); none for "t", "time" or anything else.
std::optional<TimeUnit> time_unit_of_column(std::string_view column);

// The "time_unit" object of an identification's report (identify_report: its identified,
// gamma_hat, gamma_ci_low and gamma_ci_high): {"unit", "seconds_per_unit", "source",
// "gamma_per_s", "gamma_ci_per_s", "amplitude_decay_rate_per_s"}, the rates null unless γ̂ is
// identified; null when the unit is not known (the rates are then per time unit of the data).
nlohmann::json time_unit_report(const std::optional<TimeUnit>& unit,
                                const nlohmann::json& identify_report);

}  // namespace csympnet
