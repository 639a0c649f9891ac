// The segments of a driven record (identify_driven.cpp) linked by continuity into chains over
// whole stretches of the record (docs/identification.md, "Driven records"; docs/derivations.md,
// "Positions only: linked segments"): the free positions route's link_segments
// (identify_chain.hpp), each segment carrying its steps' known inputs.
//
// Private to the library (src/identify).
#pragma once

#include <vector>

#include "csympnet/core/types.hpp"
#include "csympnet/data/dataset.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "csympnet/train/shooting.hpp"
#include "csympnet/train/window_loss.hpp"
#include "identify_chain.hpp"

namespace csympnet::detail {

// Where a segment of a driven record's cut lies: its trajectory, first sample and positions,
// and whether it is held out.
struct SegmentPlace {
  Index trajectory = 0, first = 0, length = 0;
  bool held_out = false;
};

// The segment fit of a driven record, to be linked: its training and held-out segments in the
// cut's order (`places`), their start states, the fit's report.
struct DrivenSegments {
  const ShootingSegments& train;
  const Matrix& z0;
  const ShootingSegments& val;
  const ShootingReport& report;
};

// The record (`nt`: normalised positions, d × n, with their inputs) as the chain reads it: the
// states' rows 2d (the momenta 0, never observed), each training segment's positions observed
// with the segment as their block, the held-out ones unobserved.
struct DrivenRecord {
  std::vector<Trajectory> states;  // z = (q; 0), t and u as given
  RecordLayout layout;
};
DrivenRecord driven_record(const std::vector<Trajectory>& nt,
                           const std::vector<SegmentPlace>& places);

// Per trajectory, the state at every sample: the segments' fitted rollouts (with their inputs)
// where a segment covers it, (q; 0) elsewhere.
std::vector<Matrix> driven_states(const OneStepMap& map, ConstParams theta,
                                  const DrivenRecord& record,
                                  const std::vector<SegmentPlace>& places,
                                  const DrivenSegments& fit, const Matrix& val_z0);

// The segments linked (link_segments with the inputs threaded through, its first stage holding
// `first_length` training positions per segment): θ, `val_z0` and `states` those of the last
// kept stage.
LinkedFit link_driven_segments(const OneStepMap& map, Vector& theta, const DrivenRecord& record,
                               const std::vector<SegmentPlace>& places, const DrivenSegments& fit,
                               Index first_length, Matrix& val_z0, const ShootingOptions& options,
                               std::vector<Matrix>& states);

// The record with its inputs' curvature between samples folded in: per sample
//   ũ_k = u_k − h̄² u''_k / 12,   u''_k = 2 ((u_{k+1} − u_k)/h₂ − (u_k − u_{k−1})/h₁) / (h₁ + h₂),
// h̄ = (h₁ + h₂)/2 (at a trajectory's ends its neighbour's u''), so that the first-order hold of ũ
// has the step averages of a smooth u to O(h⁴) where the hold of u is O(h²) off. Refitted with
// ũ, the change of γ̂ and B measures what the hold's straight lines cost (identify_driven.cpp).
std::vector<Trajectory> curved_inputs(const std::vector<Trajectory>& nt);

// One-step windows at every training position of the record whose next sample is in the same
// stretch, from the linked fit's states (for the modes' mean state), blocks as the layout's.
WindowSet training_state_windows(const DrivenRecord& record, const std::vector<Matrix>& states);

}  // namespace csympnet::detail
