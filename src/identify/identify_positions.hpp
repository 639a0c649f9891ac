// The positions route's own pieces (identify_positions.cpp): the velocity start of the hidden
// momenta (identify_velocity_start.cpp) and the choices of the core on the positions
// (identify_positions_choice.cpp). Private to the library (src/identify).
#pragma once

#include <cstddef>
#include <functional>
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
// Where it leaves smooth structure, its terms are judged on those segments (terms_on_segments);
// when the changed core leaves noise, it replaces `library` (θ its segment fit's) and the test
// passes. The judgement is recorded in rec["terms_on_positions"].
bool positions_floor(Candidate& library, const BlockSplit& split, Index d, double spp,
                     std::string& why, nlohmann::json& rec);

// The library core's terms judged on segments of the positions (identify_positions_terms.cpp):
// from `start` (the core `lib` fitted to them), each change that force_law_additions,
// periodic_alternatives and polynomial_alternatives offer is refitted (θ and the hidden start
// states), and the one that lowers the Bayesian information criterion of the training
// positions most, n log(loss) + parameters x log n, is made; then again, until none lowers it.
// Nothing is changed where the fit is at rounding level; at most 2d + 2 changes are made, and
// the search ends after a change where `stop` (when given) says so. `q`: the training
// positions (d x n). Throws Error on a stop request.
using StopSearch = std::function<bool(const Candidate& lib, const SegmentFit& fit)>;
struct TermsOnSegments {
  Candidate lib;  // the core as changed (θ its fit's); a copy of `lib` when nothing changed
  SegmentFit fit;
  nlohmann::json trials;
  bool changed = false;
};
TermsOnSegments terms_on_segments(const Candidate& lib, const SegmentFit& start, Index d,
                                  const Matrix& q, const ShootingOptions& options,
                                  const StopSearch& stop = {});

// The cores compared on the positions: every trained candidate's segment fit, the held-out
// loss of the positions decides (the library kept within three standard errors). Returns the
// chosen index, its fit in `chosen`, and records every candidate in rec["core_choice"].
std::size_t choose_on_positions(CoreFit& f, const Cut& train, const Cut& val, Index d,
                                const ShootingOptions& base, SegmentFit& chosen,
                                nlohmann::json& rec);

}  // namespace csympnet::detail
