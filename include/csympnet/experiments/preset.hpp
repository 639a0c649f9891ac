// Moved to csympnet/paper/preset.hpp: this header forwards there, for code written against
// the earlier layout (docs/architecture.md, "Layers").
#pragma once

#include "csympnet/paper/preset.hpp"
