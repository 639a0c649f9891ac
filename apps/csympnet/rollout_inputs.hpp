// `rollout --inputs FILE`: the known inputs a driven model is fed at each of the rollout's
// sample times.
#pragma once

#include <string>

#include "csympnet/core/types.hpp"

namespace csympnet::cli {

// Reads FILE: a header naming the input columns `u1..um` in order, optionally after a `t`
// column, then one row of numbers per sample time of the rollout: t0, t0 + h, …,
// t0 + steps·h, `steps + 1` rows in all. With a `t` column each row's time must be its sample's
// (to 1e-9 of the step). Returns the inputs, m × (steps + 1). Throws Error naming the file,
// the line and what was expected (a header, a number, the row count, a time).
Matrix read_rollout_inputs(const std::string& path, Index m, long steps, double t0, double h);

}  // namespace csympnet::cli
