#include "csympnet/train/termination_words.hpp"

#include <cctype>
#include <cstring>

namespace csympnet {

std::string termination_words(const std::string& termination) {
  // csympnet's LM says "function tolerance reached", Ceres "Function tolerance reached. ...".
  auto starts = [&](const char* prefix) {
    const std::size_t n = std::strlen(prefix);
    if (termination.size() < n) return false;
    for (std::size_t i = 0; i < n; ++i)
      if (std::tolower(static_cast<unsigned char>(termination[i])) != prefix[i]) return false;
    return true;
  };
  if (starts("maximum number of iterations reached")) return "used the full iteration budget";
  if (starts("function tolerance reached")) return "converged: the loss stopped changing";
  if (starts("gradient tolerance reached")) return "converged: the gradient is negligible";
  if (starts("parameter tolerance reached")) return "converged: the parameters stopped changing";
  return termination;
}

}  // namespace csympnet
