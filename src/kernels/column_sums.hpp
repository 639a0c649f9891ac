// Internal to src: the running sums Σ_j x_c,j over samples j = 0, 1, ... of many columns
// c at once, each summed left to right from x_c,0 (the order of a sequential dot product, and of
// Eigen's inner product of two 1 x N rows), four columns per 256-bit instruction.
//
// Why a transpose: the products x_c,j come from code that holds samples in SIMD lanes (one
// register: one column, eight samples), while the sums need the columns in lanes (one register:
// four columns, one sample; the sums then advance one sample per add, in order). The columns'
// rows are gathered in a small buffer and, whenever it fills, transposed by 4 x 4 tiles and
// added, twelve sums of four columns at a time. The buffer of kFlushColumns rows (15 KB) stays in
// the L1 cache, where a table of every column would not (the s1 backward sweep has 114 columns).
//
// Used by the backward sweeps (d1_backward_avx512.cpp, d1_backward_avx2.cpp): flush() needs
// AVX-512F and VL (256-bit operations on 32 registers, twelve sums in flight) or, in the form for
// machines without AVX-512, AVX2 (sixteen registers, four sums in flight). The sums' order is the
// same either way.
#pragma once

#include <memory>

#include "csympnet/core/types.hpp"

namespace csympnet::kernels {

// Samples per block: a row of the buffer. 40 for the AVX-512 backward sweep; 20 for the AVX2 one,
// whose rows of gradients (five registers each) then fit AVX2's sixteen registers.
constexpr Index kColumnSumsBlock = 40;
constexpr Index kColumnSumsBlockAvx2 = 20;

class ColumnSums {
 public:
  static constexpr Index kFlushColumns = 48;  // twelve tiles of 4 columns

  // The instruction set flush() uses, and with it the block: kColumnSumsBlock samples (kAvx512)
  // or kColumnSumsBlockAvx2 (kAvx2).
  enum class Isa { kAvx512, kAvx2 };

  // `columns` running sums, each starting at −0 (−0 + x = x for every x, so the first add
  // gives x_c,0 itself; the first block's adds start from the constant, not from memory).
  explicit ColumnSums(Index columns, Isa isa = Isa::kAvx512);
  ColumnSums(const ColumnSums&) = delete;
  ColumnSums& operator=(const ColumnSums&) = delete;

  // The row (a block's values, 32-byte aligned) for the next column's products at the block's
  // samples; columns come in the order 0, 1, ... in every block.
  double* next_column() { return products_ + filled_ * row_; }
  // That row is written, with the block's first cnt samples live.
  void column_done(Index cnt) {
    if (++filled_ == kFlushColumns) flush(cnt);
  }
  // Every column of the block is done: the next column is column 0 of the next block.
  void end_block(Index cnt) {
    flush(cnt);
    first_ = 0;
    fresh_ = false;
  }
  // The sums so far (after end_block()), column c at c.
  const double* sums() const { return sums_; }

 private:
  void flush(Index cnt);

  alignas(64) double products_[kFlushColumns * kColumnSumsBlock];
  alignas(64) double sums_local_[256];
  double* sums_ = sums_local_;
  std::unique_ptr<double[]> sums_heap_;  // more than 256 columns
  Isa isa_;
  Index row_;          // samples per block
  Index filled_ = 0;   // rows of products_ in use
  Index first_ = 0;    // the column of row 0
  bool fresh_ = true;  // in the first block: the sums are not yet stored
};

}  // namespace csympnet::kernels
