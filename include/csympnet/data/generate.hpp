// Synthetic data as fixed by docs/protocol.md ("Data generation", "Noise", "Test trajectories").
#pragma once

#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/core/rng.hpp"
#include "csympnet/data/dataset.hpp"
#include "csympnet/integrators/reference.hpp"
#include "csympnet/systems/system.hpp"

namespace csympnet {

// How the step of each training/validation pair is chosen.
struct StepSpec {
  double h_min = 0.1;  // each pair's h ~ U[h_min, h_max]; h_min == h_max gives a fixed step
  double h_max = 0.1;
  // Throws Error unless 0 < h_min <= h_max, both finite.
  void validate() const;
};
// JSON object {"h_min", "h_max"}; both keys required, unknown keys rejected, then validated.
void to_json(nlohmann::json& j, const StepSpec& s);
void from_json(const nlohmann::json& j, StepSpec& s);

// z0 ~ U([−box, box]^{2d}) i.i.d. per pair, h per StepSpec, z1 = reference flow.
// Draw order: for each pair, the 2d components of z0 (q then p), then h. The h draw is made
// even when h_min == h_max (h is then exactly h_min), so the starts drawn from a seed do not
// depend on the step spec.
PairSet generate_pairs(const System& sys, Index n, const StepSpec& steps, Rng& rng,
                       const ReferenceOptions& ref = {}, double box = 1.0);

// Component-wise std (population, divide by m) of m clean snapshot pairs drawn like the
// data: s0 from the starts, s1 from the ends (docs/protocol.md, "Noise": m = 1000).
struct NoiseScales {
  Vector s0;
  Vector s1;
};
NoiseScales noise_scales(const System& sys, const StepSpec& steps, Rng& rng,
                         const ReferenceOptions& ref = {}, Index m = 1000, double box = 1.0);

// z̃_ℓ = z_ℓ + σ s_ℓ ⊙ ξ, ξ ~ N(0, I), for ℓ = 0, 1. Draw order: per pair, ξ0 then ξ1.
// ξ is drawn for every σ (also σ = 0), so the stream position afterwards does not depend on σ;
// with σ = 0 the data are left bit-identical (nothing is added, not even +0.0).
void add_noise(PairSet& pairs, double sigma, const NoiseScales& scales, Rng& rng);

// Test trajectories on the uniform grid t_n = n h_test, n = 0..round(horizon / h_test).
// A start whose reference trajectory leaves ‖z‖_∞ ≤ bound at a grid point is redrawn.
// Candidates are drawn one after the other (2d components each, q then p) and the first m that
// stay bounded are kept, in draw order. They are integrated in rounds: each round draws exactly
// as many candidates as are still missing and advances them together, grid point to grid point,
// with reference_flow. So the result, `redraws` and the stream position afterwards are the same
// as drawing and testing one candidate at a time. Throws Error when redraws exceed max_redraws.
struct TestSet {
  std::vector<Trajectory> trajectories;
  Index redraws = 0;  // how many starts were rejected
};
TestSet generate_test_set(const System& sys, Index m, double h_test, double horizon, Rng& rng,
                          const ReferenceOptions& ref = {}, double bound = 10.0, double box = 1.0,
                          Index max_redraws = 100000);

}  // namespace csympnet
