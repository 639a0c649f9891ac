// CSympNet-ID (paper eq. csympnet_def):
//
//   Φ̂_h = S_a ∘ Ψ_h ∘ S_a,   S_a(q, p) = (q, a p),   a(h) = exp(−γ̂ h / 2),   γ̂ = |β|,
//
// with Ψ_h an exactly symplectic SympNet core. Then DΦ̂ᵀ J DΦ̂ = λ(h) J with
// λ(h) = a² = exp(−γ̂ h) (eq. exact_csp), by construction and for every θ, z and h.
//
// Layout of θ: the core's parameters (its own documented layout), then β as the LAST entry;
// n_params = core.n_params() + 1, damping_param_index() = n_params − 1.
//
// β and γ̂ = |β|: |·| keeps γ̂ ≥ 0 without a constrained optimiser. Its derivative sign(β)
// vanishes at β = 0, so training started at β = 0 would never move β; beta_init must
// therefore be nonzero (default kDefaultBetaInit = 0.1, i.e. a mild initial damping). Should
// β reach exactly 0 later, backward() uses the subgradient 0 there.
//
// init_params: the core's init_params (same RNG draws as the bare core), then β = beta_init
// (no draw).
#pragma once

#include <memory>

#include "symplectic_core.hpp"

namespace csympnet {

class CSympNetId final : public OneStepMap, public ColumnSplitPasses {
 public:
  static constexpr double kDefaultBetaInit = 0.1;

  // Throws Error if core is null or beta_init is 0 or not finite.
  explicit CSympNetId(std::unique_ptr<SymplecticCore> core, double beta_init = kDefaultBetaInit);

  const SymplecticCore& core() const { return *core_; }
  double beta_init() const { return beta_init_; }

  std::string type() const override { return "csympnet"; }
  Index dim() const override { return core_->dim(); }
  Index n_params() const override { return core_->n_params() + 1; }
  void init_params(Rng& rng, ParamsRef theta) const override;

  // What forward() keeps for backward(), and the column-split backward's records.
  struct Context final : ForwardContext {
    const char* owner() const override { return "csympnet"; }
    Vector h;       // the steps
    Vector a;       // a(h_j) = exp(−γ̂ h_j / 2) per column
    Matrix p_in;    // the input p, before the inner scaling (d x N)
    Matrix p_core;  // the core's p: a ⊙ p_in, in place, ending as the core's output (before the
                    // outer scaling)
    Matrix q;       // the core's q, likewise (a working buffer, kept so that an epoch reuses it)
    ForwardCache core;  // the core's flow context
    // Written by backward_columns() through a const cache: the input gradients gq, gp of the
    // sweep and dL/da per column (kept so that the epochs of a training run reuse them).
    mutable Matrix gq;
    mutable Matrix gp;
    mutable Vector grad_a;
  };

  Matrix forward(ConstParams theta, const Matrix& Z, const Vector& h,
                 ForwardCache* cache) const override;
  void backward(ConstParams theta, const ForwardCache& cache, const Matrix& dZout, ParamsRef grad,
                Matrix* dZin) const override;
  Matrix jacobian(ConstParams theta, const Vector& z, double h) const override;

  std::optional<double> damping_rate(ConstParams theta) const override;
  std::optional<Index> damping_param_index() const override { return n_params() - 1; }
  nlohmann::json hyperparams() const override;

  // The column-split passes (column_split.hpp), for cores with d > 1 whose sweeps split.
  const ColumnSplitPasses* column_split() const override { return this; }
  bool splits(Index n, const std::vector<Columns>& ranges) const override;
  void prepare(ConstParams theta, const Vector& h, ForwardCache& cache) const override;
  void forward_columns(ConstParams theta, const Matrix& Z, ForwardCache& cache, Matrix& out,
                       Columns cols) const override;
  void backward_columns(ConstParams theta, const ForwardCache& cache, const Matrix& dZout,
                        Columns cols) const override;
  void backward_params(ConstParams theta, const ForwardCache& cache, ParamsRef grad,
                       Share share) const override;
  void backward_finish(ConstParams theta, const ForwardCache& cache, ParamsRef grad) const override;

 private:
  // Makes cache hold this model's context with the forward's entries (not the backward
  // records) sized for the steps h, and returns it.
  Context& size_forward(const Vector& h, ForwardCache& cache) const;
  // The context in cache, refused (Error naming `reader`) unless a forward pass of a
  // CSympNet-ID of this d recorded it.
  const Context& recorded(const ForwardCache& cache, const char* reader) const;

  std::unique_ptr<SymplecticCore> core_;
  double beta_init_;
};

}  // namespace csympnet
