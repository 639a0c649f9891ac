// Snapshot data: pairs (z0, z1, h) and whole trajectories.
#pragma once

#include <string>
#include <vector>

#include "csympnet/core/types.hpp"

namespace csympnet {

// N snapshot pairs. Columns are samples: z0, z1 are 2d x N, h has length N.
struct PairSet {
  Matrix z0;
  Matrix z1;
  Vector h;

  Index size() const { return z0.cols(); }
  Index dim() const { return z0.rows(); }  // 2d
  Index d() const { return z0.rows() / 2; }
  // Throws Error (prefixed by `where`) on inconsistent shapes, odd dimension, h <= 0 or
  // non-finite values.
  void validate(const std::string& where = "pairs") const;
};

// Keeps the columns `idx` of a pair set, in that order.
PairSet select_pairs(const PairSet& pairs, const std::vector<Index>& idx);
// Concatenates pair sets of the same dimension.
PairSet concat_pairs(const std::vector<PairSet>& parts);

// One trajectory: states z (2d x (n+1)) at strictly increasing times t (length n+1), and the
// known inputs u (m x (n+1), sampled at the same times; empty: a free record).
struct Trajectory {
  Vector t;
  Matrix z;
  Matrix u;
  Index steps() const { return t.size() - 1; }
  // Throws Error (prefixed by `where`) unless t has n+1 >= 1 entries, z is 2d x (n+1) with
  // d >= 1, all values are finite and t strictly increases, and u is empty or has n+1 finite
  // columns.
  void validate(const std::string& where = "trajectory") const;
};

// Consecutive states of each trajectory become pairs, at whatever step they have
// (h = t[n] - t[n-1]); no pair spans two trajectories. A single-point trajectory gives no
// pair, but all of them together must give at least one. Pairs come out in trajectory order.
PairSet pairs_from_trajectories(const std::vector<Trajectory>& trajs);

}  // namespace csympnet
