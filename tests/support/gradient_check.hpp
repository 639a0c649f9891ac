// One finite-difference harness for every hand-differentiated module.
//
// The generic layer works on callables (f(x) -> value or vector, plus the analytic
// derivative) so any later module can reuse it; check_one_step_map() applies it to a
// OneStepMap's three derivative paths (dL/dθ, dL/dZ_in, DΦ̂). Like Ceres' GradientChecker,
// its own test plants wrong derivatives and asserts they are caught.
#pragma once

#include <functional>
#include <string>

#include "csympnet/core/rng.hpp"
#include "csympnet/core/types.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "csympnet/models/vector_field_model.hpp"

namespace csympnet::testing {

struct FdOptions {
  // Central-difference step for coordinate i: rel_step * max(1, |x_i|). 1e-5 balances the
  // O(δ²) truncation error against the O(ε|f|/δ) rounding error of doubles.
  double rel_step = 1e-5;
  // Largest accepted relative error (see CheckResult::rel_error).
  double tolerance = 1e-6;
};

struct CheckResult {
  // ‖analytic − fd‖_F / max(‖analytic‖_F, ‖fd‖_F, 1e-12): a norm-wise relative error, so
  // near-zero entries (whose finite differences are pure rounding noise) cannot fail alone.
  double rel_error = 0.0;
  double tolerance = 0.0;
  // Entry with the largest absolute discrepancy, for the report.
  Index worst_row = 0;
  Index worst_col = 0;
  double worst_analytic = 0.0;
  double worst_fd = 0.0;

  bool ok() const { return rel_error <= tolerance; }
  std::string report(const std::string& what) const;
};

// Compares two same-shape arrays with the metric above.
CheckResult compare(const Matrix& analytic, const Matrix& fd, double tolerance);

// Central differences of a scalar function (gradient, size n) and of a vector function
// (Jacobian, m x n).
Vector fd_gradient(const std::function<double(const Vector&)>& f, const Vector& x,
                   const FdOptions& options = {});
Matrix fd_jacobian(const std::function<Vector(const Vector&)>& f, const Vector& x,
                   const FdOptions& options = {});

CheckResult check_gradient(const std::function<double(const Vector&)>& f,
                           const std::function<Vector(const Vector&)>& grad, const Vector& x,
                           const FdOptions& options = {});
CheckResult check_jacobian(const std::function<Vector(const Vector&)>& f,
                           const std::function<Matrix(const Vector&)>& jac, const Vector& x,
                           const FdOptions& options = {});

struct ModelCheck {
  CheckResult d_theta;   // backward()'s dL/dθ for L = ⟨G, Φ̂(Z)⟩
  CheckResult d_zin;     // backward()'s dL/dZ_in
  CheckResult jacobian;  // jacobian() at the first column of Z with step h(0)

  bool ok() const { return d_theta.ok() && d_zin.ok() && jacobian.ok(); }
  std::string report() const;
};

// Runs all three checks with a random upstream G ~ N(0, 1) drawn from rng. backward() is
// called on a grad pre-filled with ones (and the ones subtracted afterwards), so a
// backward that overwrites instead of accumulating fails too.
ModelCheck check_one_step_map(const OneStepMap& model, const Vector& theta, const Matrix& z,
                              const Vector& h, Rng& rng, const FdOptions& options = {});

struct FieldCheck {
  CheckResult d_theta;   // field_backward()'s dL/dθ for L = ⟨G, f_θ(Z)⟩
  CheckResult jacobian;  // field_jacobian() at the first column of Z

  bool ok() const { return d_theta.ok() && jacobian.ok(); }
  std::string report() const;
};

// The vector-field counterpart of check_one_step_map (same conventions: random G ~ N(0, 1)
// from rng, grad pre-filled with ones so an overwriting field_backward fails).
FieldCheck check_vector_field_model(const VectorFieldModel& model, const Vector& theta,
                                    const Matrix& z, Rng& rng, const FdOptions& options = {});

}  // namespace csympnet::testing
