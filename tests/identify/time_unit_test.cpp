// The clock's unit: parsed, read from a time column's name, and reported beside γ̂ per second.
#include "csympnet/identify/time_unit.hpp"

#include <gtest/gtest.h>

#include "csympnet/core/options.hpp"

namespace csympnet {
namespace {

TEST(TimeUnit, ParsesTheNamedUnitsAndRefusesOthers) {
  EXPECT_EQ(parse_time_unit("ms", "--time-unit").seconds, 1e-3);
  EXPECT_EQ(parse_time_unit("h", "--time-unit").seconds, 3600.0);
  EXPECT_EQ(parse_time_unit("min", "x").source, "x");
  try {
    parse_time_unit("fortnight", "--time-unit");
    FAIL() << "accepted a fortnight";
  } catch (const OptionError& e) {
    EXPECT_EQ(e.key(), "time_unit");
    EXPECT_NE(std::string(e.what()).find("s, ms, us, ns, min, h"), std::string::npos) << e.what();
  }
}

TEST(TimeUnit, IsReadFromATimeColumnsName) {
  for (const auto& [name, unit] :
       std::vector<std::pair<std::string, std::string>>{{"t_ms", "ms"},
                                                        {"time_ms", "ms"},
                                                        {"timestamp_s", "s"},
                                                        {"t[s]", "s"},
                                                        {"t (ms)", "ms"},
                                                        {"Time_US", "us"},
                                                        {"time_min", "min"},
                                                        {"t_h", "h"},
                                                        {"time_seconds", "s"}}) {
    const std::optional<TimeUnit> u = time_unit_of_column(name);
    ASSERT_TRUE(u.has_value()) << name;
    EXPECT_EQ(u->name, unit) << name;
    EXPECT_EQ(u->source, "column '" + name + "'");
  }
  for (const char* none : {"t", "time", "theta", "tms", "time_utc", "timestamp", "x_ms"})
    EXPECT_FALSE(time_unit_of_column(none).has_value()) << none;
}

TEST(TimeUnit, ReportGivesGammaPerSecondAndTheAmplitudeDecayRate) {
  const nlohmann::json report = {{"identified", true},
                                 {"gamma_hat", 4.879e-05},
                                 {"gamma_ci_low", 4.8e-05},
                                 {"gamma_ci_high", 5.0e-05}};
  const nlohmann::json j = time_unit_report(parse_time_unit("ms", "--time-unit"), report);
  EXPECT_EQ(j["unit"], "ms");
  EXPECT_EQ(j["source"], "--time-unit");
  EXPECT_DOUBLE_EQ(j["gamma_per_s"].get<double>(), 0.04879);
  EXPECT_DOUBLE_EQ(j["amplitude_decay_rate_per_s"].get<double>(), 0.024395);
  EXPECT_DOUBLE_EQ(j["gamma_ci_per_s"][1].get<double>(), 0.05);
  EXPECT_TRUE(j["modes_per_s"].empty());
  EXPECT_TRUE(time_unit_report(std::nullopt, report).is_null());
  // The modes' angular frequencies in rad/s: a rate per ms is a thousand per s.
  nlohmann::json with_modes = report;
  with_modes["modes"] = {
      {"list",
       {{{"angular_frequency", 0.004}, {"angular_frequency_interval", {0.0039, 0.0041}}},
        {{"angular_frequency", 0.0026}, {"angular_frequency_interval", nullptr}}}}};
  const nlohmann::json m = time_unit_report(parse_time_unit("ms", "x"), with_modes);
  ASSERT_EQ(m["modes_per_s"].size(), 2u);
  EXPECT_DOUBLE_EQ(m["modes_per_s"][0]["angular_frequency_per_s"].get<double>(), 4.0);
  EXPECT_DOUBLE_EQ(m["modes_per_s"][0]["angular_frequency_interval_per_s"][1].get<double>(), 4.1);
  EXPECT_DOUBLE_EQ(m["modes_per_s"][1]["angular_frequency_per_s"].get<double>(), 2.6);
  EXPECT_TRUE(m["modes_per_s"][1]["angular_frequency_interval_per_s"].is_null());
  nlohmann::json not_identified = report;
  not_identified["identified"] = false;
  const nlohmann::json n = time_unit_report(parse_time_unit("s", "x"), not_identified);
  EXPECT_TRUE(n["gamma_per_s"].is_null());
  EXPECT_TRUE(n["gamma_ci_per_s"].is_null());
  EXPECT_EQ(n["unit"], "s");
}

}  // namespace
}  // namespace csympnet
