#include "csympnet/io/json_text.hpp"

#include <set>
#include <vector>

#include "csympnet/core/error.hpp"

namespace csympnet {

nlohmann::json parse_json_text(const std::string& text, const std::string& where,
                               const std::string& expected) {
  using json = nlohmann::json;
  // One set of keys per object being read; arrays get an empty placeholder so the stack
  // follows the nesting.
  std::vector<std::set<std::string>> open;
  std::vector<bool> is_object;
  std::string repeated;
  const json::parser_callback_t watch = [&](int, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start:
        open.emplace_back();
        is_object.push_back(true);
        break;
      case json::parse_event_t::array_start:
        open.emplace_back();
        is_object.push_back(false);
        break;
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        if (!open.empty()) {
          open.pop_back();
          is_object.pop_back();
        }
        break;
      case json::parse_event_t::key:
        if (!open.empty() && is_object.back() && parsed.is_string() &&
            !open.back().insert(parsed.get<std::string>()).second && repeated.empty())
          repeated = parsed.get<std::string>();
        break;
      case json::parse_event_t::value:
        break;
    }
    return true;
  };
  json doc;
  try {
    doc = json::parse(text, watch);
  } catch (const json::exception& e) {  // parse_error, or out_of_range for a number like 1e999
    throw Error(where + ": not valid JSON (" + printable(std::string(e.what()).substr(0, 200)) +
                "); expected " + expected);
  }
  if (!repeated.empty())
    throw Error(where + ": key '" + printable(repeated.substr(0, 100)) +
                "' appears twice in one object; expected each key once in " + expected);
  return doc;
}

}  // namespace csympnet
