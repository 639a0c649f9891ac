// Moved to csympnet/paper/paper_values.hpp: this header forwards there, for code written against
// the earlier layout (docs/architecture.md, "Layers").
#pragma once

#include "csympnet/paper/paper_values.hpp"
