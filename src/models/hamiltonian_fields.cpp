// DHNN, DHNN2, pHNN and pHNN2: f = M ∇H (+ ∇D for DHNN, + (0, −γ̂p) for DHNN2) with
// M = J_θ, J_θ − LLᵀ or J_θ − γ̂ diag(0, I). Derivations: docs/derivations.md, "H-based fields".
#include <cmath>

#include "activation.hpp"
#include "csympnet/core/error.hpp"
#include "library_map_detail.hpp"
#include "mlp_rop.hpp"
#include "vector_field_checks.hpp"
#include "vector_field_models.hpp"

namespace csympnet {

namespace {

const char* type_name(Dissipation kind) {
  switch (kind) {
    case Dissipation::kNetwork:
      return "dhnn";
    case Dissipation::kMomentumDamping:
      return "dhnn2";
    case Dissipation::kPortMatrix:
      return "phnn";
    case Dissipation::kPortDamping:
      return "phnn2";
  }
  return "?";
}

// Sizes of H (and D): n → w → w → 1, validated first so the error names the model.
std::vector<Index> scalar_net_sizes(Dissipation kind, Index d, Index width) {
  require(d >= 1 && width >= 1, [&] {
    return std::string(type_name(kind)) + ": d = " + std::to_string(d) +
           ", width = " + std::to_string(width) + ", expected both >= 1";
  });
  return {2 * d, width, width, 1};
}

using library_detail::abs_derivative;

}  // namespace

namespace {
// These fields hold dense 2d × 2d matrices (J and the structure matrices): refuse a d whose
// matrix would not fit in memory before allocating it, instead of std::bad_alloc.
constexpr Index kMaxDenseD = 4096;  // 2d × 2d doubles: 537 MB
Index checked_dense_dim(Index d) {
  require(d >= 1 && d <= kMaxDenseD, [&] {
    return "d = " + std::to_string(d) +
           " is too large for a Hamiltonian vector-field model, which holds dense 2d x 2d "
           "matrices; expected d <= " +
           std::to_string(kMaxDenseD);
  });
  return d;
}
}  // namespace

HamiltonianField::HamiltonianField(Dissipation kind, Index d, Index width, double beta_init,
                                   bool freeze_structure)
    : kind_(kind),
      d_(d),
      width_(width),
      beta_init_(beta_init),
      freeze_structure_(freeze_structure),
      h_(scalar_net_sizes(kind, d, width)),
      structure_offset_(kind == Dissipation::kNetwork ? 2 * h_.n_params() : h_.n_params()),
      n_params_(0),
      canonical_(canonical_j(checked_dense_dim(d))) {
  if (has_beta()) {
    require(std::isfinite(beta_init) && beta_init != 0.0, [&] {
      return type() + ": beta_init = " + std::to_string(beta_init) +
             ", expected a finite nonzero value (d|beta|/dbeta vanishes at 0, so beta would "
             "never train)";
    });
  }
  const Index n = 2 * d;
  Index extra = 0;
  if (kind == Dissipation::kPortMatrix) extra = n * n;
  if (has_beta()) extra = 1;
  n_params_ = structure_offset_ + n * n + extra;
}

std::string HamiltonianField::type() const {
  return type_name(kind_);
}

bool HamiltonianField::has_beta() const {
  return kind_ == Dissipation::kMomentumDamping || kind_ == Dissipation::kPortDamping;
}

Index HamiltonianField::port_offset() const {
  return kind_ == Dissipation::kPortMatrix ? structure_offset_ + dim() * dim() : -1;
}

Index HamiltonianField::beta_offset() const {
  return has_beta() ? n_params_ - 1 : -1;
}

void HamiltonianField::init_params(Rng& rng, ParamsRef theta) const {
  detail::check_field_theta(*this, theta.size(), "init_params");
  const Index nh = h_.n_params();
  const Index n = dim();
  h_.init_params(rng, theta.head(nh));
  if (kind_ == Dissipation::kNetwork) h_.init_params(rng, theta.segment(nh, nh));
  // J_θ starts at the canonical J even when frozen, so θ reads the same either way.
  theta.segment(structure_offset_, n * n) = canonical_.reshaped();
  if (kind_ == Dissipation::kPortMatrix) {
    for (Index i = 0; i < n * n; ++i) theta(port_offset() + i) = rng.normal(0.0, kPortInitStd);
  }
  if (has_beta()) theta(beta_offset()) = beta_init_;
}

Eigen::Map<const Matrix> HamiltonianField::structure(ConstParams theta) const {
  const double* data = freeze_structure_ ? canonical_.data() : theta.data() + structure_offset_;
  return Eigen::Map<const Matrix>(data, dim(), dim());
}

Matrix HamiltonianField::effective_structure(ConstParams theta) const {
  Matrix m = structure(theta);
  if (kind_ == Dissipation::kPortMatrix) {
    const Eigen::Map<const Matrix> l(theta.data() + port_offset(), dim(), dim());
    m.noalias() -= l * l.transpose();
  } else if (kind_ == Dissipation::kPortDamping) {
    m.bottomRightCorner(d_, d_).diagonal().array() -= std::abs(theta(beta_offset()));
  }
  return m;
}

Matrix HamiltonianField::field(ConstParams theta, const Matrix& Z) const {
  detail::check_field_theta(*this, theta.size(), "field");
  detail::check_field_rows(*this, Z.rows(), "field", "Z");
  const Index nh = h_.n_params();
  const Matrix grad_h = h_.input_gradient(theta.head(nh), Z);
  Matrix f;
  if (kind_ == Dissipation::kPortMatrix || kind_ == Dissipation::kPortDamping) {
    product_into(effective_structure(theta), grad_h, f);
    return f;
  }
  product_into(structure(theta), grad_h, f);
  if (kind_ == Dissipation::kNetwork) {
    f += h_.input_gradient(theta.segment(nh, nh), Z);
  } else {
    f.bottomRows(d_) -= std::abs(theta(beta_offset())) * Z.bottomRows(d_);
  }
  return f;
}

void HamiltonianField::field_backward(ConstParams theta, const Matrix& Z, const Matrix& G,
                                      ParamsRef grad) const {
  detail::check_field_backward_args(*this, theta, Z, G, grad);
  const Index nh = h_.n_params();
  const Index n = dim();
  // ⟨G, M ∇H⟩ = ⟨Mᵀ G, ∇H⟩: the R-op of H with upstream Mᵀ G gives ∂/∂θ_H, and ∇H comes
  // out of the same sweep.
  const Matrix m = effective_structure(theta);
  Matrix upstream;
  product_into(m.transpose(), G, upstream);
  Matrix grad_h;
  detail::scalar_mlp_rop(h_, theta.head(nh), Z, upstream, grad.data(), nullptr, &grad_h);

  if (kind_ == Dissipation::kNetwork) {
    h_.input_gradient_backward(theta.segment(nh, nh), Z, G, grad.segment(nh, nh), nullptr);
  }
  if (kind_ == Dissipation::kMomentumDamping) {
    // f_p ∋ −|β| p  ⇒  ∂L/∂β = −sign(β) ⟨G_P, P⟩.
    grad(beta_offset()) -= abs_derivative(theta(beta_offset())) *
                           G.bottomRows(d_).cwiseProduct(Z.bottomRows(d_)).sum();
  }
  if (kind_ == Dissipation::kPortDamping) {
    // f_p ∋ −|β| ∂H/∂p  ⇒  ∂L/∂β = −sign(β) ⟨G_P, ∇_p H⟩.
    grad(beta_offset()) -= abs_derivative(theta(beta_offset())) *
                           G.bottomRows(d_).cwiseProduct(grad_h.bottomRows(d_)).sum();
  }
  if (freeze_structure_ && kind_ != Dissipation::kPortMatrix) return;
  // ∂L/∂M = Σ_j G_j ∇H_jᵀ; J_θ enters M with coefficient 1, L through −LLᵀ.
  Matrix dm(n, n);
  dm.noalias() = G * grad_h.transpose();
  if (!freeze_structure_) {
    Eigen::Map<Matrix>(grad.data() + structure_offset_, n, n) += dm;
  }
  if (kind_ == Dissipation::kPortMatrix) {
    // ∂/∂L ⟨dM, −LLᵀ⟩ = −(dM + dMᵀ) L.
    const Eigen::Map<const Matrix> l(theta.data() + port_offset(), n, n);
    Eigen::Map<Matrix>(grad.data() + port_offset(), n, n).noalias() -= (dm + dm.transpose()) * l;
  }
}

Matrix HamiltonianField::field_jacobian(ConstParams theta, const Vector& z) const {
  detail::check_field_theta(*this, theta.size(), "field_jacobian");
  detail::check_field_rows(*this, z.size(), "field_jacobian", "z");
  const Index nh = h_.n_params();
  // Df = M ∇²H (+ ∇²D for dhnn, − γ̂ diag(0, I) for dhnn2).
  Matrix jac = effective_structure(theta) * h_.input_hessian(theta.head(nh), z);
  if (kind_ == Dissipation::kNetwork) {
    jac += h_.input_hessian(theta.segment(nh, nh), z);
  } else if (kind_ == Dissipation::kMomentumDamping) {
    jac.bottomRightCorner(d_, d_).diagonal().array() -= std::abs(theta(beta_offset()));
  }
  return jac;
}

std::optional<double> HamiltonianField::damping_rate(ConstParams theta) const {
  if (!has_beta()) return std::nullopt;
  detail::check_field_theta(*this, theta.size(), "damping_rate");
  return std::abs(theta(beta_offset()));
}

std::optional<Index> HamiltonianField::damping_param_index() const {
  if (!has_beta()) return std::nullopt;
  return beta_offset();
}

nlohmann::json HamiltonianField::hyperparams() const {
  nlohmann::json spec = {
      {"type", type()}, {"d", d_}, {"width", width_}, {"freeze_structure", freeze_structure_}};
  if (has_beta()) spec["beta_init"] = beta_init_;
  return spec;
}

}  // namespace csympnet
