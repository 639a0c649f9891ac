// Moved to csympnet/identify/time_unit.hpp: this header forwards there, for code written against
// the earlier layout (docs/architecture.md, "Layers").
#pragma once

#include "csympnet/identify/time_unit.hpp"
