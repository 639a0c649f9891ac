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

}  // namespace csympnet
