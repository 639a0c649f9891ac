#include "mlp.hpp"

#include <cmath>
#include <string>
#include <utility>

#include "activation.hpp"
#include "csympnet/core/error.hpp"
#include "mlp_rop.hpp"

namespace csympnet {

namespace {

using ConstMatMap = Eigen::Map<const Matrix>;
using ConstVecMap = Eigen::Map<const Vector>;
using MatMap = Eigen::Map<Matrix>;
using VecMap = Eigen::Map<Vector>;

// Position of W_l in θ; b_l follows it. Layers are few (3 here), so a linear scan is free.
Index weight_offset(const std::vector<Index>& sizes, std::size_t layer) {
  Index offset = 0;
  for (std::size_t l = 0; l < layer; ++l) offset += (sizes[l] + 1) * sizes[l + 1];
  return offset;
}

struct Layer {
  ConstMatMap w;
  ConstVecMap b;
};

Layer layer_at(const std::vector<Index>& sizes, const double* theta, std::size_t l) {
  const Index offset = weight_offset(sizes, l);
  const Index rows = sizes[l + 1];
  const Index cols = sizes[l];
  return {ConstMatMap(theta + offset, rows, cols), ConstVecMap(theta + offset + rows * cols, rows)};
}

struct LayerGrad {
  MatMap w;
  VecMap b;
};

LayerGrad layer_grad_at(const std::vector<Index>& sizes, double* grad, std::size_t l) {
  const Index offset = weight_offset(sizes, l);
  const Index rows = sizes[l + 1];
  const Index cols = sizes[l];
  return {MatMap(grad + offset, rows, cols), VecMap(grad + offset + rows * cols, rows)};
}

// tanh'(z) written through the cached a = tanh(z): 1 − a².
auto tanh_slope(const Matrix& a) {
  return 1.0 - a.array().square();
}

void check_input(const Mlp& mlp, ConstParams theta, Index rows, const char* where) {
  require(theta.size() == mlp.n_params(), [&] {
    return std::string("Mlp::") + where + ": theta has " + std::to_string(theta.size()) +
           " entries, expected n_params() = " + std::to_string(mlp.n_params());
  });
  require(rows == mlp.in_dim(), [&] {
    return std::string("Mlp::") + where + ": input has " + std::to_string(rows) +
           " rows, expected in_dim() = " + std::to_string(mlp.in_dim());
  });
}

void check_scalar(const Mlp& mlp, const char* where) {
  require(mlp.out_dim() == 1, [&] {
    return std::string("Mlp::") + where +
           ": defined for scalar networks only, but out_dim() = " + std::to_string(mlp.out_dim());
  });
}

}  // namespace

Mlp::Mlp(std::vector<Index> sizes) : sizes_(std::move(sizes)) {
  require(sizes_.size() >= 2, [&] {
    return "Mlp: needs at least an input and an output size, got " + std::to_string(sizes_.size()) +
           " sizes";
  });
  for (std::size_t l = 0; l < sizes_.size(); ++l) {
    require(sizes_[l] >= 1, [&] {
      return "Mlp: sizes[" + std::to_string(l) + "] = " + std::to_string(sizes_[l]) +
             ", expected >= 1";
    });
  }
  n_params_ = weight_offset(sizes_, sizes_.size() - 1);
}

Index Mlp::n_params() const {
  return n_params_;
}
Index Mlp::in_dim() const {
  return sizes_.front();
}
Index Mlp::out_dim() const {
  return sizes_.back();
}
const std::vector<Index>& Mlp::sizes() const {
  return sizes_;
}

void Mlp::init_params(Rng& rng, ParamsRef theta) const {
  require(theta.size() == n_params_, [&] {
    return "Mlp::init_params: theta has " + std::to_string(theta.size()) + " entries, expected " +
           std::to_string(n_params_);
  });
  // Draw order = θ order: W_l column-major, then b_l, layer by layer.
  Index k = 0;
  for (std::size_t l = 0; l + 1 < sizes_.size(); ++l) {
    const double bound = 1.0 / std::sqrt(static_cast<double>(sizes_[l]));
    const Index count = (sizes_[l] + 1) * sizes_[l + 1];
    for (Index i = 0; i < count; ++i) theta(k++) = rng.uniform(-bound, bound);
  }
}

Matrix Mlp::forward(ConstParams theta, const Matrix& X, MlpCache* cache) const {
  check_input(*this, theta, X.rows(), "forward");
  const std::size_t n_layers = sizes_.size() - 1;
  // acts[l] is the input of layer l (acts[0] = X); without a cache a local vector holds them.
  MlpCache local;
  std::vector<Matrix>& acts = cache != nullptr ? cache->acts : local.acts;
  acts.resize(n_layers);
  if (cache != nullptr) acts[0] = X;
  Matrix out;
  for (std::size_t l = 0; l < n_layers; ++l) {
    const Layer layer = layer_at(sizes_, theta.data(), l);
    const Matrix& in = (l == 0) ? X : acts[l];
    Matrix& next = (l + 1 < n_layers) ? acts[l + 1] : out;
    product_into(layer.w, in, next);
    next.colwise() += layer.b;
    if (l + 1 < n_layers) next = next.array().tanh().matrix();
  }
  return out;
}

void Mlp::backward(ConstParams theta, const MlpCache& cache, const Matrix& dY, ParamsRef grad,
                   Matrix* dX) const {
  const std::size_t n_layers = sizes_.size() - 1;
  require(cache.acts.size() == n_layers && cache.acts[0].rows() == in_dim(),
          "Mlp::backward: the cache holds no forward pass of this network (call forward with "
          "a cache first)");
  check_input(*this, theta, cache.acts[0].rows(), "backward");
  require(dY.rows() == out_dim() && dY.cols() == cache.acts[0].cols(), [&] {
    return "Mlp::backward: dY is " + std::to_string(dY.rows()) + " x " + std::to_string(dY.cols()) +
           ", expected " + std::to_string(out_dim()) + " x " +
           std::to_string(cache.acts[0].cols()) + " (the forward batch)";
  });
  require(grad.size() == n_params_, [&] {
    return "Mlp::backward: grad has " + std::to_string(grad.size()) + " entries, expected " +
           std::to_string(n_params_);
  });
  // δ_L = dY;  ∂W_l += δ_l a_lᵀ,  ∂b_l += δ_l 1,  δ_{l−1} = (W_lᵀ δ_l) ⊙ (1 − a_l²).
  Matrix delta = dY;
  Matrix back;
  for (std::size_t l = n_layers; l-- > 0;) {
    const Layer layer = layer_at(sizes_, theta.data(), l);
    LayerGrad g = layer_grad_at(sizes_, grad.data(), l);
    const Matrix& in = cache.acts[l];
    g.w.noalias() += delta * in.transpose();
    g.b.noalias() += delta.rowwise().sum();
    if (l == 0 && dX == nullptr) break;
    product_into(layer.w.transpose(), delta, back);
    if (l == 0) {
      *dX = std::move(back);
    } else {
      delta = (back.array() * tanh_slope(in)).matrix();
    }
  }
}

Matrix Mlp::input_jacobian(ConstParams theta, const Vector& x) const {
  check_input(*this, theta, x.size(), "input_jacobian");
  // Forward mode: T_0 = I, T_{l+1} = diag(1 − a_{l+1}²) W_l T_l (no tanh on the last layer).
  Vector a = x;
  Matrix t = Matrix::Identity(in_dim(), in_dim());
  const std::size_t n_layers = sizes_.size() - 1;
  for (std::size_t l = 0; l < n_layers; ++l) {
    const Layer layer = layer_at(sizes_, theta.data(), l);
    Vector z = layer.w * a + layer.b;
    Matrix next = layer.w * t;
    if (l + 1 < n_layers) {
      a = z.array().tanh().matrix();
      next.array().colwise() *= 1.0 - a.array().square();
    }
    t = std::move(next);
  }
  return t;
}

Matrix Mlp::input_gradient(ConstParams theta, const Matrix& X) const {
  check_scalar(*this, "input_gradient");
  MlpCache cache;
  forward(theta, X, &cache);
  // Backpropagation of dY = 1ᵀ without the parameter gradients.
  const std::size_t n_layers = sizes_.size() - 1;
  Matrix delta = Matrix::Ones(1, X.cols());
  Matrix back;
  for (std::size_t l = n_layers; l-- > 0;) {
    const Layer layer = layer_at(sizes_, theta.data(), l);
    product_into(layer.w.transpose(), delta, back);
    if (l == 0) break;
    delta = (back.array() * tanh_slope(cache.acts[l])).matrix();
  }
  return back;
}

Matrix Mlp::input_hessian(ConstParams theta, const Vector& x) const {
  check_scalar(*this, "input_hessian");
  check_input(*this, theta, x.size(), "input_hessian");
  // Linear layers have no curvature, so every second-order term comes from a tanh:
  //   ∇²s(x) = Σ_l T_lᵀ diag(g_l ⊙ tanh''(z_l)) T_l,
  // T_l = ∂z_l/∂x (T_1 = W_0, T_{l+1} = W_l diag(tanh'(z_l)) T_l), g_l = ∂s/∂a_l, and
  // tanh'' = −2a(1 − a²) (docs/derivations.md, "MLP"). One primal pass, one adjoint pass and
  // the tangents T_l: about a third of the FLOPs of the R-op sweep with G = I.
  const std::size_t n_layers = sizes_.size() - 1;
  std::vector<Vector> a(n_layers);  // a[l] = tanh(z_l), hidden layers l = 1 … n_layers − 1
  Vector in = x;
  for (std::size_t l = 0; l + 1 < n_layers; ++l) {
    const Layer layer = layer_at(sizes_, theta.data(), l);
    a[l + 1] = (layer.w * in + layer.b).array().tanh().matrix();
    in = a[l + 1];
  }
  // Adjoints g_l = ∂s/∂a_l, from the output down.
  std::vector<Vector> g(n_layers);
  Vector upstream = layer_at(sizes_, theta.data(), n_layers - 1).w.transpose();
  for (std::size_t l = n_layers - 1; l > 0; --l) {
    g[l] = upstream;
    const Vector dz = (upstream.array() * (1.0 - a[l].array().square())).matrix();
    upstream = layer_at(sizes_, theta.data(), l - 1).w.transpose() * dz;
  }
  Matrix hessian = Matrix::Zero(in_dim(), in_dim());
  Matrix tangent = layer_at(sizes_, theta.data(), 0).w;  // T_1
  Matrix scaled;
  for (std::size_t l = 1; l < n_layers; ++l) {
    const auto slope = 1.0 - a[l].array().square();
    const Vector curvature = (g[l].array() * (-2.0 * a[l].array() * slope)).matrix();
    scaled = curvature.asDiagonal() * tangent;
    hessian.noalias() += tangent.transpose() * scaled;
    if (l + 1 < n_layers) {
      scaled = slope.matrix().asDiagonal() * tangent;
      tangent.noalias() = layer_at(sizes_, theta.data(), l).w * scaled;
    }
  }
  return hessian;
}

void Mlp::input_gradient_backward(ConstParams theta, const Matrix& X, const Matrix& G,
                                  ParamsRef grad, Matrix* dX) const {
  require(grad.size() == n_params_, [&] {
    return "Mlp::input_gradient_backward: grad has " + std::to_string(grad.size()) +
           " entries, expected " + std::to_string(n_params_);
  });
  detail::scalar_mlp_rop(*this, theta, X, G, grad.data(), dX, nullptr);
}

namespace detail {

void scalar_mlp_rop(const Mlp& mlp, ConstParams theta, const Matrix& X, const Matrix& G,
                    double* grad, Matrix* dX, Matrix* input_grad) {
  check_scalar(mlp, "input_gradient_backward");
  check_input(mlp, theta, X.rows(), "input_gradient_backward");
  require(G.rows() == X.rows() && G.cols() == X.cols(), [&] {
    return "Mlp::input_gradient_backward: G is " + std::to_string(G.rows()) + " x " +
           std::to_string(G.cols()) + ", expected the shape of X (" + std::to_string(X.rows()) +
           " x " + std::to_string(X.cols()) + ")";
  });
  const std::vector<Index>& sizes = mlp.sizes();
  const std::size_t n_layers = sizes.size() - 1;
  const Index n = X.cols();
  // Forward sweep, primal and tangent (ȧ_0 = G): for every hidden layer
  //   a_{l+1} = tanh(W_l a_l + b_l),  ż_{l+1} = W_l ȧ_l,  ȧ_{l+1} = (1 − a_{l+1}²) ⊙ ż_{l+1};
  // the output's tangent is W_L ȧ_L = ⟨G_j, ∇s(X_j)⟩ per column, and L sums it.
  std::vector<Matrix> a(n_layers), adot(n_layers), zdot(n_layers);
  for (std::size_t l = 0; l + 1 < n_layers; ++l) {
    const Layer layer = layer_at(sizes, theta.data(), l);
    const Matrix& in = (l == 0) ? X : a[l];
    const Matrix& tin = (l == 0) ? G : adot[l];
    product_into(layer.w, in, a[l + 1]);
    a[l + 1].colwise() += layer.b;
    a[l + 1] = a[l + 1].array().tanh().matrix();
    product_into(layer.w, tin, zdot[l + 1]);
    adot[l + 1] = (zdot[l + 1].array() * tanh_slope(a[l + 1])).matrix();
  }
  const auto primal = [&](std::size_t l) -> const Matrix& { return l == 0 ? X : a[l]; };
  const auto tangent = [&](std::size_t l) -> const Matrix& { return l == 0 ? G : adot[l]; };

  // Reverse sweep. T = adjoint of ȧ_l, A = adjoint of a_l. Output layer: L = 1ᵀ W_L ȧ_L, so
  // ∂W_L = 1ᵀ ȧ_Lᵀ (row sums), T_L = W_Lᵀ 1ᵀ, A_L = 0 (L does not read the primal output).
  const std::size_t last = n_layers - 1;
  const Layer out_layer = layer_at(sizes, theta.data(), last);
  if (grad != nullptr) {
    layer_grad_at(sizes, grad, last).w.noalias() += tangent(last).rowwise().sum().transpose();
  }
  Matrix t = out_layer.w.transpose().replicate(1, n);
  Matrix adj_a = Matrix::Zero(sizes[last], n);
  Matrix adj_zdot, adj_z;
  for (std::size_t l = last; l > 0; --l) {
    // At a hidden output a_l with slope s' = 1 − a_l²:
    //   ∂L/∂ż_l = T ⊙ s',   ∂L/∂a_l = A − 2 a_l ⊙ ż_l ⊙ T  (through s' in ȧ_l),
    //   ∂L/∂z_l = (∂L/∂a_l) ⊙ s'.
    const auto slope = tanh_slope(a[l]);
    adj_zdot = (t.array() * slope).matrix();
    adj_z = ((adj_a.array() - 2.0 * a[l].array() * zdot[l].array() * t.array()) * slope).matrix();
    // Layer l−1: z_l = W a + b and ż_l = W ȧ share W.
    const Layer layer = layer_at(sizes, theta.data(), l - 1);
    if (grad != nullptr) {
      LayerGrad g = layer_grad_at(sizes, grad, l - 1);
      g.w.noalias() += adj_zdot * tangent(l - 1).transpose();
      g.w.noalias() += adj_z * primal(l - 1).transpose();
      g.b.noalias() += adj_z.rowwise().sum();
    }
    if (l > 1 || input_grad != nullptr) product_into(layer.w.transpose(), adj_zdot, t);
    if (l > 1 || dX != nullptr) product_into(layer.w.transpose(), adj_z, adj_a);
  }
  // With no hidden layer ∇s = W_0ᵀ is constant: T and A above are already right.
  if (dX != nullptr) *dX = std::move(adj_a);
  if (input_grad != nullptr) *input_grad = std::move(t);
}

}  // namespace detail

}  // namespace csympnet
