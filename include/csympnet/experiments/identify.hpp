// Moved to csympnet/identify/identify.hpp: this header forwards there, for code written against
// the earlier layout (docs/architecture.md, "Layers").
#pragma once

#include "csympnet/identify/identify.hpp"
