// Reference solvers for the damped flow Φ_h of a System.
//
//   Splitting (default; docs/protocol.md, "Reference solutions"): n = ceil(h / h_ref) steps
//     of δ = h / n of S_a ∘ SV_δ ∘ S_a,
//     a = exp(−γδ/2), SV = kick δ/2, drift δ, kick δ/2.
//   Expm: z(h) = exp(hA) z0, exact for linear systems (oscillator, chain).
//   Rk: adaptive Runge–Kutta (Boost.Odeint, tight tolerances) for any system.
#pragma once

#include <string>

#include "csympnet/core/types.hpp"
#include "csympnet/systems/system.hpp"

namespace csympnet {

enum class Reference { kSplitting, kExpm, kRk };

// "splitting", "expm", "rk"; throws Error naming the bad value otherwise.
Reference parse_reference(const std::string& name);
std::string to_string(Reference r);

struct ReferenceOptions {
  Reference method = Reference::kSplitting;  // which solver
  double h_ref = 1e-3;                       // splitting: largest substep
  double rk_rtol = 1e-12;                    // rk: relative tolerance
  double rk_atol = 1e-14;                    // rk: absolute tolerance
  void validate() const;
};

// Number of splitting substeps over time h: n = ceil(h / h_ref · (1 − 1e-10)), at least 1.
// The relative slack absorbs rounding in h / h_ref (0.1 / 1e-3 = 100.00000000000001 must give
// 100, not 101); it only changes n when h / h_ref is within 1e-10 (relative) above an integer.
Index substep_count(double h, double h_ref);

// Advances every column of Z (2d x N) by its own step h(j) > 0. Columns that share the same
// h (bitwise) are advanced together as one batch; each column's result does not depend on
// which other columns are present. kExpm needs a linear system; kRk solves column by column.
Matrix reference_flow(const System& sys, const Matrix& Z, const Vector& h,
                      const ReferenceOptions& opt = {});

// One conformal Störmer–Verlet substep S_a ∘ SV_δ ∘ S_a applied in place to the columns.
void conformal_sv_substep(const System& sys, Matrix& Z, double delta);

// The splitting map over time h (ceil(h / h_ref) substeps) for a single state, and its
// exact Jacobian M = DΦ (tangent propagation through each substep); M satisfies
// MᵀJM = exp(−γh) J to rounding.
Vector conformal_sv_flow(const System& sys, const Vector& z, double h, double h_ref = 1e-3);
Matrix conformal_sv_jacobian(const System& sys, const Vector& z, double h, double h_ref = 1e-3);

// exp(hA) for a linear system (Eigen's MatrixFunctions).
Matrix expm_propagator(const System& sys, double h);

// Adaptive Runge–Kutta solve of one state over time h.
Vector rk_flow(const System& sys, const Vector& z, double h, double rtol = 1e-12,
               double atol = 1e-14);

}  // namespace csympnet
