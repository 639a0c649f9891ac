// Moved to csympnet/paper/summary.hpp: this header forwards there, for code written against
// the earlier layout (docs/architecture.md, "Layers").
#pragma once

#include "csympnet/paper/summary.hpp"
