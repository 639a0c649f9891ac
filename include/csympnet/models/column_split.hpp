// Training passes split over the columns of a batch and over shares of the parameters, so that
// one epoch can run on several threads with the results of the serial passes to the bit
// (docs/architecture.md, "Threads without new bits").
//
// Why the bits survive a split: every column of a batch is a sample, and the forward pass and
// the input-gradient sweep of the backward pass treat samples independently, with per-entry
// operations that do not depend on which other columns share a call (the exact product
// kernels, σ and exp on pairs of elements that start at even offsets). Only the parameter
// gradient sums over samples; those sums run over all columns at once, after the sweep, each
// parameter block's updates whole and in their serial order, on one thread. What may not be
// split (a d = 1 LA core, whose sweeps are single-row kernels, or a product shape the exact
// kernels do not cover) reports so, and the caller runs the serial passes instead.
#pragma once

#include <vector>

#include "csympnet/core/types.hpp"

namespace csympnet {

// Columns [begin, end) of a batch.
struct Columns {
  Index begin = 0;
  Index end = 0;
  Index size() const { return end - begin; }
};

// Part `index` of `count` equal shares of some work, dealt in a fixed order.
struct Share {
  int index = 0;
  int count = 1;
  bool owns(Index item) const { return item % count == index; }
};

// Column ranges start at multiples of this: the exact kernels' units (pairs of elements for σ
// and exp, blocks of 4 columns for a product's remainder rows) then fall on the same columns
// as in one call on the whole batch.
inline constexpr Index kColumnAlign = 8;

// n columns cut into at most `parts` consecutive ranges of nearly equal size, every range
// but the last a multiple of kColumnAlign wide; fewer ranges when n is small (never empty ones).
std::vector<Columns> column_ranges(Index n, int parts);

// Whether `ranges` cut n columns the way the passes need: consecutive from 0 to n, none empty,
// each starting at a multiple of kColumnAlign.
bool ranges_tile(Index n, const std::vector<Columns>& ranges);

class ForwardCache;

// The passes of one training step of a one-step map, in the order a caller runs them:
//   prepare                    serial
//   forward_columns            one call per column range, in parallel
//   (the loss and dL/dΦ̂, serial)
//   backward_columns           one call per column range, in parallel
//   backward_params            one call per share, in parallel
//   backward_finish            serial
// Together they compute OneStepMap::forward (with a cache) and backward to the bit, for any
// ranges from column_ranges() that splits() accepts and any number of shares.
class ColumnSplitPasses {
 public:
  virtual ~ColumnSplitPasses() = default;

  // Whether a batch of n columns may be cut into `ranges`.
  virtual bool splits(Index n, const std::vector<Columns>& ranges) const = 0;
  // Sizes everything in `cache` for a batch of h.size() columns with steps h.
  virtual void prepare(ConstParams theta, const Vector& h, ForwardCache& cache) const = 0;
  // Φ̂ on columns `cols` of Z into the same columns of out (2d x n, sized by the caller).
  virtual void forward_columns(ConstParams theta, const Matrix& Z, ForwardCache& cache, Matrix& out,
                               Columns cols) const = 0;
  // The input-gradient sweep of backward() on columns `cols` of the upstream gradient dZout;
  // records in the cache what the parameter gradient needs.
  virtual void backward_columns(ConstParams theta, const ForwardCache& cache, const Matrix& dZout,
                                Columns cols) const = 0;
  // grad += the share's parameter blocks of dL/dθ, each summed over all columns.
  virtual void backward_params(ConstParams theta, const ForwardCache& cache, ParamsRef grad,
                               Share share) const = 0;
  // grad += the rest of dL/dθ (what needs every block's sweep first, e.g. ∂L/∂β).
  virtual void backward_finish(ConstParams theta, const ForwardCache& cache,
                               ParamsRef grad) const = 0;
};

}  // namespace csympnet
