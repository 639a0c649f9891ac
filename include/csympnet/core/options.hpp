// Refusing an option by the name its user wrote.
//
// The library checks every option's range, and the rules between options, itself (each
// config's validate(), and the builders make_fit_config / make_identify_config): the CLI and
// Python only check what they alone can (that a command-line word is a number, that a Python
// object is an int). An option the library refuses is refused with an OptionError that
// carries the option's key ("val_fraction") and the problem; each front end writes the key
// its own way (OptionSpelling): "--val-fraction" on the command line, "val_fraction" in
// Python. See docs/architecture.md, "Options".
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "csympnet/core/error.hpp"

namespace csympnet {

// How a front end writes an option: its name ("--refine", "refine"), and the option given a
// value ("--refine lm", 'refine="lm"').
struct OptionSpelling {
  std::function<std::string(const std::string& key)> name;
  std::function<std::string(const std::string& key, const std::string& value)> given;
};
// The library's own spelling: the key itself, and "key = value". what() of an OptionError
// uses it.
const OptionSpelling& key_spelling();

// An option refused by the library. `problem` says what was wrong and what was expected; it
// may name other options as {key} or {key=value}, which message() spells as the front end
// does (so "needs {refine=lm}" reads "needs --refine lm" on the command line).
class OptionError : public Error {
 public:
  OptionError(std::string key, std::string problem);
  const std::string& key() const noexcept { return key_; }
  // The problem with the options it names spelt by `spelling`.
  std::string problem(const OptionSpelling& spelling) const;
  // "<the option>: <the problem>".
  std::string message(const OptionSpelling& spelling) const;

 private:
  std::string key_, problem_;
};

// A numeric option's accepted values: lo <= v <= hi (either end strict when open), or a
// whole number in that range. The one place an option's range is written: the library's
// validate() checks with it, and the CLI shows expected() in its help and checks each value
// with it while parsing.
struct OptionRange {
  const char* key;
  double lo, hi;
  bool whole = false;    // a whole number (checked as a long)
  bool lo_open = false;  // v > lo rather than v >= lo
  bool hi_open = false;  // v < hi rather than v <= hi
  // When set, 0 is accepted too and means this ("off", "automatic").
  const char* zero_means = nullptr;
  // When set, said after the expected range when a value is refused: why it is the range.
  const char* why = nullptr;

  bool accepts(double v) const;
  // "a number from 0.01 to 0.99", "0 (off) or a number from 10 to 1000000", "a number >= 0"
  // (hi infinite).
  std::string expected() const;
  // Throws OptionError "'<v>' is out of range; expected <expected()>". `written`, when given,
  // is the value as its user wrote it (the command-line word), quoted instead of v.
  void check(double v, const std::string& written = {}) const;
  void check(long v, const std::string& written = {}) const;
};

// Refuses 0 for `key` ("'0' is zero; expected a nonzero number"), and NaN and infinities.
void check_nonzero(const char* key, double v, const std::string& written = {});

// Refuses `text` unless it is one of `names`, with an OptionError "'x' is not a choice;
// expected one of a, b, c"; returns its index in `names`. The parse_* functions of the
// library's closed sets (RefineMethod, LrSchedule, ...) refuse through it.
std::size_t choice_index(const char* key, const std::vector<std::string>& names,
                         const std::string& text);

}  // namespace csympnet
