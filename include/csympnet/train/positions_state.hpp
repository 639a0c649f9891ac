// state_from_positions (train/shooting.hpp) for a front end: `rollout --from-positions` and
// Python's Model.state_from_positions. A window the fit cannot take (a gap in its times) is
// refused before the fit, and a fit that does not explain the window after it (a residual
// that is not finite or beyond a tenth of the window's spread, a state that is not finite),
// rather than a forecast from a state that means nothing (rms 2.8e63 and a forecast of 4.8e63
// from a window with a gap; rms 2e4 from a window far from the data fitted).
#pragma once

#include <string>

#include "csympnet/core/types.hpp"
#include "csympnet/models/one_step_map.hpp"

namespace csympnet {

// A step longer than this many times the window's median step is a gap.
inline constexpr double kWindowGapFactor = 5.0;
// The largest rms position residual accepted, as a share of the window's spread (the rms
// distance of its positions from their mean).
inline constexpr double kStateFitMaxRelativeRms = 0.1;
// ... or, where the motion is within a few times the noise, this many times the noise in the
// positions (from their fourth differences: sqrt(mean (Δ⁴q)² / 70)).
inline constexpr double kStateFitMaxNoiseMultiple = 1.5;
// ... but never beyond this share of the spread: a fit that leaves most of a window unexplained
// (a zigzag at the sampling rate, noise alone) explains nothing to forecast from.
inline constexpr double kStateFitNoiseCap = 0.5;

// Refuses (Error naming `what`) a window whose times are not finite and increasing or that has
// a gap.
void check_positions_window(const Matrix& q, const Vector& t, const std::string& what);
// Refuses a fitted state that is not finite, or whose rms position residual is not finite or
// beyond both kStateFitMaxRelativeRms of the window's spread and kStateFitMaxNoiseMultiple of
// its noise (and beyond kStateFitNoiseCap of the spread, unless `white_residuals` are given and
// look like noise: a driven system's warm-up at rest, see checked_state_from_positions).
void check_state_fit(const Matrix& q, const Vector& z, double rms, const std::string& what,
                     const Matrix* white_residuals = nullptr);

// check_positions_window, state_from_positions, check_state_fit; u: the window's inputs per
// step (2m × (L − 1), start then end; empty: none). With inputs, a window whose positions are
// within the noise of rest (a driven record's first samples) is a start like any other: the
// input, not the state, carries the motion that follows, so the cap on the share of the spread
// left unexplained is lifted when the residuals look like white noise (their fourth
// differences' noise at least 1/kStateFitMaxNoiseMultiple of their rms; a smooth misfit, which
// differencing suppresses, is still refused). Without inputs such a window is still refused:
// there is nothing in it to forecast from.
Vector checked_state_from_positions(const OneStepMap& map, ConstParams theta, const Matrix& q,
                                    const Vector& t, double* rms, const std::string& what,
                                    const Matrix& u = Matrix());

}  // namespace csympnet
