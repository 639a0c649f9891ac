#include "support/gradient_check.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace csympnet::testing {

std::string CheckResult::report(const std::string& what) const {
  std::ostringstream out;
  out << what << ": relative error " << rel_error << " (tolerance " << tolerance
      << "); worst entry (" << worst_row << ", " << worst_col << "): analytic " << worst_analytic
      << " vs finite difference " << worst_fd;
  return out.str();
}

CheckResult compare(const Matrix& analytic, const Matrix& fd, double tolerance) {
  CheckResult result;
  result.tolerance = tolerance;
  if (analytic.rows() != fd.rows() || analytic.cols() != fd.cols()) {
    result.rel_error = INFINITY;  // a shape mismatch is never acceptable
    return result;
  }
  const Matrix diff = analytic - fd;
  const double scale = std::max({analytic.norm(), fd.norm(), 1e-12});
  result.rel_error = diff.norm() / scale;
  if (diff.size() > 0) {
    diff.cwiseAbs().maxCoeff(&result.worst_row, &result.worst_col);
    result.worst_analytic = analytic(result.worst_row, result.worst_col);
    result.worst_fd = fd(result.worst_row, result.worst_col);
  }
  if (!std::isfinite(result.rel_error)) result.rel_error = INFINITY;
  return result;
}

Vector fd_gradient(const std::function<double(const Vector&)>& f, const Vector& x,
                   const FdOptions& options) {
  Vector g(x.size());
  Vector xp = x;
  for (Index i = 0; i < x.size(); ++i) {
    const double step = options.rel_step * std::max(1.0, std::abs(x(i)));
    xp(i) = x(i) + step;
    const double up = f(xp);
    xp(i) = x(i) - step;
    const double down = f(xp);
    xp(i) = x(i);
    g(i) = (up - down) / (2.0 * step);
  }
  return g;
}

Matrix fd_jacobian(const std::function<Vector(const Vector&)>& f, const Vector& x,
                   const FdOptions& options) {
  Matrix jac;
  Vector xp = x;
  for (Index i = 0; i < x.size(); ++i) {
    const double step = options.rel_step * std::max(1.0, std::abs(x(i)));
    xp(i) = x(i) + step;
    const Vector up = f(xp);
    xp(i) = x(i) - step;
    const Vector down = f(xp);
    xp(i) = x(i);
    if (i == 0) jac.resize(up.size(), x.size());
    jac.col(i) = (up - down) / (2.0 * step);
  }
  return jac;
}

CheckResult check_gradient(const std::function<double(const Vector&)>& f,
                           const std::function<Vector(const Vector&)>& grad, const Vector& x,
                           const FdOptions& options) {
  return compare(grad(x), fd_gradient(f, x, options), options.tolerance);
}

CheckResult check_jacobian(const std::function<Vector(const Vector&)>& f,
                           const std::function<Matrix(const Vector&)>& jac, const Vector& x,
                           const FdOptions& options) {
  return compare(jac(x), fd_jacobian(f, x, options), options.tolerance);
}

std::string ModelCheck::report() const {
  return d_theta.report("dL/dtheta") + "\n" + d_zin.report("dL/dZin") + "\n" +
         jacobian.report("jacobian");
}

ModelCheck check_one_step_map(const OneStepMap& model, const Vector& theta, const Matrix& z,
                              const Vector& h, Rng& rng, const FdOptions& options) {
  const Matrix upstream = rng.normal_matrix(z.rows(), z.cols(), 1.0);
  const auto loss = [&](const Vector& th, const Matrix& zz) {
    return (upstream.array() * model.apply(th, zz, h).array()).sum();
  };
  // One analytic pass gives both dL/dθ and dL/dZ_in.
  ForwardCache cache;
  model.forward(theta, z, h, &cache);
  Vector grad = Vector::Ones(theta.size());
  Matrix dz_in;
  model.backward(theta, cache, upstream, grad, &dz_in);
  grad.array() -= 1.0;

  ModelCheck check;
  check.d_theta =
      compare(grad, fd_gradient([&](const Vector& th) { return loss(th, z); }, theta, options),
              options.tolerance);
  const Vector z_flat = z.reshaped();
  const Vector fd_z =
      fd_gradient([&](const Vector& zf) { return loss(theta, zf.reshaped(z.rows(), z.cols())); },
                  z_flat, options);
  check.d_zin = compare(dz_in.reshaped(), fd_z, options.tolerance);

  const Vector h0 = h.head(1);
  check.jacobian = check_jacobian(
      [&](const Vector& zz) -> Vector { return model.apply(theta, zz, h0); },
      [&](const Vector& zz) { return model.jacobian(theta, zz, h0(0)); }, z.col(0), options);
  return check;
}

std::string FieldCheck::report() const {
  return d_theta.report("dL/dtheta") + "\n" + jacobian.report("field jacobian");
}

FieldCheck check_vector_field_model(const VectorFieldModel& model, const Vector& theta,
                                    const Matrix& z, Rng& rng, const FdOptions& options) {
  const Matrix upstream = rng.normal_matrix(z.rows(), z.cols(), 1.0);
  Vector grad = Vector::Ones(theta.size());
  model.field_backward(theta, z, upstream, grad);
  grad.array() -= 1.0;
  FieldCheck check;
  const auto loss = [&](const Vector& th) {
    return (upstream.array() * model.field(th, z).array()).sum();
  };
  check.d_theta = compare(grad, fd_gradient(loss, theta, options), options.tolerance);
  check.jacobian = check_jacobian(
      [&](const Vector& zz) -> Vector { return model.field(theta, zz); },
      [&](const Vector& zz) { return model.field_jacobian(theta, zz); }, z.col(0), options);
  return check;
}

}  // namespace csympnet::testing
