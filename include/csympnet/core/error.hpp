// The one exception type the library throws for bad input or bad options.
//
// Messages say what was wrong, where (file:line, option name), and what was expected.
#pragma once

#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace csympnet {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Throws Error(message) when `ok` is false. Checks that run on every call of a hot path
// (shape checks in forward/backward, per-pair data checks) pass a literal or a callable that
// builds the message: the callable runs only when the check fails, so a passing check
// allocates nothing. An already-built std::string is for checks at the boundary (options,
// files), which run once.
inline void require(bool ok, const char* message) {
  if (!ok) [[unlikely]]
    throw Error(message);
}

inline void require(bool ok, const std::string& message) {
  if (!ok) [[unlikely]]
    throw Error(message);
}

template <class MakeMessage>
requires std::is_invocable_r_v<std::string, MakeMessage&>
inline void require(bool ok, MakeMessage&& make_message) {
  if (!ok) [[unlikely]]
    throw Error(make_message());
}

// `text` with every byte outside printable ASCII shown as \xNN, for quoting input (a parser's
// "last read" of a binary file) in a message that must stay plain text.
std::string printable(const std::string& text);

// The items of a message's list ("expected one of: a, b, c"), separated by ", ".
std::string comma_separated(const std::vector<std::string>& items);

// A number for a message: six significant digits ("1e+300", "0.1", "2.5e-07").
std::string number_text(double v);
// The shortest text that reads back to exactly v ("0.2", not "0.20000000000000001"): what every
// file and table csympnet writes uses, so that numbers are both short and bit-exact.
std::string round_trip_text(double v);

}  // namespace csympnet
