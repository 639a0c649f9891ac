#include "csympnet/core/options.hpp"

#include <cmath>
#include <cstdio>
#include <limits>

namespace csympnet {

const OptionSpelling& key_spelling() {
  static const OptionSpelling s{
      [](const std::string& key) { return key; },
      [](const std::string& key, const std::string& value) { return key + " = " + value; }};
  return s;
}

namespace {
// `problem` with {key} → spelling.name(key) and {key=value} → spelling.given(key, value).
std::string spelt(const std::string& problem_, const OptionSpelling& spelling) {
  std::string out;
  std::size_t i = 0;
  while (i < problem_.size()) {
    const std::size_t open = problem_.find('{', i);
    const std::size_t close = open == std::string::npos ? open : problem_.find('}', open);
    if (close == std::string::npos) {
      out += problem_.substr(i);
      break;
    }
    out += problem_.substr(i, open - i);
    const std::string ref = problem_.substr(open + 1, close - open - 1);
    const std::size_t eq = ref.find('=');
    out += eq == std::string::npos ? spelling.name(ref)
                                   : spelling.given(ref.substr(0, eq), ref.substr(eq + 1));
    i = close + 1;
  }
  return out;
}
}  // namespace

// what() is the message in the library's own spelling, for a C++ caller.
OptionError::OptionError(std::string key, std::string problem)
    : Error(key + ": " + spelt(problem, key_spelling())),
      key_(std::move(key)),
      problem_(std::move(problem)) {}

std::string OptionError::problem(const OptionSpelling& spelling) const {
  return spelt(problem_, spelling);
}

std::string OptionError::message(const OptionSpelling& spelling) const {
  return spelling.name(key_) + ": " + problem(spelling);
}

namespace {
// Plain digits for a range's ends (1e-12, 0.99, 100000000), as the CLI always wrote them.
std::string end_text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.15g", v);
  return buf;
}
}  // namespace

bool OptionRange::accepts(double v) const {
  if (zero_means != nullptr && v == 0.0) return true;
  if (!std::isfinite(v) || (whole && v != std::floor(v))) return false;
  return (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);  // false for NaN
}

std::string OptionRange::expected() const {
  std::string range;
  if (std::isinf(hi)) {
    range = std::string("a number ") + (lo_open ? "> " : ">= ") + end_text(lo);
  } else if (!lo_open && !hi_open) {
    range = "a number from " + end_text(lo) + " to " + end_text(hi);
  } else {
    range = std::string("a number ") + (lo_open ? "> " : ">= ") + end_text(lo) +
            (hi_open ? " and < " : " and <= ") + end_text(hi);
  }
  if (zero_means != nullptr) range = std::string("0 (") + zero_means + ") or " + range;
  return range;
}

namespace {
std::string out_of_range(const OptionRange& r, const std::string& value) {
  return "'" + value + "' is out of range; expected " + r.expected() +
         (r.why != nullptr ? std::string(": ") + r.why : std::string());
}
}  // namespace

void OptionRange::check(double v, const std::string& written) const {
  if (accepts(v)) return;
  throw OptionError(key, out_of_range(*this, written.empty() ? number_text(v) : written));
}

void OptionRange::check(long v, const std::string& written) const {
  if (zero_means != nullptr && v == 0) return;
  // A long beyond 2^53 rounds as a double: the ends are compared as longs too.
  if (accepts(static_cast<double>(v)) && v >= static_cast<long>(std::ceil(lo)) &&
      v <= static_cast<long>(std::floor(hi)))
    return;
  throw OptionError(key, out_of_range(*this, written.empty() ? std::to_string(v) : written));
}

void check_nonzero(const char* key, double v, const std::string& written) {
  const std::string text = written.empty() ? number_text(v) : written;
  if (!std::isfinite(v))
    throw OptionError(key, "'" + text + "' is not finite; expected a finite nonzero number");
  if (v == 0.0) throw OptionError(key, "'" + text + "' is zero; expected a nonzero number");
}

std::size_t choice_index(const char* key, const std::vector<std::string>& names,
                         const std::string& text) {
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == text) return i;
  std::string list;
  for (const std::string& n : names) list += (list.empty() ? "" : ", ") + n;
  throw OptionError(key, "'" + text + "' is not a choice; expected one of " + list);
}

}  // namespace csympnet
