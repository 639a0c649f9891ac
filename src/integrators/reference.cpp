#include "csympnet/integrators/reference.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include <boost/numeric/odeint.hpp>
#include <unsupported/Eigen/MatrixFunctions>

#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"

namespace csympnet {

namespace {

// Relative slack subtracted from h / h_ref before the ceiling (see substep_count).
constexpr double kCeilSlack = 1e-10;
// More substeps than this in one call is certainly a units mistake, not a request.
constexpr double kMaxSubsteps = 1e12;
// Adaptive steps (accepted or rejected) of one rk_flow call before it gives up.
constexpr long kMaxRkSteps = 10000000;

// n substeps of S_a ∘ SV_δ ∘ S_a on the columns (Q, P). The closing kick of one substep and the
// opening kick of the next use ∇V at the same q, so the gradient is computed once per substep
// (first-same-as-last); the values, and hence the bits, are the same as without the reuse.
void splitting_steps(const System& sys, Matrix& Q, Matrix& P, double delta, Index n) {
  const double a = std::exp(-0.5 * sys.gamma() * delta);  // conformal factor over δ/2
  const double half = 0.5 * delta;
  Matrix G = sys.grad_potential_batch(Q);
  // A substep costs O(d N): poll each one for a large block, every 1,024 for a small one.
  const Index poll_mask = Q.size() >= 65536 ? 0 : 1023;
  for (Index s = 0; s < n; ++s) {
    if ((s & poll_mask) == poll_mask)
      throw_if_stop_requested("the splitting reference integration");
    P *= a;          // scale
    P -= half * G;   // kick
    Q += delta * P;  // drift
    G = sys.grad_potential_batch(Q);
    P -= half * G;  // kick
    P *= a;         // scale
  }
}

// Advances all columns of Z (2d x N) by the same h with the splitting, into out (sized like Z;
// it may be Z itself). Chunk by chunk from Z, so no whole copy of a large batch is made first
// (a copy of gigabytes is a second in which no stop request is seen).
// The columns are independent (every operation is elementwise, the gradient is taken column by
// column), so a large block goes in chunks of about 2^20 entries: the same bits as in one
// piece, and a stop request is seen within a chunk's substep (a block of 10^5 dimensions by
// 10^3 columns took seconds per pass before).
void splitting_block(const System& sys, const Matrix& Z, Matrix& out, double h, double h_ref) {
  const Index d = sys.d();
  const Index n = substep_count(h, h_ref);
  const Index chunk = std::max<Index>(1, (Index{1} << 20) / std::max<Index>(1, Z.rows()));
  for (Index c0 = 0; c0 < Z.cols(); c0 += chunk) {
    if (c0 > 0) throw_if_stop_requested("the splitting reference integration");
    const Index w = std::min(chunk, Z.cols() - c0);
    Matrix Q = Z.block(0, c0, d, w);
    Matrix P = Z.block(d, c0, d, w);
    splitting_steps(sys, Q, P, h / static_cast<double>(n), n);
    out.block(0, c0, d, w) = Q;
    out.block(d, c0, d, w) = P;
  }
}

void check_state(const System& sys, const Vector& z, const char* where) {
  require(z.size() == sys.dim(), [&] {
    return std::string(where) + ": z has length " + std::to_string(z.size()) +
           ", expected 2d = " + std::to_string(sys.dim());
  });
}

void check_step(double h, const char* where) {
  require(std::isfinite(h) && h > 0.0, [&] {
    return std::string(where) + ": step h must be a finite number > 0, got " + number_text(h);
  });
}

}  // namespace

Reference parse_reference(const std::string& name) {
  if (name == "splitting") return Reference::kSplitting;
  if (name == "expm") return Reference::kExpm;
  if (name == "rk") return Reference::kRk;
  throw Error("reference method must be one of splitting, expm, rk; got \"" + name + "\"");
}

std::string to_string(Reference r) {
  switch (r) {
    case Reference::kSplitting:
      return "splitting";
    case Reference::kExpm:
      return "expm";
    case Reference::kRk:
      return "rk";
  }
  throw Error("to_string(Reference): invalid enum value " + std::to_string(static_cast<int>(r)));
}

void ReferenceOptions::validate() const {
  require(method == Reference::kSplitting || method == Reference::kExpm || method == Reference::kRk,
          [&] {
            return "reference.method: invalid enum value " +
                   std::to_string(static_cast<int>(method));
          });
  require(std::isfinite(h_ref) && h_ref > 0.0,
          [&] { return "reference.h_ref must be a finite number > 0, got " + number_text(h_ref); });
  require(std::isfinite(rk_rtol) && rk_rtol > 0.0, [&] {
    return "reference.rk_rtol must be a finite number > 0, got " + number_text(rk_rtol);
  });
  require(std::isfinite(rk_atol) && rk_atol > 0.0, [&] {
    return "reference.rk_atol must be a finite number > 0, got " + number_text(rk_atol);
  });
}

Index substep_count(double h, double h_ref) {
  check_step(h, "substep_count");
  require(std::isfinite(h_ref) && h_ref > 0.0, [&] {
    return "substep_count: h_ref must be a finite number > 0, got " + number_text(h_ref);
  });
  const double r = h / h_ref;
  require(r <= kMaxSubsteps,
          [&] { return "substep_count: h / h_ref = " + number_text(r) + " substeps is too many"; });
  const double n = std::ceil(r * (1.0 - kCeilSlack));
  return n < 1.0 ? Index{1} : static_cast<Index>(n);
}

void conformal_sv_substep(const System& sys, Matrix& Z, double delta) {
  require(Z.rows() == sys.dim(), [&] {
    return "conformal_sv_substep: Z has " + std::to_string(Z.rows()) +
           " rows, expected 2d = " + std::to_string(sys.dim());
  });
  check_step(delta, "conformal_sv_substep");
  Matrix Q = Z.topRows(sys.d());
  Matrix P = Z.bottomRows(sys.d());
  splitting_steps(sys, Q, P, delta, 1);
  Z.topRows(sys.d()) = Q;
  Z.bottomRows(sys.d()) = P;
}

Vector conformal_sv_flow(const System& sys, const Vector& z, double h, double h_ref) {
  check_state(sys, z, "conformal_sv_flow");
  Matrix Z = z;
  splitting_block(sys, Z, Z, h, h_ref);
  return Z.col(0);
}

Matrix conformal_sv_jacobian(const System& sys, const Vector& z, double h, double h_ref) {
  check_state(sys, z, "conformal_sv_jacobian");
  const Index d = sys.d();
  const Index n = substep_count(h, h_ref);
  const double delta = h / static_cast<double>(n);
  const double a = std::exp(-0.5 * sys.gamma() * delta);
  const double half = 0.5 * delta;
  // Tangent rows: M = [Mq; Mp] = DΦ, starting from the identity. Each sub-map is linearised
  // at the state it acts on: scale Mp *= a; kick Mp −= δ/2 ∇²V(q) Mq; drift Mq += δ Mp.
  Vector q = z.head(d);
  Vector p = z.tail(d);
  Matrix Mq = Matrix::Zero(d, 2 * d);
  Matrix Mp = Matrix::Zero(d, 2 * d);
  Mq.leftCols(d).setIdentity();
  Mp.rightCols(d).setIdentity();
  for (Index s = 0; s < n; ++s) {
    if ((s & 1023) == 1023) throw_if_stop_requested("the splitting reference integration");
    p *= a;
    Mp *= a;
    p -= half * sys.grad_potential(q);
    Mp -= half * sys.hess_potential_times(q, Mq);
    q += delta * p;
    Mq += delta * Mp;
    p -= half * sys.grad_potential(q);
    Mp -= half * sys.hess_potential_times(q, Mq);
    p *= a;
    Mp *= a;
  }
  Matrix M(2 * d, 2 * d);
  M.topRows(d) = Mq;
  M.bottomRows(d) = Mp;
  return M;
}

Matrix expm_propagator(const System& sys, double h) {
  require(sys.is_linear(), [&] {
    return "expm reference: system kind \"" + sys.spec().kind +
           "\" is nonlinear; use splitting or rk";
  });
  require(std::isfinite(h),
          [&] { return "expm_propagator: h must be finite, got " + number_text(h); });
  const Matrix hA = h * sys.linear_generator();
  return hA.exp();
}

Vector rk_flow(const System& sys, const Vector& z, double h, double rtol, double atol) {
  namespace odeint = boost::numeric::odeint;
  check_state(sys, z, "rk_flow");
  check_step(h, "rk_flow");
  require(std::isfinite(rtol) && rtol > 0.0 && std::isfinite(atol) && atol > 0.0, [&] {
    return "rk_flow: tolerances must be finite and > 0, got rtol " + number_text(rtol) + ", atol " +
           number_text(atol);
  });
  using FlowState = std::vector<double>;
  const Index dim = sys.dim();
  FlowState x(z.data(), z.data() + dim);
  auto rhs = [&sys, dim](const FlowState& xs, FlowState& dxdt, double /*t*/) {
    const Vector f = sys.vector_field(Eigen::Map<const Vector>(xs.data(), dim));
    Eigen::Map<Vector>(dxdt.data(), dim) = f;
  };
  // Fehlberg 7(8): high order keeps the step count small at rtol ~ 1e-12.
  // The controlled loop by hand (integrate_adaptive has no step bound): a stiff system (a huge
  // ω) would otherwise take steps without end. Each try counts against kMaxRkSteps, and the
  // stop request is polled every 64 tries.
  auto stepper = odeint::make_controlled(atol, rtol, odeint::runge_kutta_fehlberg78<FlowState>());
  double t = 0.0, dt = 0.1 * h;
  for (long tries = 0; t < h; ++tries) {
    require(tries < kMaxRkSteps, [&] {
      return "the rk reference took " + std::to_string(kMaxRkSteps) +
             " adaptive steps and reached t = " + number_text(t) + " of a step of " +
             number_text(h) +
             " (the system is too stiff for it at this step: a large omega or gamma?); "
             "expected a system and step the rk reference can integrate, or the splitting "
             "reference";
    });
    if ((tries & 63) == 63) throw_if_stop_requested("the rk reference integration");
    const bool last = dt >= h - t;
    const double t_before = t;
    if (last) dt = h - t;
    if (stepper.try_step(rhs, x, t, dt) == odeint::success) {
      if (last || t >= h) t = h;
    }
    require(std::isfinite(dt) && dt > 0.0 && (t >= h || t + dt > t), [&] {
      return "the rk reference's step size underflowed (dt = " + number_text(dt) +
             ") at t = " + number_text(t_before) + " of a step of " + number_text(h) +
             "; expected a system and step the rk reference can integrate";
    });
  }
  require(std::all_of(x.begin(), x.end(), [](double v) { return std::isfinite(v); }), [&] {
    return "the rk reference's state became non-finite over a step of " + number_text(h) +
           "; expected a system and step the rk reference can integrate";
  });
  return Eigen::Map<const Vector>(x.data(), dim);
}

Matrix reference_flow(const System& sys, const Matrix& Z, const Vector& h,
                      const ReferenceOptions& opt) {
  opt.validate();
  require(Z.rows() == sys.dim(), [&] {
    return "reference_flow: Z has " + std::to_string(Z.rows()) +
           " rows, expected 2d = " + std::to_string(sys.dim());
  });
  require(h.size() == Z.cols(), [&] {
    return "reference_flow: h has length " + std::to_string(h.size()) + " but Z has " +
           std::to_string(Z.cols()) + " columns";
  });
  for (Index j = 0; j < h.size(); ++j) check_step(h(j), "reference_flow");
  if (Z.cols() == 0) return Z;

  Matrix out(Z.rows(), Z.cols());
  if (opt.method == Reference::kRk) {
    for (Index j = 0; j < Z.cols(); ++j)
      out.col(j) = rk_flow(sys, Z.col(j), h(j), opt.rk_rtol, opt.rk_atol);
    return out;
  }

  // Columns grouped by their (bitwise) step, in order of first appearance within a group.
  std::map<double, std::vector<Index>> groups;
  for (Index j = 0; j < h.size(); ++j) groups[h(j)].push_back(j);

  if (opt.method == Reference::kExpm) {
    for (const auto& [step, cols] : groups) {
      throw_if_stop_requested("the expm reference integration");
      const Matrix E = expm_propagator(sys, step);
      // Column by column (matrix-vector), so a column's bits do not depend on the batch.
      for (Index j : cols) out.col(j).noalias() = E * Z.col(j);
    }
    return out;
  }

  if (groups.size() == 1) {  // the common case: one step for the whole batch, no gathering
    splitting_block(sys, Z, out, h(0), opt.h_ref);
    return out;
  }
  for (const auto& [step, cols] : groups) {
    throw_if_stop_requested("the splitting reference integration");
    Matrix block(Z.rows(), static_cast<Index>(cols.size()));
    for (std::size_t i = 0; i < cols.size(); ++i) block.col(static_cast<Index>(i)) = Z.col(cols[i]);
    splitting_block(sys, block, block, step, opt.h_ref);
    for (std::size_t i = 0; i < cols.size(); ++i)
      out.col(cols[i]) = block.col(static_cast<Index>(i));
  }
  return out;
}

}  // namespace csympnet
