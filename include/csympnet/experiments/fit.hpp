// Moved to csympnet/paper/fit.hpp: this header forwards there, for code written against
// the earlier layout (docs/architecture.md, "Layers").
#pragma once

#include "csympnet/paper/fit.hpp"
