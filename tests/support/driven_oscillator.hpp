// A linear oscillator driven by a random-phase multisine, q'' + γq' + ω²q = b u(t), sampled
// with its input: the driven-record fixture of the identification and CLI tests.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "csympnet/core/rng.hpp"
#include "csympnet/data/dataset.hpp"

namespace csympnet::testing {

inline constexpr double kDrivenGamma = 0.1, kDrivenOmega = 2.0, kDrivenGain = 1.5;

struct Multisine {
  std::vector<double> freq, phase;
  double operator()(double t) const {
    double u = 0.0;
    for (std::size_t k = 0; k < freq.size(); ++k) u += std::sin(freq[k] * t + phase[k]);
    return u / std::sqrt(static_cast<double>(freq.size()));
  }
};

// The oscillator by classic RK4, 20 steps per sample, u evaluated where RK4 asks; positions
// with noise of `noise` times their spread; momenta p = q' exactly.
// `gamma`: the damping rate of the record (kDrivenGamma unless given); `cubic`: a hardening
// force −cubic·q³ beside the spring (a Duffing oscillator, V = ω²q²/2 + cubic·q⁴/4);
// `straight`: the input is the straight line between its samples (a first-order hold, as a
// generator that interpolates linearly gives it) instead of the smooth multisine.
// `rest_until` > 0: the oscillator starts at rest and the input is 0 until that time, then
// rises smoothly to the multisine over 2 time units (a record that starts before the drive).
// `saturate` = l > 0: the spring saturates, −ω²q replaced by −(ω²/4) q − (3ω²/4) l tanh(q / l)
// (stiffness ω² at rest, ω²/4 far out: a force outside the library of terms).
inline Trajectory driven_record(Index n, double h, double noise, std::uint64_t seed,
                                double gamma = kDrivenGamma, double cubic = 0.0,
                                bool straight = false, double rest_until = 0.0,
                                double saturate = 0.0) {
  Rng rng(seed, "driven-record");
  Multisine sines;
  for (int k = 0; k < 8; ++k) {
    sines.freq.push_back(0.3 + 0.45 * k);  // 0.3 … 3.45 rad per time unit, around ω = 2
    sines.phase.push_back(rng.uniform(0.0, 2.0 * M_PI));
  }
  const auto u = [&](double t) {
    if (rest_until <= 0.0) return sines(t);
    const double s = std::clamp((t - rest_until) / 2.0, 0.0, 1.0);
    return std::pow(std::sin(0.5 * M_PI * s), 2) * sines(t);
  };
  double t0 = 0.0;  // the current sample's time (for the straight input)
  const auto input = [&](double t) {
    if (!straight) return u(t);
    const double s = (t - t0) / h;
    return (1.0 - s) * u(t0) + s * u(t0 + h);
  };
  const auto field = [&](double q, double v, double t, double& dq, double& dv) {
    dq = v;
    const double w2 = kDrivenOmega * kDrivenOmega;
    const double spring =
        saturate > 0.0 ? 0.25 * w2 * q + 0.75 * w2 * saturate * std::tanh(q / saturate) : w2 * q;
    dv = -spring - cubic * q * q * q - gamma * v + kDrivenGain * input(t);
  };
  Trajectory tr;
  tr.t.resize(n);
  tr.z.resize(2, n);
  tr.u.resize(1, n);
  double q = rest_until > 0.0 ? 0.0 : 0.3, v = 0.0;
  const int sub = 20;
  for (Index k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * h;
    t0 = t;
    tr.t(k) = t;
    tr.z(0, k) = q;
    tr.z(1, k) = v;
    tr.u(0, k) = u(t);
    const double dt = h / sub;
    for (int s = 0; s < sub; ++s) {
      const double ts = t + s * dt;
      double k1q, k1v, k2q, k2v, k3q, k3v, k4q, k4v;
      field(q, v, ts, k1q, k1v);
      field(q + 0.5 * dt * k1q, v + 0.5 * dt * k1v, ts + 0.5 * dt, k2q, k2v);
      field(q + 0.5 * dt * k2q, v + 0.5 * dt * k2v, ts + 0.5 * dt, k3q, k3v);
      field(q + dt * k3q, v + dt * k3v, ts + dt, k4q, k4v);
      q += dt / 6.0 * (k1q + 2 * k2q + 2 * k3q + k4q);
      v += dt / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v);
    }
  }
  const double spread = std::sqrt((tr.z.row(0).array() - tr.z.row(0).mean()).square().mean());
  for (Index k = 0; k < n; ++k) tr.z(0, k) += noise * spread * rng.normal();
  return tr;
}

// The record as a positions-with-input CSV: t,q1,u1 rows, 17 significant digits.
inline void write_positions_with_input(const std::string& path, const Trajectory& tr) {
  std::ofstream out(path);
  out << "t,q1,u1\n";
  char line[128];
  for (Index k = 0; k < tr.t.size(); ++k) {
    std::snprintf(line, sizeof line, "%.17g,%.17g,%.17g\n", tr.t(k), tr.z(0, k), tr.u(0, k));
    out << line;
  }
}

}  // namespace csympnet::testing
