// Internal to the CSV readers: the --columns a message suggests for a header csympnet does not
// read, built from the file's own column names.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace csympnet::csv_detail {

// What a column's name says it holds. Positions are the default: a name is read as a velocity
// or momentum only when it says so (a token v, vel, velocity, speed, omega, p, mom, momentum, a
// token ending in "dot", or v/p followed by digits), so "left_cart_px" (pixels) stays a
// position; a time is a token t, time or timestamp; a trajectory id is traj or trajectory.
enum class ColumnRole { kTime, kTraj, kPosition, kMomentum };
ColumnRole guess_column_role(std::string_view name);

// "--columns t=…,q1=…[,p1=…]" for a header of these names: the first time-like column (else
// the first column) as t, a traj-like column as traj, the momentum-like columns as p1..pd
// when there are as many as positions, and every other column as a position q1..qd. Files of
// positions alone are read, so without momentum-like names every column after t is a position.
std::string columns_example(const std::vector<std::string_view>& fields);

}  // namespace csympnet::csv_detail
