// Moved to csympnet/paper/run.hpp: this header forwards there, for code written against
// the earlier layout (docs/architecture.md, "Layers").
#pragma once

#include "csympnet/paper/run.hpp"
