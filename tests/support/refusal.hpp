// The message of the csympnet::Error a call throws, or "" when it returns: for the tests that
// check a refusal names what was wrong.
#pragma once

#include <functional>
#include <string>

#include "csympnet/core/error.hpp"

namespace csympnet::testing {

inline std::string refusal(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace csympnet::testing
