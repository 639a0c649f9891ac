// Adaptive Dormand–Prince 5(4) on Boost.Odeint's controlled stepper, driven by our own loop so
// that the step budget, the non-finite check and the exact landing on t = h are ours.
// Design notes and measured accuracy: docs/rollout.md.
#include "csympnet/integrators/dopri5.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include <boost/numeric/odeint.hpp>

#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"

namespace csympnet {

namespace {

namespace odeint = boost::numeric::odeint;

// std::vector with odeint's default range_algebra: no algebra plumbing for Eigen types, and the
// stepper's internal buffers are sized once per call.
using State = std::vector<double>;
using Stepper = odeint::runge_kutta_dopri5<State>;

std::string num17(double x) {
  std::ostringstream os;
  os.precision(17);
  os << x;
  return os.str();
}

bool all_finite(const State& x) {
  return std::all_of(x.begin(), x.end(), [](double v) { return std::isfinite(v); });
}

void check_h(double h, const char* where) {
  require(std::isfinite(h) && h > 0.0,
          [&] { return std::string(where) + ": h must be a finite number > 0, got " + num17(h); });
}

void check_z0(const Vector& z0, const char* where) {
  require(z0.size() > 0, [&] { return std::string(where) + ": z0 must be non-empty"; });
  require(z0.allFinite(), [&] { return std::string(where) + ": z0 has non-finite entries"; });
}

// Calls f into a preallocated buffer and checks that f kept the length (a model with the wrong
// state dimension would otherwise write out of bounds of the odeint state).
void eval_field(const VectorField& f, const Vector& z, Vector& out) {
  f(z, out);
  require(out.size() == z.size(), [&] {
    return "dopri5: the vector field returned " + std::to_string(out.size()) +
           " components for a state of " + std::to_string(z.size());
  });
}

// dz/dt = f(z) as an odeint system. odeint copies the system by value on every step, so the
// functor holds only pointers; the Eigen buffers live in the caller's frame.
struct PlainSystem {
  const VectorField* f;
  Vector* z;
  Vector* fz;

  void operator()(const State& x, State& dxdt, double /*t*/) const {
    const Index n = z->size();
    *z = Eigen::Map<const Vector>(x.data(), n);
    eval_field(*f, *z, *fz);
    Eigen::Map<Vector>(dxdt.data(), n) = *fz;
  }
};

// Augmented state x = [z; vec(M)] (M column-major, n x n):
//   dz/dt = f(z),   dM/dt = Df(z) M.
struct AugmentedSystem {
  const VectorField* f;
  const VectorFieldJacobian* df;
  Vector* z;
  Vector* fz;

