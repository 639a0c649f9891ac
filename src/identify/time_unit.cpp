#include "csympnet/identify/time_unit.hpp"

#include <cctype>

#include "csympnet/core/options.hpp"

namespace csympnet {

namespace {

struct Known {
  const char* name;
  double seconds;
};
// Other spellings of the same units, as column names write them.
constexpr Known kUnits[] = {{"s", 1.0},   {"ms", 1e-3},  {"us", 1e-6},
                            {"ns", 1e-9}, {"min", 60.0}, {"h", 3600.0}};
constexpr std::pair<const char*, const char*> kAliases[] = {
    {"sec", "s"},       {"secs", "s"},    {"second", "s"}, {"seconds", "s"},
    {"msec", "ms"},     {"millis", "ms"}, {"µs", "us"},    {"usec", "us"},
    {"micros", "us"},   {"nsec", "ns"},   {"mins", "min"}, {"minute", "min"},
    {"minutes", "min"}, {"hr", "h"},      {"hours", "h"},  {"hour", "h"}};

std::string lower(std::string_view s) {
  std::string out;
  for (char c : s) out += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::optional<TimeUnit> known(std::string_view name) {
  std::string n = lower(name);
  for (const auto& [alias, unit] : kAliases)
    if (n == alias) n = unit;
  for (const Known& k : kUnits)
    if (n == k.name) return TimeUnit{k.name, k.seconds, ""};
  return std::nullopt;
}

}  // namespace

const std::vector<std::string>& time_unit_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> v;
    for (const Known& k : kUnits) v.emplace_back(k.name);
    return v;
  }();
  return names;
}

TimeUnit parse_time_unit(std::string_view name, std::string source) {
  for (const Known& k : kUnits)
    if (name == k.name) return TimeUnit{k.name, k.seconds, std::move(source)};
  std::string list;
  for (const std::string& n : time_unit_names()) list += (list.empty() ? "" : ", ") + n;
  throw OptionError("time_unit", "'" + std::string(name.substr(0, 40)) +
                                     "' is not a unit of time; expected one of " + list);
}

std::optional<TimeUnit> time_unit_of_column(std::string_view column) {
  // Split "timestamp_s", "t[s]", "t (ms)" into a time word and what follows it.
  const std::string c = lower(column);
  std::size_t word_end = 0;
  while (word_end < c.size() && std::isalpha(static_cast<unsigned char>(c[word_end]))) ++word_end;
  const std::string word = c.substr(0, word_end);
  if (word != "t" && word != "time" && word != "timestamp" && word != "times") return std::nullopt;
  std::string rest = c.substr(word_end);
  std::string unit;
  for (char ch : rest)
    if (ch != '_' && ch != ' ' && ch != '[' && ch != ']' && ch != '(' && ch != ')' && ch != '-' &&
        ch != '/')
      unit += ch;
  if (unit.empty() || rest.empty()) return std::nullopt;
  std::optional<TimeUnit> u = known(unit);
  if (u) u->source = "column '" + std::string(column.substr(0, 40)) + "'";
  return u;
}

nlohmann::json time_unit_report(const std::optional<TimeUnit>& unit,
                                const nlohmann::json& identify_report) {
  if (!unit) return nullptr;
  const bool identified = identify_report.value("identified", false);
  const auto per_s = [&](const char* key) -> nlohmann::json {
    const nlohmann::json& v = identify_report.value(key, nlohmann::json());
    return identified && v.is_number() ? nlohmann::json(v.get<double>() / unit->seconds)
                                       : nlohmann::json(nullptr);
  };
  const nlohmann::json g = per_s("gamma_hat"), lo = per_s("gamma_ci_low"),
                       hi = per_s("gamma_ci_high");
  // Each mode's angular frequency in rad/s (a damping ratio has no unit).
  nlohmann::json modes = nlohmann::json::array();
  const nlohmann::json& listed =
      identify_report.contains("modes") && identify_report.at("modes").is_object()
          ? identify_report.at("modes").value("list", nlohmann::json())
          : nlohmann::json();
  if (listed.is_array())
    for (const nlohmann::json& m : listed) {
      const auto scaled = [&](const nlohmann::json& v) -> nlohmann::json {
        return v.is_number() ? nlohmann::json(v.get<double>() / unit->seconds)
                             : nlohmann::json(nullptr);
      };
      nlohmann::json iv = nullptr;
      if (m.contains("angular_frequency_interval") &&
          m.at("angular_frequency_interval").is_array() &&
          m.at("angular_frequency_interval").size() == 2)
        iv = {scaled(m.at("angular_frequency_interval")[0]),
              scaled(m.at("angular_frequency_interval")[1])};
      modes.push_back(
          {{"angular_frequency_per_s", scaled(m.value("angular_frequency", nlohmann::json()))},
           {"angular_frequency_interval_per_s", iv}});
    }
  return {{"unit", unit->name},
          {"seconds_per_unit", unit->seconds},
          {"source", unit->source},
          {"gamma_per_s", g},
          {"gamma_ci_per_s", lo.is_null() || hi.is_null() ? nlohmann::json(nullptr)
                                                          : nlohmann::json::array({lo, hi})},
          {"amplitude_decay_rate_per_s",
           g.is_null() ? nlohmann::json(nullptr) : nlohmann::json(g.get<double>() / 2.0)},
          {"modes_per_s", modes}};
}

}  // namespace csympnet
