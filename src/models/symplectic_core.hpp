// Common base of the exactly symplectic SympNet cores Ψ_h (LA- and G-SympNet, Jin et al.
// 2020). A core is itself a OneStepMap; it additionally exposes its flow as in-place
// primitives on (q, p) so that CSympNet-ID (paper eq. csympnet_def) can wrap it without
// copying, and can place the core's cached intermediates after its own in one ForwardCache.
#pragma once

#include <cstddef>
#include <vector>

#include "csympnet/models/column_split.hpp"
#include "csympnet/models/one_step_map.hpp"

namespace csympnet {

class SymplecticCore : public OneStepMap {
 public:
  explicit SymplecticCore(Index d);

  // Half the phase-space dimension.
  Index d() const { return d_; }
  Index dim() const final { return 2 * d_; }

  // Cache layout: vecs[0] = h; mats[0, cache_slots()) as recorded by flow().
  Matrix forward(ConstParams theta, const Matrix& Z, const Vector& h,
                 ForwardCache* cache) const final;
  void backward(ConstParams theta, const ForwardCache& cache, const Matrix& dZout, ParamsRef grad,
                Matrix* dZin) const final;
  Matrix jacobian(ConstParams theta, const Vector& z, double h) const final;
  // core_spec() plus "d".
  nlohmann::json hyperparams() const final;

  // The architecture without d, e.g. {"type": "la", "layers": 5, "sublayers": 20}.
  virtual nlohmann::json core_spec() const = 0;
  // How many entries of ForwardCache::mats one flow() records.
  virtual std::size_t cache_slots() const = 0;

  // Ψ_h applied in place to the batch (q, p) (d x N each), column j with step h(j). When
  // cache is not null, records into cache->mats[slot0, slot0 + cache_slots()), growing
  // mats if needed but never shrinking it (entries outside the range belong to the caller).
  // Default: size_slots(), then flow_columns() on all columns.
  virtual void flow(ConstParams theta, Matrix& q, Matrix& p, const Vector& h, ForwardCache* cache,
                    std::size_t slot0) const;
  // Reverse mode of flow(): on entry gq, gp hold dL/d(q_out, p_out); on exit dL/d(q_in, p_in).
  // grad (size n_params()) += dL/dθ.
  virtual void flow_backward(ConstParams theta, const ForwardCache& cache, std::size_t slot0,
                             const Vector& h, Matrix& gq, Matrix& gp, ParamsRef grad) const = 0;

  // The column-split passes (column_split.hpp): flow() is size_slots() and flow_columns() on
  // each range; flow_backward() is backward_columns() on each range, then backward_params()
  // for each share. The backward records live in cache.records[0, record_slots()).
  //
  // Whether the passes may run on `ranges` (from column_ranges(n, ·)) of a batch of n columns
  // with the results of flow() and flow_backward() to the bit.
  virtual bool splits_columns(Index n, const std::vector<Columns>& ranges) const = 0;
  // How many entries of ForwardCache::records the column-split backward writes.
  virtual std::size_t record_slots() const = 0;
  // Sizes cache.mats[slot0, slot0 + cache_slots()) for a batch of n columns (growing mats if
  // needed), and with `records` the backward records too.
  virtual void size_slots(ForwardCache& cache, std::size_t slot0, Index n, bool records) const = 0;
  // flow() on columns `cols` of q and p; a non-null cache must be sized by size_slots().
  virtual void flow_columns(ConstParams theta, Matrix& q, Matrix& p, const Vector& h,
                            ForwardCache* cache, std::size_t slot0, Columns cols) const = 0;
  // The input-gradient sweep of flow_backward() on columns `cols` of gq, gp; records what the
  // parameter gradient needs.
  virtual void backward_columns(ConstParams theta, const ForwardCache& cache, std::size_t slot0,
                                const Vector& h, Matrix& gq, Matrix& gp, Columns cols) const = 0;
  // grad += the share's parameter blocks of dL/dθ, from the records of backward_columns().
  virtual void backward_params(ConstParams theta, const ForwardCache& cache, std::size_t slot0,
                               const Vector& h, ParamsRef grad, Share share) const = 0;
  // Forward mode: advances the state (q, p) through Ψ_h and the tangents (tq, tp) (d x k
  // each, the q and p rows of k tangent vectors) through DΨ_h.
  virtual void flow_tangent(ConstParams theta, Vector& q, Vector& p, Matrix& tq, Matrix& tp,
                            double h) const = 0;

 protected:
  // Makes sure cache.mats has at least n entries without touching existing ones.
  static void reserve_slots(ForwardCache& cache, std::size_t n);

 private:
  Index d_;
};

}  // namespace csympnet