  void operator()(const State& x, State& dxdt, double t) const {
    const Index n = z->size();
    PlainSystem{f, z, fz}(x, dxdt, t);  // the first n entries: dz/dt = f(z)
    const Matrix jac = (*df)(*z);
    require(jac.rows() == n && jac.cols() == n, [&] {
      return "dopri5_flow_jacobian: the field Jacobian is " + std::to_string(jac.rows()) + " x " +
             std::to_string(jac.cols()) + ", expected " + std::to_string(n) + " x " +
             std::to_string(n);
    });
    const Eigen::Map<const Matrix> m(x.data() + n, n, n);
    Eigen::Map<Matrix>(dxdt.data() + n, n, n).noalias() = jac * m;
  }
};

// max_i |v_i| / (atol + rtol |x_i|): the weighted infinity norm of Boost's error checker,
// without its dt|f| term (no step exists yet).
double scaled_norm(const State& v, const State& x, const OdeOptions& opt) {
  double r = 0.0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    r = std::max(r, std::abs(v[i]) / (opt.atol + opt.rtol * std::abs(x[i])));
  }
  return r;
}

// Starting step after Hairer, Nørsett & Wanner, Solving ODEs I, §II.4 ("starting step size"):
//   h0 = 0.01 ‖x0‖/‖f0‖, one Euler probe x1 = x0 + h0 f0,
//   d2 = ‖f(x1) − f0‖ / h0 (a second-derivative estimate),
//   h1 = (0.01 / max(‖f0‖, d2))^{1/5},  dt0 = min(100 h0, h1, h),
// all norms weighted as above. Costs one extra field evaluation; the controller repairs a poor
// guess anyway, this only saves rejected steps. Leaves f0 = f(x0) in `f0`.
template <class System>
double initial_step(System& sys, const State& x0, State& f0, double h, const OdeOptions& opt) {
  sys(x0, f0, 0.0);
  require(all_finite(f0), "dopri5: the vector field is non-finite at the initial state");
  const double d0 = scaled_norm(x0, x0, opt);
  const double d1 = scaled_norm(f0, x0, opt);
  double h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
  h0 = std::min(h0, h);

  State x1(x0.size());
  State f1(x0.size());
  for (std::size_t i = 0; i < x0.size(); ++i) x1[i] = x0[i] + h0 * f0[i];
  sys(x1, f1, h0);
  for (std::size_t i = 0; i < x0.size(); ++i) f1[i] -= f0[i];
  const double d2 = scaled_norm(f1, x0, opt) / h0;

  double h1;
  if (!std::isfinite(d2)) {
    h1 = 1e-3 * h0;  // the probe already left the finite numbers: start very carefully
  } else if (std::max(d1, d2) <= 1e-15) {
    h1 = std::max(1e-6, 1e-3 * h0);
  } else {
    h1 = std::pow(0.01 / std::max(d1, d2), 0.2);
  }
  const double dt = std::min({100.0 * h0, h1, h});
  return (std::isfinite(dt) && dt > 0.0) ? dt : h;
}

// Integrates x from t = 0 to exactly t = h. Counts every try_step (accepted or rejected) against
// opt.max_steps. The last step is clamped to h − t and then t is set to h, so the end point is
// hit exactly rather than up to rounding.
template <class System>
void integrate(System sys, State& x, double h, const OdeOptions& opt) {
  // Boost's argument order is (abs, rel). Error per step: max_i |err_i| /
  // (atol + rtol (|x_i| + dt |f_i|)) at the step's start, accepted when ≤ 1.
  auto stepper = odeint::make_controlled<Stepper>(opt.atol, opt.rtol);
  State dxdt(x.size());
  State x_new(x.size());
  State dxdt_new(x.size());
  double dt = initial_step(sys, x, dxdt, h, opt);
  double t = 0.0;
  long steps = 0;
  while (t < h) {
    require(steps < opt.max_steps, [&] {
      return "dopri5: step budget of " + std::to_string(opt.max_steps) +
             " exhausted at t = " + num17(t) + " of h = " + num17(h) +
             " (the learned field may be stiff or blowing up); expected a span the field "
             "can be integrated over within the budget (a smaller step)";
    });
    ++steps;
    // A step costs microseconds to milliseconds; a span of 1e12 takes up to the whole budget.
    // Polled only once a call is long (an ordinary step takes tens of steps): a training
    // stopped by a signal still evaluates its best checkpoint with the same integrator.
    if (steps >= 4096 && (steps & 63) == 0) throw_if_stop_requested("dopri5: the integration");
    const double remaining = h - t;
    const bool last = dt >= remaining;
    if (last) dt = remaining;
    const auto result = stepper.try_step(sys, x, dxdt, t, x_new, dxdt_new, dt);
    if (result == odeint::success) {
      // A NaN error estimate compares as "not > 1" and is accepted by Boost, so this check is
      // also what catches a field that returned NaN inside the step.
      require(all_finite(x_new) && all_finite(dxdt_new), [&] {
        return "dopri5: the state became non-finite at t = " + num17(t) + " of h = " + num17(h) +
               " (the learned field may be blowing up or returned NaN)";
      });
      x.swap(x_new);
      dxdt.swap(dxdt_new);
      if (last) t = h;
    }
    require(t >= h || (std::isfinite(dt) && dt > 0.0 && t + dt > t), [&] {
      return "dopri5: step size underflow (dt = " + num17(dt) + ") at t = " + num17(t) +
             " of h = " + num17(h) + " (the learned field may be stiff or blowing up)";
    });
  }
}

}  // namespace

void OdeOptions::validate() const {
  require(std::isfinite(rtol) && rtol > 0.0,
          [&] { return "OdeOptions.rtol must be a finite number > 0, got " + num17(rtol); });
  require(std::isfinite(atol) && atol > 0.0,
          [&] { return "OdeOptions.atol must be a finite number > 0, got " + num17(atol); });
  require(max_steps >= 1,
          [&] { return "OdeOptions.max_steps must be >= 1, got " + std::to_string(max_steps); });
}

Vector dopri5_flow(const VectorField& f, const Vector& z0, double h, const OdeOptions& opt) {
  opt.validate();
  check_h(h, "dopri5_flow");
  check_z0(z0, "dopri5_flow");
  const Index n = z0.size();
  Vector z(n);
  Vector fz(n);
  State x(z0.data(), z0.data() + n);
  integrate(PlainSystem{&f, &z, &fz}, x, h, opt);
  return Eigen::Map<const Vector>(x.data(), n);
}

std::pair<Vector, Matrix> dopri5_flow_jacobian(const VectorField& f, const VectorFieldJacobian& df,
                                               const Vector& z0, double h, const OdeOptions& opt) {
  opt.validate();
  check_h(h, "dopri5_flow_jacobian");
  check_z0(z0, "dopri5_flow_jacobian");
  const Index n = z0.size();
  Vector z(n);
  Vector fz(n);
  // [z0; vec(I)]: the identity's column-major layout has ones at i (n + 1), i < n.
  State x(static_cast<std::size_t>(n + n * n), 0.0);
  std::copy(z0.data(), z0.data() + n, x.begin());
  for (Index i = 0; i < n; ++i) x[static_cast<std::size_t>(n + i * (n + 1))] = 1.0;
  // Error control covers z and M alike (docs/rollout.md, "Error control").
  integrate(AugmentedSystem{&f, &df, &z, &fz}, x, h, opt);
  return {Eigen::Map<const Vector>(x.data(), n), Eigen::Map<const Matrix>(x.data() + n, n, n)};
}

}  // namespace csympnet
