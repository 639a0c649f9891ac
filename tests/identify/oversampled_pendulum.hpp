// A record shared by the force-law and positions-terms tests: a pendulum, V = -cos q, unit
// mass, amplitude 0.6 rad, 85 samples per period, 4,000 positions with noise 2e-3 of the
// amplitude, by the library map at 8 substeps of order 6 (far below the noise).
#pragma once

#include <cmath>

#include <nlohmann/json.hpp>

#include "csympnet/core/rng.hpp"
#include "csympnet/data/dataset.hpp"
#include "csympnet/models/model.hpp"

namespace csympnet {

inline Trajectory oversampled_pendulum(double gamma) {
  const nlohmann::json core = {
      {"type", "library"}, {"terms", {"cos(q1)"}}, {"order", 6}, {"substeps", 8}};
  const Model truth =
      make_model({{"type", "csympnet"}, {"d", 1}, {"core", core}, {"beta_init", 0.1}});
  Vector theta = Vector::Zero(truth.n_params());
  theta(0) = 1.0;    // W
  theta(1) = -1.0;   // the cosine's coefficient
  theta(2) = 1.0;    // its wavenumber
  theta(3) = gamma;  // β
  const int n = 4000;
  const double h = 2.0 * M_PI / 85.0;
  Matrix z(2, n);
  z.col(0) << 0.6, 0.0;
  const Vector step = Vector::Constant(1, h);
  for (int k = 1; k < n; ++k) z.col(k) = truth.map->forward(theta, z.col(k - 1), step, nullptr);
  Rng rng(3, "oversampled-pendulum");
  Trajectory t;
  t.t = Vector::LinSpaced(n, 0.0, h * (n - 1));
  t.z = z.topRows(1) + 0.6 * 2e-3 * rng.normal_matrix(1, n, 1.0);
  return t;
}

}  // namespace csympnet
