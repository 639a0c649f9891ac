#include "csympnet/systems/system.hpp"

#include <cmath>
#include <limits>
#include <utility>

#include "csympnet/core/error.hpp"

namespace csympnet {

namespace {

constexpr const char* kValidKinds = "oscillator, chain, cubic";

void require_finite(double x, const char* field) {
  require(std::isfinite(x), [&] {
    return std::string("system.") + field + " must be a finite number, got " + number_text(x);
  });
}

// ∇V for one column stored contiguously (q and g have length d). The batched and single-state
// gradients both call this, so their results agree to the bit.
//   oscillator: g = ω² q
//   chain:      g_i = k (q_i − q_{i−1}) − k (q_{i+1} − q_i), missing neighbours dropped
//   cubic:      g = ω² q + 3α s² 1, s = Σ q_i
void grad_column(const SystemSpec& s, const double* q, double* g, Index d) {
  if (s.kind == "chain") {
    for (Index i = 0; i < d; ++i) g[i] = 0.0;
    for (Index i = 0; i + 1 < d; ++i) {
      const double f = s.k * (q[i + 1] - q[i]);  // spring force between i and i+1
      g[i] -= f;
      g[i + 1] += f;
    }
    return;
  }
  const double w2 = s.omega * s.omega;
  double c = 0.0;
  if (s.kind == "cubic") {
    double sum = 0.0;
    for (Index i = 0; i < d; ++i) sum += q[i];
    c = 3.0 * s.alpha * sum * sum;
  }
  for (Index i = 0; i < d; ++i) g[i] = w2 * q[i] + c;
}

void check_length(Index got, Index want, const char* where, const char* what) {
  require(got == want, [&] {
    return std::string("System::") + where + ": " + what + " has length " + std::to_string(got) +
           ", expected " + std::to_string(want);
  });
}

}  // namespace

void SystemSpec::validate() const {
  require(kind == "oscillator" || kind == "chain" || kind == "cubic", [&] {
    return "system.kind must be one of " + std::string(kValidKinds) + "; got \"" + kind + "\"";
  });
  require(d >= 1, [&] { return "system.d must be an integer >= 1, got " + std::to_string(d); });
  require(std::isfinite(gamma) && gamma >= 0.0,
          [&] { return "system.gamma must be a finite number >= 0, got " + number_text(gamma); });
  require_finite(omega, "omega");
  require_finite(k, "k");
  require_finite(alpha, "alpha");
  if (kind != "chain")
    require(omega > 0.0, [&] {
      return "system.omega must be > 0 for kind \"" + kind + "\", got " + number_text(omega);
    });
  require(k >= 0.0, [&] { return "system.k must be >= 0, got " + number_text(k); });
}

void to_json(nlohmann::json& j, const SystemSpec& s) {
  j = nlohmann::json{{"kind", s.kind},   {"d", s.d}, {"gamma", s.gamma},
                     {"omega", s.omega}, {"k", s.k}, {"alpha", s.alpha}};
}

void from_json(const nlohmann::json& j, SystemSpec& s) {
  require(j.is_object(),
          [&] { return "system: expected a JSON object, got " + std::string(j.type_name()); });
  SystemSpec out;
  for (const auto& item : j.items()) {  // not a structured binding: clang 14 cannot capture it
    const std::string& key = item.key();
    const nlohmann::json& value = item.value();
    const std::string where = "system." + key;
    if (key == "kind") {
      require(value.is_string(),
              [&] { return where + " must be a string, got " + value.type_name(); });
      out.kind = value.get<std::string>();
    } else if (key == "d") {
      require(value.is_number_integer(),
              [&] { return where + " must be an integer, got " + value.dump(); });
      const auto v = value.get<long long>();
      require(v >= 1 && v <= std::numeric_limits<int>::max(),
              [&] { return where + " must be an integer >= 1, got " + value.dump(); });
      out.d = static_cast<int>(v);
    } else if (key == "gamma" || key == "omega" || key == "k" || key == "alpha") {
      require(value.is_number(), [&] { return where + " must be a number, got " + value.dump(); });
      const double v = value.get<double>();
      if (key == "gamma") out.gamma = v;
      if (key == "omega") out.omega = v;
      if (key == "k") out.k = v;
      if (key == "alpha") out.alpha = v;
    } else {
      throw Error("system: unknown key \"" + key + "\" (allowed: kind, d, gamma, omega, k, alpha)");
    }
  }
  require(j.contains("kind"),
          [&] { return "system.kind is required (one of " + std::string(kValidKinds) + ")"; });
  require(j.contains("d"), "system.d is required (an integer >= 1)");
  out.validate();
  s = std::move(out);
}

System::System(SystemSpec spec) : spec_(std::move(spec)) {
  spec_.validate();
}

double System::potential(const Vector& q) const {
  check_length(q.size(), d(), "potential", "q");
  if (spec_.kind == "chain") {
    double v = 0.0;
    for (Index i = 0; i + 1 < d(); ++i) v += (q(i + 1) - q(i)) * (q(i + 1) - q(i));
    return 0.5 * spec_.k * v;
  }
  double v = 0.5 * spec_.omega * spec_.omega * q.squaredNorm();
  if (spec_.kind == "cubic") {
    const double s = q.sum();
    v += spec_.alpha * s * s * s;
  }
  return v;
}

Vector System::grad_potential(const Vector& q) const {
  check_length(q.size(), d(), "grad_potential", "q");
  Vector g(d());
  grad_column(spec_, q.data(), g.data(), d());
  return g;
}

Matrix System::grad_potential_batch(const Matrix& Q) const {
  require(Q.rows() == d(), [&] {
    return "System::grad_potential_batch: Q has " + std::to_string(Q.rows()) +
           " rows, expected d = " + std::to_string(d());
  });
  Matrix G(d(), Q.cols());
  // Column-major storage: column j starts at data() + j d.
  for (Index j = 0; j < Q.cols(); ++j) grad_column(spec_, Q.col(j).data(), G.col(j).data(), d());
  return G;
}

Matrix System::hess_potential(const Vector& q) const {
  check_length(q.size(), d(), "hess_potential", "q");
  return hess_potential_times(q, Matrix::Identity(d(), d()));
}

Matrix System::hess_potential_times(const Vector& q, const Matrix& X) const {
  check_length(q.size(), d(), "hess_potential_times", "q");
  require(X.rows() == d(), [&] {
    return "System::hess_potential_times: X has " + std::to_string(X.rows()) +
           " rows, expected d = " + std::to_string(d());
  });
  const Index n = d();
  if (spec_.kind == "chain") {
    // ∇²V = k L with L the path-graph Laplacian: (L X)_i = (X_i − X_{i−1}) − (X_{i+1} − X_i).
    Matrix R = Matrix::Zero(n, X.cols());
    if (n > 1) {
      const Matrix D = spec_.k * (X.bottomRows(n - 1) - X.topRows(n - 1));
      R.topRows(n - 1) -= D;
      R.bottomRows(n - 1) += D;
    }
    return R;
  }
  Matrix R = (spec_.omega * spec_.omega) * X;
  if (spec_.kind == "cubic") {
    // ∇²V = ω² I + 6α s 11ᵀ, s = Σ q_i.
    const double c = 6.0 * spec_.alpha * q.sum();
    R.rowwise() += c * X.colwise().sum();
  }
  return R;
}

double System::energy(const Vector& z) const {
  check_length(z.size(), dim(), "energy", "z");
  return 0.5 * z.tail(d()).squaredNorm() + potential(z.head(d()));
}

Vector System::grad_energy(const Vector& z) const {
  check_length(z.size(), dim(), "grad_energy", "z");
  Vector g(dim());
  g.head(d()) = grad_potential(z.head(d()));
  g.tail(d()) = z.tail(d());
  return g;
}

Matrix System::hess_energy(const Vector& z) const {
  check_length(z.size(), dim(), "hess_energy", "z");
  Matrix h = Matrix::Zero(dim(), dim());
  h.topLeftCorner(d(), d()) = hess_potential(z.head(d()));
  h.bottomRightCorner(d(), d()).setIdentity();
  return h;
}

Vector System::vector_field(const Vector& z) const {
  check_length(z.size(), dim(), "vector_field", "z");
  Vector f(dim());
  f.head(d()) = z.tail(d());
  f.tail(d()) = -grad_potential(z.head(d())) - spec_.gamma * z.tail(d());
  return f;
}

Matrix System::vector_field_jacobian(const Vector& z) const {
  check_length(z.size(), dim(), "vector_field_jacobian", "z");
  // Df = [[0, I], [−∇²V, −γI]].
  Matrix a = Matrix::Zero(dim(), dim());
  a.topRightCorner(d(), d()).setIdentity();
  a.bottomLeftCorner(d(), d()) = -hess_potential(z.head(d()));
  a.bottomRightCorner(d(), d()).diagonal().setConstant(-spec_.gamma);
  return a;
}

bool System::is_linear() const {
  return spec_.kind != "cubic";
}

Matrix System::linear_generator() const {
  require(is_linear(), [&] {
    return "System::linear_generator: kind \"" + spec_.kind +
           "\" is nonlinear; only oscillator and chain have f(z) = A z";
  });
  // The Hessian of a quadratic V is constant, so the Jacobian at 0 is A.
  return vector_field_jacobian(Vector::Zero(dim()));
}

}  // namespace csympnet
