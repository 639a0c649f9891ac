// G-SympNet(L, w) (Jin et al. 2020), step-dependent: L gradient modules, alternating kick
// (even k) and drift (odd k):
//
//   kick   p += h Kᵀ (a ⊙ σ(K q + b)),   drift   q += h Kᵀ (a ⊙ σ(K p + b)),
//
// with K ∈ R^{w×d}, a, b ∈ R^w. Each increment is the gradient of
// V(x) = Σ_i a_i ∫σ(K_i x + b_i), so every module is an exactly symplectic shear.
//
// Layout of θ, module by module (k = 0 .. L-1): K_k (w x d, column-major), a_k (w), b_k (w).
// n_params = L w (d + 2).
//
// init_params walks θ in that order and draws one rng.normal() per K or a entry (scaled by
// kInitStddev = 0.01); b is set to 0 without consuming draws.
#pragma once

#include "symplectic_core.hpp"

namespace csympnet {

class GSympNet final : public SymplecticCore {
 public:
  static constexpr double kInitStddev = 0.01;

  // Throws Error unless d, layers, width >= 1.
  GSympNet(Index d, Index layers, Index width);

  std::string type() const override { return "g"; }
  Index n_params() const override { return layers_ * width_ * (d() + 2); }
  void init_params(Rng& rng, ParamsRef theta) const override;
  nlohmann::json core_spec() const override;
  // What flow() records, module by module, and the column-split backward's records.
  struct FlowContext final : ForwardContext {
    const char* owner() const override { return "g core"; }
    struct Module {
      Matrix input;  // what the module reads: q for a kick, p for a drift (d x N)
      Matrix sigma;  // σ(K x + b) (w x N)
    };
    // The backward sweep's values at module k (y = a ⊙ σ(u), u = K x + b), read by the
    // parameter sums: G_dst H (d x N), dL/dy and dL/du (w x N each).
    struct ModuleRecords {
      Matrix g_dst_h;
      Matrix gy;
      Matrix gu;
    };
    std::vector<Module> modules;
    // Written by backward_columns() through a const cache: scratch of the backward pass, kept
    // so that the epochs of a training run reuse the storage.
    mutable std::vector<ModuleRecords> records;
  };

  void flow_backward(ConstParams theta, const ForwardCache& flow_cache, const Vector& h, Matrix& gq,
                     Matrix& gp, ParamsRef grad) const override;
  void flow_tangent(ConstParams theta, Vector& q, Vector& p, Matrix& tq, Matrix& tp,
                    double h) const override;

  bool splits_columns(Index n, const std::vector<Columns>& ranges) const override;
  void size_flow(ForwardCache& flow_cache, Index n, bool records) const override;
  void flow_columns(ConstParams theta, Matrix& q, Matrix& p, const Vector& h,
                    ForwardCache* flow_cache, Columns cols) const override;
  void backward_columns(ConstParams theta, const ForwardCache& flow_cache, const Vector& h,
                        Matrix& gq, Matrix& gp, Columns cols) const override;
  void backward_params(ConstParams theta, const ForwardCache& flow_cache, const Vector& h,
                       ParamsRef grad, Share share) const override;

  Index layers() const { return layers_; }
  Index width() const { return width_; }

 private:
  Index module_offset(Index k) const { return k * width_ * (d() + 2); }
  // This core's flow context in flow_cache, refused (Error naming `reader`) unless a flow of a
  // core with as many modules recorded it.
  const FlowContext& recorded(const ForwardCache& flow_cache, const char* reader) const;
  // Module k's backward as a sweep step on columns cols (the input gradients, and the records'
  // gh, gy, gu on those columns) and a parameter step over all columns.
  void sweep_module(ConstParams theta, Index k, const FlowContext::Module& rec, const Vector& h,
                    Matrix& gq, Matrix& gp, Columns cols, FlowContext::ModuleRecords& out) const;
  void params_module(ConstParams theta, Index k, const FlowContext::Module& rec,
                     const FlowContext::ModuleRecords& in, ParamsRef grad) const;

  Index layers_;
  Index width_;
};

}  // namespace csympnet
