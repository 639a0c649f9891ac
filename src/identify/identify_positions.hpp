// The positions route's own pieces (identify_positions.cpp): the velocity start of the hidden
// momenta (identify_velocity_start.cpp) and the choices of the core on the positions
// (identify_positions_choice.cpp). Private to the library (src/identify).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/data/dataset.hpp"
#include "csympnet/train/shooting.hpp"
#include "identify_segments.hpp"
#include "identify_stages.hpp"

namespace csympnet::detail {

// Refuses a record of positions that cannot be fitted, before any work: every trajectory with
// the same d, one time per sample, times increasing, finite values, every coordinate varying.
void check_positions(const std::vector<Trajectory>& positions);

// The velocity start's half width (in the data's time) and the lag it came from.
struct VelocityStart {
  std::vector<Trajectory> states;  // the positions with velocities from local fits
  double half = 0.0, lag = 0.0;
};
VelocityStart velocity_start(const std::vector<Trajectory>& positions);

// The lag-one correlation of the shooting residuals within the segments, pooled over segments
// and coordinates, and how many neighbouring pairs it pools (identify_positions_choice.cpp).
// Measurement noise leaves about −2/(L − 2) over segments of L positions (the fitted starts take
// the residuals' slowest part); a misfit of the force a positive excess.
struct LagOne {
  double rho = 0.0;
  Index pairs = 0;
};
LagOne residual_lag_one(const OneStepMap& map, ConstParams theta, const Matrix& z0,
                        const ShootingSegments& segs);

// The floor test of the positions route (FloorTest): whether the library core, fitted to
// segments of the positions, leaves residuals that are noise (`why` says what was measured).
bool positions_floor(const Candidate& library, const BlockSplit& split, Index d, double spp,
                     std::string& why);

// The cores compared on the positions: every trained candidate's segment fit, the held-out
// loss of the positions decides (the library kept within three standard errors). Returns the
// chosen index, its fit in `chosen`, and records every candidate in rec["core_choice"].
std::size_t choose_on_positions(CoreFit& f, const Cut& train, const Cut& val, Index d,
                                const ShootingOptions& base, SegmentFit& chosen,
                                nlohmann::json& rec);

}  // namespace csympnet::detail
