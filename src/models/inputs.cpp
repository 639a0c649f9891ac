#include "csympnet/models/inputs.hpp"

#include "csympnet/core/error.hpp"

namespace csympnet {

std::string hold_name(InputHold hold) {
  return hold == InputHold::kZero ? "zoh" : "foh";
}

InputHold parse_hold(const std::string& text, const std::string& where) {
  if (text == "foh") return InputHold::kFirst;
  if (text == "zoh") return InputHold::kZero;
  throw Error(where + ": hold '" + text +
              "', expected \"foh\" (first-order hold: the input interpolated linearly between "
              "samples) or \"zoh\" (zero-order hold: held at each sample's value)");
}

InputSpec read_input_spec(const nlohmann::json& v, const std::string& where) {
  const std::string at = where + ".inputs";
  require(v.is_object(), [&] {
    return at + " = " + v.dump() + ", expected an object {\"m\": 1, \"hold\": \"foh\"}";
  });
  for (const auto& item : v.items())
    require(item.key() == "m" || item.key() == "hold" || item.key() == "B", [&] {
      return at + ": unknown key '" + item.key() + "'; expected only the keys m, hold, B";
    });
  require(v.contains("m") && v.at("m").is_number_integer() && v.at("m").get<long long>() >= 1 &&
              v.at("m").get<long long>() <= 1000,
          [&] { return at + ": key 'm' must be an integer from 1 to 1000 (the input channels)"; });
  InputSpec s;
  s.m = static_cast<Index>(v.at("m").get<long long>());
  if (v.contains("hold")) {
    require(v.at("hold").is_string(),
            [&] { return at + ": key 'hold' = " + v.at("hold").dump() + ", expected a string"; });
    s.hold = parse_hold(v.at("hold").get<std::string>(), at);
  }
  if (v.contains("B"))
    require(v.at("B") == "row-major", [&] {
      return at + ": key 'B' = " + v.at("B").dump() +
             ", expected \"row-major\" (B, d x m, in params row by row after the dissipation "
             "rates)";
    });
  return s;
}

nlohmann::json input_spec_json(const InputSpec& spec) {
  return {{"m", spec.m}, {"hold", hold_name(spec.hold)}, {"B", "row-major"}};
}

}  // namespace csympnet
