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
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/core/rng.hpp"
#include "csympnet/core/types.hpp"
#include "csympnet/models/column_split.hpp"

namespace csympnet {

// Intermediates of one forward pass. Opaque to callers; reusing one cache across calls of
// the same batch size lets a model avoid reallocating.
struct ForwardCache {
  std::vector<Matrix> mats;
  std::vector<Vector> vecs;
  // The column-split backward's records (column_split.hpp): written by its sweep over column
  // ranges, read by its parameter sums. Scratch of backward(), which takes the cache as const;
  // kept here so that the epochs of a training run reuse the storage.
  mutable std::vector<Matrix> records;
  mutable std::vector<Vector> record_vecs;
  // What a wrapping map (DofScaledMap) keeps of its own; the wrapped map never touches it.
  std::vector<Matrix> outer;
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

  // The identified damping rate γ̂, for models that carry one.
  virtual std::optional<double> damping_rate(ConstParams /*theta*/) const { return std::nullopt; }
  // Index of the damping parameter β in θ (so an optimiser can exclude it from decay).
  virtual std::optional<Index> damping_param_index() const { return std::nullopt; }

  // Everything needed to rebuild the architecture (not the parameters); accepted back by
  // make_one_step_map().
  virtual nlohmann::json hyperparams() const = 0;

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
