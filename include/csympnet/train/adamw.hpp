// AdamW (Loshchilov & Hutter 2019) with exactly PyTorch's torch.optim.AdamW semantics
// (amsgrad off, maximize off):
//   θ ← θ − lr·wd·θ                          (decoupled decay, before the moment update)
//   m ← β1 m + (1−β1) g,   v ← β2 v + (1−β2) g²
//   θ ← θ − (lr / (1−β1ᵗ)) · m / ( √v / √(1−β2ᵗ) + eps )
#pragma once

#include <limits>
#include <optional>

#include <nlohmann/json.hpp>

#include "csympnet/core/options.hpp"
#include "csympnet/core/types.hpp"

namespace csympnet {

// The ranges of the options the front ends give (core/options.hpp): the learning rate (below
// 1e-12 nothing moves in a budget of 1e8 epochs; above 10 every model here diverges) and the
// weight decay.
inline constexpr OptionRange kLrRange{.key = "lr", .lo = 1e-12, .hi = 10.0};
inline constexpr OptionRange kWeightDecayRange{
    .key = "weight_decay", .lo = 0.0, .hi = std::numeric_limits<double>::infinity()};

struct AdamWOptions {
  double lr = 1e-3;            // learning rate
  double beta1 = 0.9;          // first-moment decay
  double beta2 = 0.999;        // second-moment decay
  double eps = 1e-8;           // denominator guard
  double weight_decay = 5e-4;  // decoupled weight decay
  // Apply the weight decay to the damping parameter β too (the paper's recipe: true). With
  // false, β is excluded, which removes decay's pull of γ̂ towards 0.
  bool decay_damping = true;
  void validate() const;
};
void to_json(nlohmann::json& j, const AdamWOptions& o);
void from_json(const nlohmann::json& j, AdamWOptions& o);

class AdamW {
 public:
  // `damping_index`: position of β in θ, excluded from decay when !decay_damping.
  AdamW(Index n_params, AdamWOptions options, std::optional<Index> damping_index = {});
  // One update of theta in place with gradient g (src/kernels/adamw_update.hpp: the same
  // bits whether its AVX-512 kernel or the portable code runs).
  void step(ParamsRef theta, const Vector& g);
  long steps_taken() const { return t_; }
  // Changes the learning rate for the following steps (for schedules).
  void set_lr(double lr) { opt_.lr = lr; }
  double lr() const { return opt_.lr; }

 private:
  AdamWOptions opt_;
  std::optional<Index> damping_index_;
  Vector m_, v_;
  long t_ = 0;

  void check_sizes(ParamsRef theta, const Vector& g) const;
};

}  // namespace csympnet
