// LA-SympNet(L, m) (Jin et al. 2020), step-dependent: every increment is multiplied by h.
//
//   linear module k (m sublayers, kick first; S = A + Aᵀ keeps each shear symplectic):
//     kick  p += h S q,   drift  q += h S p,   ...,   then  p += h b_p,  q += h b_q
//   activation module j between linear modules j and j+1 (kick for even j, drift for odd j):
//     kick  p += h a ⊙ σ(q),   drift  q += h a ⊙ σ(p)
//
// Layout of θ, in application order; d x d matrices are column-major:
//   for k = 0 .. L-1:  A_{k,0}, ..., A_{k,m-1} (d² each), b_p (d), b_q (d),
//                      then, if k < L-1, the activation amplitude a_k (d).
// n_params = L (m d² + 2d) + (L − 1) d.
//
// init_params walks θ in that order and draws one rng.normal() per A or a entry (scaled by
// kInitStddev = 0.01); biases are set to 0 without consuming draws.
//
// Step polynomials (step_terms = 2, beyond Jin et al.): every linear sublayer and activation
// module gets its own coefficient c and scales its increment by τ = h (1 + c h) instead of h.
// Each update stays a shear, so Ψ is symplectic at every h. Why (docs/identification.md, "An
// h-dependent core"): with increments linear in h, the qp-part of log Ψ_h is even in h, while
// the exact Ψ_h of a damped system has it at h³, a misfit no width or depth removes. The
// coefficients follow the other parameters in θ, linear sublayers first (module-major), then
// the activation modules: L m + L − 1 more parameters, initialised to 0 without consuming
// draws (τ = h exactly, so the map at initialisation is the step_terms = 1 map).
#pragma once

#include "symplectic_core.hpp"

namespace csympnet {

namespace kernels {
struct D1Core;            // src/kernels/d1_sweeps.hpp
enum class Family : int;  // src/kernels/registry.hpp
}  // namespace kernels
namespace detail {
// src/models/la_d1_check.cpp: the self-checks of the d = 1 sweeps' AVX-512 and AVX2 forms, and
// what both run on the form they name.
bool la_d1_kernels_agree();
bool la_d1_avx2_kernels_agree();
bool la_d1_form_agrees(kernels::Family form);

// S = A + Aᵀ for the d x d block A of θ at `offset` (la_sympnet.cpp and la_sympnet_sweeps.cpp).
inline void symmetric_from(ConstParams theta, Index offset, Index d, Matrix& s) {
  const Eigen::Map<const Matrix> a(theta.data() + offset, d, d);
  s = a + a.transpose();
}
}  // namespace detail

class LaSympNet final : public SymplecticCore {
 public:
  static constexpr double kInitStddev = 0.01;

  // Throws Error unless d, layers, sublayers >= 1 and step_terms is 1 or 2.
  LaSympNet(Index d, Index layers, Index sublayers, Index step_terms = 1);

  std::string type() const override { return "la"; }
  Index n_params() const override;
  void init_params(Rng& rng, ParamsRef theta) const override;
  nlohmann::json core_spec() const override;

  // What flow() records, and the column-split backward's records.
  struct FlowContext final : ForwardContext {
    const char* owner() const override { return "la core"; }
    // The backward sweep's values at one unit (backward_units()), read by its parameter step:
    // a shear or an activation module keeps gh = G_dst ⊙ τ and, with step polynomials, g_dst;
    // a bias unit keeps g_p and g_q. Unused members stay empty.
    struct SweepRecords {
      Matrix gh;
      Matrix g_dst;
      Matrix gp;
      Matrix gq;
    };
    // In application order, per linear module k: the input of each of its sublayers, then
    // (k < L − 1) σ of the activation module after it; recorded_steps() in all. One array in
    // that order because the d = 1 kernels walk it as rows (d1_sweeps.hpp).
    std::vector<Matrix> steps;
    // Per unit of backward_units(), written by backward_columns() through a const cache:
    // scratch of the backward pass, kept so that the epochs of a training run reuse it.
    mutable std::vector<SweepRecords> records;
  };
  // How many entries of FlowContext::steps one flow() records.
  std::size_t recorded_steps() const;

  // d = 1 runs single-row sweeps (flow_d1); d > 1 the column passes of la_sympnet_sweeps.cpp.
  void flow(ConstParams theta, Matrix& q, Matrix& p, const Vector& h,
            ForwardCache* flow_cache) const override;
  void flow_backward(ConstParams theta, const ForwardCache& flow_cache, const Vector& h, Matrix& gq,
                     Matrix& gp, ParamsRef grad) const override;
  void flow_tangent(ConstParams theta, Vector& q, Vector& p, Matrix& tq, Matrix& tp,
                    double h) const override;

