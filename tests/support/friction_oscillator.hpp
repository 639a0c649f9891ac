// Exact records of the oscillator with viscous damping and Coulomb friction,
//
//   q̈ = −ω² q − γ q̇ − μ sign(q̇),
//
// for the tests of the dissipation terms, independent of the map that is tested: between
// reversals of q̇ the motion is the damped oscillator about the shifted centre c_s = −μ s/ω²
// (s = sign q̇), in closed form, and the velocity's zeros are found in closed form too (the
// phase at which the velocity's sinusoid vanishes). At a reversal the mass sticks for good when
// the spring force cannot beat the friction, |ω² q| ≤ μ (Filippov's solution). Underdamped
// only (γ < 2ω).
//
// And the same oscillator with quadratic drag (q̈ = −ω² q − γ q̇ − c q̇|q̇|), which has no closed
// form, by a classical RK4 with 400 substeps per sample (the field is C¹).
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/data/dataset.hpp"

namespace csympnet::testing {

struct FrictionOscillator {
  double omega = 2.0;
  double gamma = 0.05;
  double mu = 0.0;    // Coulomb: a deceleration
  double drag = 0.0;  // quadratic drag c
};

// The state (q, v) after time T from (q, v), Coulomb and viscous only (drag must be 0).
inline void coulomb_advance(const FrictionOscillator& o, double& q, double& v, double T) {
  require(o.drag == 0.0 && o.gamma < 2.0 * o.omega, "coulomb_advance: underdamped, no drag");
  const double w2 = o.omega * o.omega;
  const double wd = std::sqrt(w2 - 0.25 * o.gamma * o.gamma);
  double left = T;
  while (left > 0.0) {
    if (v == 0.0 && w2 * std::abs(q) <= o.mu) return;  // stuck for good
    const double s = v != 0.0 ? (v > 0.0 ? 1.0 : -1.0) : (q > 0.0 ? -1.0 : 1.0);
    const double c = -o.mu * s / w2;
    const double x0 = q - c, a = x0, b = (v + 0.5 * o.gamma * x0) / wd;
    // v(t) = e^{−γt/2} (C cos ω_d t − D sin ω_d t); its next zero after t = 0.
    const double cc = v, dd = a * wd + 0.5 * o.gamma * b;
    double phase = std::fmod(std::atan2(cc, dd), std::numbers::pi);
    if (phase < 0.0) phase += std::numbers::pi;
    if (phase <= 1e-15) phase += std::numbers::pi;
    const double t_zero = phase / wd;
    const double t = std::min(left, t_zero);
    const double e = std::exp(-0.5 * o.gamma * t), cs = std::cos(wd * t), sn = std::sin(wd * t);
    q = c + e * (a * cs + b * sn);
    v = t < t_zero ? e * (cc * cs - dd * sn) : 0.0;
    left -= t;
  }
}

// Records of `points` samples at step h from each start (q, v), with measurement noise of
// `sigma` times each coordinate's standard deviation (the identification tests' convention).
inline std::vector<Trajectory> friction_records(
    const FrictionOscillator& o, const std::vector<std::pair<double, double>>& starts, int points,
    double h, double sigma, std::uint64_t seed) {
  std::vector<Trajectory> out;
  for (const auto& [q0, v0] : starts) {
    Trajectory tr;
    tr.t = Vector::LinSpaced(points, 0.0, h * (points - 1));
    tr.z.resize(2, points);
    double q = q0, v = v0;
    const double dt = h / 400.0;
    const auto accel = [&](double qq, double vv) {
      return -o.omega * o.omega * qq - o.gamma * vv - o.drag * vv * std::abs(vv);
    };
    for (int k = 0; k < points; ++k) {
      tr.z(0, k) = q;
      tr.z(1, k) = v;
      if (o.drag == 0.0) {
        coulomb_advance(o, q, v, h);
        continue;
      }
      require(o.mu == 0.0, "friction_records: Coulomb and drag together are not simulated");
      for (int s = 0; s < 400; ++s) {
        const double a1 = v, b1 = accel(q, v);
        const double a2 = v + 0.5 * dt * b1, b2 = accel(q + 0.5 * dt * a1, a2);
        const double a3 = v + 0.5 * dt * b2, b3 = accel(q + 0.5 * dt * a2, a3);
        const double a4 = v + dt * b3, b4 = accel(q + dt * a3, a4);
        q += dt / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4);
        v += dt / 6.0 * (b1 + 2 * b2 + 2 * b3 + b4);
      }
    }
    out.push_back(tr);
  }
  if (sigma > 0.0) {
    Rng rng(seed, "friction-records-noise");
    for (Trajectory& t : out)
      for (Index i = 0; i < 2; ++i) {
        const double sd = std::sqrt((t.z.row(i).array() - t.z.row(i).mean()).square().mean());
        for (Index k = 0; k < t.z.cols(); ++k) t.z(i, k) += sigma * sd * rng.normal();
      }
  }
  return out;
}

}  // namespace csympnet::testing
