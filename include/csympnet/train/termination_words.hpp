// How an optimiser's stage ended, in plain words for people: the termination messages of
// csympnet's LM and of Ceres ("maximum number of iterations reached", "Function tolerance
// reached. ...") say that a budget was used or that the optimiser converged, which the bare
// messages can make read like failures. Reports keep the messages themselves.
#pragma once

#include <string>

namespace csympnet {

// "maximum number of iterations reached" -> "used the full iteration budget";
// "function tolerance reached" (either spelling) -> "converged: the loss stopped changing";
// gradient and parameter tolerances likewise; any other message unchanged.
std::string termination_words(const std::string& termination);

}  // namespace csympnet
