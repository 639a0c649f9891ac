// A learned one-step map  z1 ≈ Φ̂_h(z0)  with a flat parameter vector θ.
//
// Every implementation provides, with hand-written derivatives:
//   forward   Φ̂_h on a batch (columns are samples), caching what backward needs;
//   backward  reverse mode: accumulates dL/dθ and optionally returns dL/dZ_in;
//   jacobian  the exact input Jacobian DΦ̂_h(z) (2d x 2d), forward mode.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <typeinfo>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/core/rng.hpp"
#include "csympnet/core/types.hpp"
#include "csympnet/models/column_split.hpp"

namespace csympnet {

// What one map's forward pass keeps for its backward pass, with named members. Each map that
// keeps something defines its own context type (a core: per module its input and σ; CSympNet-ID:
// its conformal scalings and, nested, its core's cache); maps that only wrap another and keep
// nothing of their own (SympNet, NormalizedMap) pass the cache through.
class ForwardContext {
 public:
  virtual ~ForwardContext() = default;
  // The kind of map that recorded it ("g core", "csympnet", ...), for the error when a map of
  // another kind is handed this context.
  virtual const char* owner() const = 0;
};

// Intermediates of one forward pass: the typed context of the map that ran it. Callers create
// the cache, pass it to forward() and then, unchanged, to backward(); its contents are opaque to
// them. Reusing one cache across calls lets a map keep its storage: a forward pass finds its own
// context and resizes it in place (no allocation once the batch size has been seen), so the
// epochs of a training run allocate nothing here.
class ForwardCache {
 public:
  ForwardCache() = default;
  ForwardCache(ForwardCache&&) noexcept = default;
  ForwardCache& operator=(ForwardCache&&) noexcept = default;

  bool empty() const { return context_ == nullptr; }

  // For a forward pass: the context of type C held, else a new C replacing whatever the cache
  // held (a forward pass defines every value it records, so another map's context is simply
  // dropped).
  template <class C>
  C& make_context() {
    if (!holds<C>()) context_ = std::make_unique<C>();
    return static_cast<C&>(*context_);
  }

  // For a backward pass (or a later pass of the same forward): the context of type C that a
  // forward pass recorded. Throws Error naming `reader` if the cache is empty or holds what a
  // map of another kind recorded: reading it as a C would be undefined behaviour.
  template <class C>
  const C& context(const char* reader) const {
    if (!holds<C>()) refuse(reader);
    return static_cast<const C&>(*context_);
  }
  template <class C>
  C& context(const char* reader) {
    if (!holds<C>()) refuse(reader);
    return static_cast<C&>(*context_);
  }

 private:
  [[noreturn]] void refuse(const char* reader) const;
  // Whether the cache holds a context of exactly type C (bound to a reference first, so that
  // typeid sees an lvalue, not a call).
  template <class C>
  bool holds() const {
    if (context_ == nullptr) return false;
    const ForwardContext& held = *context_;
    return typeid(held) == typeid(C);
  }

  std::unique_ptr<ForwardContext> context_;
};

class OneStepMap {
 public:
  virtual ~OneStepMap() = default;

  // Short type name as used on the command line and in model files ("csympnet", ...).
  virtual std::string type() const = 0;
  // Phase-space dimension 2d.
  virtual Index dim() const = 0;
  virtual Index n_params() const = 0;
  // Writes the documented initial parameters into theta (size n_params()).
  virtual void init_params(Rng& rng, ParamsRef theta) const = 0;

  // Φ̂_h applied to each column of Z (2d x N) with its own step h(j). When `cache` is not
  // null, it receives what backward() needs.
  virtual Matrix forward(ConstParams theta, const Matrix& Z, const Vector& h,
                         ForwardCache* cache) const = 0;
  // Reverse mode through the forward pass recorded in `cache` (same theta, Z, h):
  // grad += dL/dθ for the upstream gradient dZout = dL/dZ_out (2d x N); if dZin is not null
  // it is set to dL/dZ_in.
  virtual void backward(ConstParams theta, const ForwardCache& cache, const Matrix& dZout,
                        ParamsRef grad, Matrix* dZin) const = 0;
  // Exact DΦ̂_h(z), 2d x 2d.
  virtual Matrix jacobian(ConstParams theta, const Vector& z, double h) const = 0;

  // Known inputs (models/inputs.hpp): the number m of input channels the map reads (0: a free
  // map, the default). A map with inputs takes them per step through forward_driven() and
  // jacobian_driven(); its forward() and jacobian() are those with every input 0.
  virtual Index n_inputs() const { return 0; }
  // Φ̂_h driven by U (2m × N: per column the input at the step's start, rows 0 … m−1, and at its
  // end, rows m … 2m−1); the cache keeps U for backward(). U with 0 rows is forward(). The
  // default (a free map) refuses any other U with an Error naming the map's type.
  virtual Matrix forward_driven(ConstParams theta, const Matrix& Z, const Vector& h,
                                const Matrix& U, ForwardCache* cache) const;
  // Exact DΦ̂_h(z) driven by u (2m values, as a column of U; empty: jacobian()).
  virtual Matrix jacobian_driven(ConstParams theta, const Vector& z, double h,
                                 const Vector& u) const;

  // The identified damping rate γ̂, for models that carry one.
  virtual std::optional<double> damping_rate(ConstParams /*theta*/) const { return std::nullopt; }
  // Index of the damping parameter β in θ (so an optimiser can exclude it from decay).
  virtual std::optional<Index> damping_param_index() const { return std::nullopt; }

  // Everything needed to rebuild the architecture (not the parameters); accepted back by
  // make_one_step_map().
  virtual nlohmann::json hyperparams() const = 0;

  // Forward-mode sensitivities of one step, for maps that provide them (has_step_tangents()):
  //   z ← Φ̂_h(z) driven by u (2m values as a column of U; null: none), the same bits as
  //   forward_driven();
  //   t ← DΦ̂_h(z) t + [∂Φ̂_h/∂θ_0 … ∂Φ̂_h/∂θ_{n_theta−1} | 0]   (t: 2d × c, n_theta ≤ c),
  // the sensitivity of a rollout to θ's first n_theta entries (columns 0 … n_theta − 1) and to
  // anything else (the other columns, e.g. its start state) carried one step further. With c = 0
  // it is the step alone. The multiple-shooting and window fits take it in place of a reverse
  // pass per state component and a separate state Jacobian (docs/derivations.md, "Forward-mode
  // sensitivities"). The default refuses (Error).
  virtual bool has_step_tangents() const { return false; }
  virtual void step_tangents(ConstParams theta, double h, const double* u, double* z, Matrix& t,
                             Index n_theta) const;

  // The column-split training passes, for models that have them (column_split.hpp); null
  // otherwise. Whether a given batch may be split is then asked of the passes.
  virtual const ColumnSplitPasses* column_split() const { return nullptr; }

  // Convenience: forward without a cache.
  Matrix apply(ConstParams theta, const Matrix& Z, const Vector& h) const {
    return forward(theta, Z, h, nullptr);
  }
};

// Builds a model from its hyperparams JSON (e.g. {"type": "csympnet", "d": 1, "core":
// {"type": "la", "layers": 5, "sublayers": 20}}). Throws Error naming a bad or missing key.
std::unique_ptr<OneStepMap> make_one_step_map(const nlohmann::json& spec);

}  // namespace csympnet
