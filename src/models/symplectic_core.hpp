// Common base of the exactly symplectic SympNet cores Ψ_h (LA- and G-SympNet, Jin et al.
// 2020). A core is itself a OneStepMap; it additionally exposes its flow as in-place
// primitives on (q, p) so that CSympNet-ID (paper eq. csympnet_def) can wrap it without
// copying, and can keep the core's record of a flow in a cache of its own (the flow cache, which
// holds the core's typed context: GSympNet::FlowContext, LaSympNet::FlowContext).
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

  // The core as a map on its own keeps the steps and, in a nested cache, its flow's record.
  struct MapContext final : ForwardContext {
    const char* owner() const override { return "symplectic core"; }
    Vector h;
    ForwardCache flow;
  };

  Matrix forward(ConstParams theta, const Matrix& Z, const Vector& h,
                 ForwardCache* cache) const final;
  void backward(ConstParams theta, const ForwardCache& cache, const Matrix& dZout, ParamsRef grad,
                Matrix* dZin) const final;
  Matrix jacobian(ConstParams theta, const Vector& z, double h) const final;
  // core_spec() plus "d".
  nlohmann::json hyperparams() const final;

  // The architecture without d, e.g. {"type": "la", "layers": 5, "sublayers": 20}.
  virtual nlohmann::json core_spec() const = 0;

  // Ψ_h applied in place to the batch (q, p) (d x N each), column j with step h(j). When
  // `flow_cache` is not null, it receives the core's flow context (what flow_backward() needs).
  // Default: size_flow(), then flow_columns() on all columns.
  virtual void flow(ConstParams theta, Matrix& q, Matrix& p, const Vector& h,
                    ForwardCache* flow_cache) const;
  // Reverse mode of flow() from what it recorded in flow_cache: on entry gq, gp hold
  // dL/d(q_out, p_out); on exit dL/d(q_in, p_in). grad (size n_params()) += dL/dθ.
  virtual void flow_backward(ConstParams theta, const ForwardCache& flow_cache, const Vector& h,
                             Matrix& gq, Matrix& gp, ParamsRef grad) const = 0;

  // The column-split passes (column_split.hpp): flow() is size_flow() and flow_columns() on
  // each range; flow_backward() is backward_columns() on each range, then backward_params()
  // for each share. The backward records are mutable members of the flow context.
  //
  // Whether the passes may run on `ranges` (from column_ranges(n, ·)) of a batch of n columns
  // with the results of flow() and flow_backward() to the bit.
  virtual bool splits_columns(Index n, const std::vector<Columns>& ranges) const = 0;
  // Makes flow_cache hold this core's flow context, sized for a batch of n columns, and with
  // `records` the backward records too (storage already there is reused).
  virtual void size_flow(ForwardCache& flow_cache, Index n, bool records) const = 0;
  // flow() on columns `cols` of q and p; a non-null flow_cache must be sized by size_flow().
  virtual void flow_columns(ConstParams theta, Matrix& q, Matrix& p, const Vector& h,
                            ForwardCache* flow_cache, Columns cols) const = 0;
  // The input-gradient sweep of flow_backward() on columns `cols` of gq, gp; records what the
  // parameter gradient needs.
  virtual void backward_columns(ConstParams theta, const ForwardCache& flow_cache, const Vector& h,
                                Matrix& gq, Matrix& gp, Columns cols) const = 0;
  // grad += the share's parameter blocks of dL/dθ, from the records of backward_columns().
  virtual void backward_params(ConstParams theta, const ForwardCache& flow_cache, const Vector& h,
                               ParamsRef grad, Share share) const = 0;
  // Forward mode: advances the state (q, p) through Ψ_h and the tangents (tq, tp) (d x k
  // each, the q and p rows of k tangent vectors) through DΨ_h.
  virtual void flow_tangent(ConstParams theta, Vector& q, Vector& p, Matrix& tq, Matrix& tp,
                            double h) const = 0;

 private:
  Index d_;
};

}  // namespace csympnet
