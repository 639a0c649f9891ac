// The driven route's segment fit and its terms (identify_driven.cpp is the route): the record
// cut into segments with their inputs, one fit of a term set by multiple shooting from its
// equation-error start (identify_driven_fit.cpp), and the selection of the terms by BIC over
// the training segments (identify_driven_terms.cpp). docs/identification.md, "Driven records".
//
// Private to the library (src/identify).
#pragma once

#include <memory>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/core/types.hpp"
#include "csympnet/data/dataset.hpp"
#include "csympnet/identify/identify.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/train/shooting.hpp"
#include "identify_driven_link.hpp"
#include "identify_segments.hpp"

namespace csympnet::detail {

// Positions per shooting segment: its hidden start takes 2 of them per coordinate.
inline constexpr Index kSegment = 20;
// Every kHoldOut-th segment is held out.
inline constexpr Index kHoldOut = 5;
// LM iterations of a driven fit (of each stage of the linking too).
inline constexpr long kDrivenIterations = 200;
// LM iterations of a neural core's fits (identify_driven_neural.cpp), which end sooner when the
// loss converges: its hundreds of parameters take longer than the library's few.
inline constexpr long kNeuralIterations = 1000;
// (The bound on the hidden start states, kMaxAbsState, is the positions route's:
// identify_segments.hpp.)

struct DrivenCut {
  ShootingSegments train, val;
  std::vector<detail::SegmentPlace> places;  // every segment, in the record's order
};

// Segments of kSegment positions (the last of a trajectory joined to the one before when
// shorter than half); per step the input at its start and at its end. Throws Error when fewer
// than 3 training segments result.
DrivenCut cut_driven(const std::vector<Trajectory>& nt, Index d);

// The library map of `terms` with the spec's order, substeps and hold (first order by default);
// a diagonal mass.
HamiltonianLibraryMap driven_map(const LibrarySpec& s, const std::vector<LibraryTerm>& terms,
                                 Index d, Index m);

// One driven fit: the equation-error start, the segments' start states, LM on the positions.
// With `neural` set, the fit is that map's (CSympNet-ID with a neural core and the inputs'
// half-kicks, identify_driven_neural.cpp): θ, the start states and the report are its, and `map`
// is the library fit it started from.
struct DrivenFit {
  HamiltonianLibraryMap map;
  Vector theta;
  Matrix z0, vz0;
  ShootingReport rep;
  std::shared_ptr<const OneStepMap> neural;

  // The map θ belongs to.
  const OneStepMap& used() const { return neural ? *neural : static_cast<const OneStepMap&>(map); }
  Index beta_index() const { return *used().damping_param_index(); }
  // θ's entry of B(r, j): the library's after β and its dissipation rates; a neural map's
  // between its core's parameters and β (the last entry).
  Index input_index(Index r, Index j) const {
    if (!neural) return map.input_index(r, j);
    const Index m = neural->n_inputs();
    return neural->n_params() - 1 - (neural->dim() / 2) * m + r * m + j;
  }
};

// The options of a driven fit: the configured LM budget, at most max_iterations.
ShootingOptions driven_options(const IdentifyConfig& config, const IdentifyHooks& hooks,
                               long max_iterations);

// θ from the equation-error start, the segments' start states, then θ and the training
// segments' start states by multiple shooting with the inputs (at most max_iterations LM steps).
DrivenFit fit_driven(HamiltonianLibraryMap map, const std::vector<Trajectory>& nt,
                     const DrivenCut& cut, const IdentifyConfig& config, const IdentifyHooks& hooks,
                     long max_iterations = kDrivenIterations);

// Forward selection by BIC over the training segments, a few additions at most, then each
// power of degree 3 or 4 or sin/cos pair dropped while that lowers the criterion. The velocity-free
// analogue of the free route's selection: the input excites the record's whole range of amplitudes,
// and the positions judge the force law. Every trial in record["selection"].
DrivenFit select_driven_terms(DrivenFit fit, const LibrarySpec& spec, Index m,
                              const std::vector<Trajectory>& nt, const DrivenCut& cut,
                              const IdentifyConfig& config, const IdentifyHooks& hooks,
                              nlohmann::json& record);

// The neural core of a driven record (identify_driven_neural.cpp): `requested`, the core the
// options name ({"type": "la"|"g", ...}), or, when null, the default G core if the library fit
// leaves smooth structure in the held-out positions (the lag-one test of the positions route,
// residual_lag_one, with a least excess of 0.1). The neural map CSympNet-ID with the library's
// hold starts from the library fit (its γ̂, B and start states; the core taught the library's
// motion along the training segments as one-step pairs), is fitted by multiple shooting on the
// positions, and replaces the library fit when its held-out loss is lower by more than three
// standard errors (√(2/n) of itself), or when named. Every step goes into record["neural"].
DrivenFit consider_neural_core(DrivenFit library, const nlohmann::json& requested, Index m,
                               const DrivenCut& cut, const IdentifyConfig& config,
                               const IdentifyHooks& hooks, nlohmann::json& record);

}  // namespace csympnet::detail
