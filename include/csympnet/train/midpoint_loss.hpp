// The midpoint loss of the vector-field models, paper eq. (midpoint_loss):
//   L(θ) = (1/N) Σ_i ‖(z1_i − z0_i)/h_i − f_θ((z0_i + z1_i)/2)‖².
#pragma once

#include "csympnet/data/dataset.hpp"
#include "csympnet/models/vector_field_model.hpp"

namespace csympnet {

// The two data-only terms, computed once per data set.
struct MidpointData {
  Matrix midpoints;  // (z0 + z1)/2, 2d x N
  Matrix slopes;     // (z1 − z0)/h, 2d x N
};
MidpointData midpoint_data(const PairSet& pairs);

// Loss value; when grad is not null it is overwritten with dL/dθ.
double midpoint_loss(const VectorFieldModel& model, ConstParams theta, const MidpointData& data,
                     Vector* grad = nullptr);

}  // namespace csympnet
