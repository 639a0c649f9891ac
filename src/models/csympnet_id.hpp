// CSympNet-ID (paper eq. csympnet_def):
//
//   Φ̂_h = S_a ∘ Ψ_h ∘ S_a,   S_a(q, p) = (q, a p),   a(h) = exp(−γ̂ h / 2),   γ̂ = |β|,
//
// with Ψ_h an exactly symplectic SympNet core. Then DΦ̂ᵀ J DΦ̂ = λ(h) J with
// λ(h) = a² = exp(−γ̂ h) (eq. exact_csp), by construction and for every θ, z and h.
//
// Layout of θ: the core's parameters (its own documented layout), then, for a driven map with m
// known inputs, B (d × m, row by row), then β as the LAST entry; n_params = core.n_params() +
// d·m + 1, damping_param_index() = n_params − 1.
//
// Known inputs (models/inputs.hpp; docs/derivations.md, "Known inputs: the neural cores"): with
// H = H₀ − qᵀB u(t), the input's force enters as two half-kicks around the core,
//
//   Φ̂_h(z; u) = S_a ∘ K_{h/2, u(t₀+h)} ∘ Ψ_h ∘ K_{h/2, u(t₀)} ∘ S_a,   K_{τ,u}(q, p) = (q, p + τ B
//   u),
//
// u(t₀+h) as the hold gives it (the first-order hold: the sample at the step's end; the
// zero-order hold: the one at its start). A kick is a translation in p, so symplectic, and the
// map stays exactly conformally symplectic with factor a² for every input; with every input 0
// it is the free map.
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

#include "csympnet/models/inputs.hpp"
#include "symplectic_core.hpp"

namespace csympnet {

class CSympNetId final : public OneStepMap, public ColumnSplitPasses {
 public:
  static constexpr double kDefaultBetaInit = 0.1;

  // Throws Error if core is null or beta_init is 0 or not finite.
  explicit CSympNetId(std::unique_ptr<SymplecticCore> core, double beta_init = kDefaultBetaInit,
                      InputSpec inputs = {});

  const SymplecticCore& core() const { return *core_; }
  double beta_init() const { return beta_init_; }

  std::string type() const override { return "csympnet"; }
  Index dim() const override { return core_->dim(); }
  Index n_params() const override { return core_->n_params() + core_->d() * inputs_.m + 1; }
  // The core's draws, B = 0, β = beta_init.
  void init_params(Rng& rng, ParamsRef theta) const override;

  Index n_inputs() const override { return inputs_.m; }
  const InputSpec& inputs() const { return inputs_; }
  // θ's entry of B(r, j) (r < d, j < m).
  Index input_index(Index r, Index j) const { return core_->n_params() + r * inputs_.m + j; }

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
    Matrix u;           // a driven pass's inputs (2m x N), empty for a free one
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
  // The half-kicks around the core (above); U with 0 rows: forward().
  Matrix forward_driven(ConstParams theta, const Matrix& Z, const Vector& h, const Matrix& U,
                        ForwardCache* cache) const override;
  // The kicks are translations: DΦ̂ is DΨ's at the kicked state, between the scalings.
  Matrix jacobian_driven(ConstParams theta, const Vector& z, double h,
                         const Vector& u) const override;

  std::optional<double> damping_rate(ConstParams theta) const override;
  std::optional<Index> damping_param_index() const override { return n_params() - 1; }
  nlohmann::json hyperparams() const override;

  // The column-split passes (column_split.hpp), for free maps with d > 1 whose sweeps split.
  const ColumnSplitPasses* column_split() const override { return inputs_.m == 0 ? this : nullptr; }
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

  // p += (h_j / 2) B u(t₀ + σ h_j) per column j (σ = 0: the first kick, 1: the second).
  void kick(ConstParams theta, Matrix& p, const Vector& h, const Matrix& U, double sigma) const;
  // grad(B) += Σ_j (h_j / 2) gp_j u(t₀ + σ h_j)ᵀ: the kick's parameter gradient for the gradient
  // gp of p after it.
  void kick_backward(const Matrix& gp, const Vector& h, const Matrix& U, double sigma,
                     ParamsRef grad) const;
  void check_inputs(const Matrix& U, Index n) const;

  std::unique_ptr<SymplecticCore> core_;
  double beta_init_;
  InputSpec inputs_;
};

}  // namespace csympnet
