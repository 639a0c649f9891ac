// Moved to csympnet/identify/model_checks.hpp: this header forwards there, for code written against
// the earlier layout (docs/architecture.md, "Layers").
#pragma once

#include "csympnet/identify/model_checks.hpp"
