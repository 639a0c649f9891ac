// The one exception type the library throws for bad input or bad options.
//
// Messages say what was wrong, where (file:line, option name), and what was expected.
#pragma once

#include <stdexcept>
#include <string>

namespace csympnet {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Throws Error(message) when `ok` is false.
inline void require(bool ok, const std::string& message) {
  if (!ok) throw Error(message);
}

// `text` with every byte outside printable ASCII shown as \xNN, for quoting input (a parser's
// "last read" of a binary file) in a message that must stay plain text.
std::string printable(const std::string& text);

// A number for a message: six significant digits ("1e+300", "0.1", "2.5e-07").
std::string number_text(double v);

}  // namespace csympnet