  // The column-split passes need d > 1 (false from splits_columns() at d = 1, and the other
  // four throw Error there).
  bool splits_columns(Index n, const std::vector<Columns>& ranges) const override;
  void size_flow(ForwardCache& flow_cache, Index n, bool records) const override;
  void flow_columns(ConstParams theta, Matrix& q, Matrix& p, const Vector& h,
                    ForwardCache* flow_cache, Columns cols) const override;
  void backward_columns(ConstParams theta, const ForwardCache& flow_cache, const Vector& h,
                        Matrix& gq, Matrix& gp, Columns cols) const override;
  void backward_params(ConstParams theta, const ForwardCache& flow_cache, const Vector& h,
                       ParamsRef grad, Share share) const override;

  Index layers() const { return layers_; }
  Index sublayers() const { return sublayers_; }
  Index step_terms() const { return step_terms_; }

 private:
  // flow() and flow_backward() for d = 1: the d = 1 sweep kernels (src/kernels/d1_sweeps.hpp)
  // where they run, else the single-row loops below.
  void flow_d1(ConstParams theta, Matrix& q, Matrix& p, const Vector& h,
               ForwardCache* flow_cache) const;
  void flow_backward_d1(ConstParams theta, const FlowContext& ctx, const Vector& h, Matrix& gq,
                        Matrix& gp, ParamsRef grad) const;
  // The d = 1 loops in Eigen expressions, what runs where the kernels do not, and the reference
  // of their self-check (la_d1_check.cpp).
  void flow_d1_rows(ConstParams theta, Matrix& q, Matrix& p, const Vector& h,
                    FlowContext* ctx) const;
  void flow_backward_d1_rows(ConstParams theta, const FlowContext& ctx, const Vector& h, Matrix& gq,
                             Matrix& gp, ParamsRef grad) const;
  // This core's flow context in flow_cache, with its steps sized for recorded_steps() (the d = 1
  // paths size the rows themselves).
  FlowContext& flow_context(ForwardCache& flow_cache) const;
  // The flow context recorded in flow_cache, refused (Error naming `reader`) unless a flow of a
  // core with as many steps recorded it.
  const FlowContext& recorded(const ForwardCache& flow_cache, const char* reader) const;
  kernels::D1Core d1_core() const;
  friend bool detail::la_d1_form_agrees(kernels::Family form);

  // The backward sweep at d > 1 as a sequence of units (la_sympnet_sweeps.cpp): for k = L−1
  // … 0, the activation module after linear module k (k < L − 1), the biases of module k, then
  // its shears m−1 … 0. Each unit's sweep step updates the input gradients on a range of
  // columns; its parameter step adds its block of dL/dθ from what the sweep step left.
  struct Unit;
  struct UnitRecords;
  std::vector<Unit> backward_units() const;
  void require_batch_core(const char* what) const;
  void sweep_unit(ConstParams theta, const Unit& u, const FlowContext& ctx, const Vector& h,
                  Matrix& gq, Matrix& gp, Columns cols, const UnitRecords& out) const;
  void params_unit(ConstParams theta, const Unit& u, const FlowContext& ctx, const Vector& h,
                   const Vector& h2, const UnitRecords& in, ParamsRef grad) const;
  // flow_backward() at d > 1: each unit's sweep step on all columns, then its parameter step.
  void flow_backward_batch(ConstParams theta, const FlowContext& ctx, const Vector& h, Matrix& gq,
                           Matrix& gp, ParamsRef grad) const;
  // τ on columns cols: h itself when step_terms = 1, else h ⊙ (1 + c h) written to buf.
  const double* unit_step_columns(ConstParams theta, Index coef, const Vector& h, Columns cols,
                                  Vector& buf) const;

  // Offset of linear module k in θ (each module but the last is followed by its activation).
  Index module_offset(Index k) const { return k * (sublayers_ * d() * d() + 3 * d()); }
  // θ entries of the step coefficients (step_terms = 2 only): linear sublayer i of module k,
  // and the activation module after linear module k.
  Index shear_coef(Index k, Index i) const { return n_layer_params() + k * sublayers_ + i; }
  Index act_coef(Index k) const { return n_layer_params() + layers_ * sublayers_ + k; }
  Index n_layer_params() const;
  // The step a unit with coefficient at θ(coef) scales its increment by: h itself when
  // step_terms = 1, else τ = h ⊙ (1 + c h), written to buf.
  const Vector& unit_step(ConstParams theta, Index coef, const Vector& h, Vector& buf) const;
  double unit_step(ConstParams theta, Index coef, double h) const;

  Index layers_;
  Index sublayers_;
  Index step_terms_;
};

}  // namespace csympnet
