#include "core_option.hpp"

#include <stdexcept>

#include "csympnet/core/error.hpp"

namespace csympnet::cli {

// "la:L:m", "la:L:m:h2" (LA with step polynomials), "g:L:w", or "library" (the
// Hamiltonian-library core with its terms selected from the data: `fit` only), or a library
// core as JSON ({"type": "library", "terms": [...]}, with "inputs" for a driven record), which
// the identification checks.
nlohmann::json parse_core(const std::string& s) {
  if (s == "library") return {{"type", "library"}};
  if (!s.empty() && s.front() == '{') {
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(s);
    } catch (const nlohmann::json::exception&) {
      throw Error("--core '" + s +
                  "': not valid JSON; expected an object such as "
                  "{\"type\": \"library\", \"terms\": [\"q1^2\", \"q1^4\"]}");
    }
    if (!j.is_object() || j.value("type", "") != "library")
      throw Error("--core '" + s + "': a JSON core must be {\"type\": \"library\", ...}");
    return j;
  }
  const std::string expected =
      "expected la:LAYERS:SUBLAYERS[:h2], g:LAYERS:WIDTH or library, e.g. la:5:20 or la:5:20:h2";
  const auto c1 = s.find(':');
  const auto c2 = c1 == std::string::npos ? c1 : s.find(':', c1 + 1);
  if (c2 == std::string::npos) throw Error("--core '" + s + "': " + expected);
  const auto c3 = s.find(':', c2 + 1);
  const std::string type = s.substr(0, c1);
  const std::string suffix = c3 == std::string::npos ? "" : s.substr(c3 + 1);
  int a = 0, b = 0;
  try {
    std::size_t pa = 0, pb = 0;
    const std::string sa = s.substr(c1 + 1, c2 - c1 - 1);
    const std::string sb = s.substr(c2 + 1, c3 == std::string::npos ? c3 : c3 - c2 - 1);
    a = std::stoi(sa, &pa);
    b = std::stoi(sb, &pb);
    if (pa != sa.size() || pb != sb.size()) throw std::invalid_argument("trailing text");
  } catch (const std::exception&) {
    throw Error("--core '" + s + "': " + expected);
  }
  if (a < 1 || b < 1) throw Error("--core '" + s + "': sizes must be >= 1; " + expected);
  if (c3 != std::string::npos && (type != "la" || suffix != "h2"))
    throw Error("--core '" + s + "': the only suffix is ':h2', on la cores; " + expected);
  if (type == "la") {
    nlohmann::json core = {{"type", "la"}, {"layers", a}, {"sublayers", b}};
    if (suffix == "h2") core["step_terms"] = 2;
    return core;
  }
  if (type == "g") return {{"type", "g"}, {"layers", a}, {"width", b}};
  throw Error("--core '" + s + "': unknown core type '" + type + "'; " + expected);
}

const CLI::Validator kCoreSpec(
    [](std::string& input) {
      try {
        parse_core(input);
      } catch (const Error& e) {
        // parse_core says "--core 'S': ..."; CLI11 prefixes the option name itself.
        const std::string what = e.what(), prefix = "--core ";
        return what.rfind(prefix, 0) == 0 ? what.substr(prefix.size()) : what;
      }
      return std::string();
    },
    "la:L:m[:h2]|g:L:w|library");

}  // namespace csympnet::cli
