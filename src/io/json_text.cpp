#include "csympnet/io/json_text.hpp"

#include <new>
#include <set>
#include <vector>

#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"

namespace csympnet {

nlohmann::json parse_json_text(const std::string& text, const std::string& where,
                               const std::string& expected, const JsonLimits& limits) {
  using json = nlohmann::json;
  // One set of keys per object being read; arrays get an empty placeholder so the stack
  // follows the nesting.
  std::vector<std::set<std::string>> open;
  std::vector<bool> is_object;
  std::string repeated;
  std::string top_key;  // the key of the top-level object being read
  std::size_t bulk = 0, other = 0, events = 0;
  const auto too_deep = [&](int depth) {
    if (static_cast<std::size_t>(depth) >= limits.max_depth)
      throw Error(where + ": nested deeper than " + std::to_string(limits.max_depth) +
                  " levels of objects and arrays; expected " + expected);
  };
  const json::parser_callback_t watch = [&](int depth, json::parse_event_t event, json& parsed) {
    if ((++events & 0xFFFF) == 0) throw_if_stop_requested("reading " + where);
    switch (event) {
      case json::parse_event_t::object_start:
        too_deep(depth);
        open.emplace_back();
        is_object.push_back(true);
        break;
      case json::parse_event_t::array_start:
        too_deep(depth);
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
        if (depth == 1 && parsed.is_string()) top_key = parsed.get<std::string>();
        if (!open.empty() && is_object.back() && parsed.is_string() &&
            !open.back().insert(parsed.get<std::string>()).second && repeated.empty())
          repeated = parsed.get<std::string>();
        break;
      case json::parse_event_t::value:
        if (depth == 2 && !limits.bulk_key.empty() && top_key == limits.bulk_key) {
          if (++bulk > limits.max_bulk_values)
            throw Error(where + ": \"" + limits.bulk_key + "\" holds more than " +
                        std::to_string(limits.max_bulk_values) + " values; expected at most " +
                        std::to_string(limits.max_bulk_values) + " in " + expected);
        } else if (++other > limits.max_other_values) {
          throw Error(
              where + ": holds more than " + std::to_string(limits.max_other_values) + " values" +
              (limits.bulk_key.empty() ? std::string() : " outside \"" + limits.bulk_key + "\"") +
              "; expected at most " + std::to_string(limits.max_other_values) + " in " + expected);
        }
        break;
    }
    return true;
  };
  json doc;
  try {
    doc = json::parse(text, watch);
  } catch (const std::bad_alloc&) {
    throw Error(where + ": not enough memory to read it (" + std::to_string(text.size()) +
                " bytes); expected " + expected + " that fits in memory");
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
