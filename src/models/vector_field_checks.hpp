// Internal to src/models: argument checks shared by the vector-field models. Each failure
// names the model, the call, the argument, the size found and the size expected.
#pragma once

#include <string>

#include "csympnet/core/error.hpp"
#include "csympnet/models/vector_field_model.hpp"

namespace csympnet::detail {

inline void check_field_theta(const VectorFieldModel& model, Index size, const char* where,
                              const char* what = "theta") {
  require(size == model.n_params(), [&] {
    return model.type() + "::" + where + ": " + what + " has " + std::to_string(size) +
           " entries, expected n_params() = " + std::to_string(model.n_params());
  });
}

inline void check_field_rows(const VectorFieldModel& model, Index rows, const char* where,
                             const char* what) {
  require(rows == model.dim(), [&] {
    return model.type() + "::" + where + ": " + what + " has " + std::to_string(rows) +
           " rows, expected 2d = " + std::to_string(model.dim());
  });
}

inline void check_field_backward_args(const VectorFieldModel& model, ConstParams theta,
                                      const Matrix& Z, const Matrix& G, ParamsRef grad) {
  check_field_theta(model, theta.size(), "field_backward");
  check_field_theta(model, grad.size(), "field_backward", "grad");
  check_field_rows(model, Z.rows(), "field_backward", "Z");
  require(G.rows() == Z.rows() && G.cols() == Z.cols(), [&] {
    return model.type() + "::field_backward: G is " + std::to_string(G.rows()) + " x " +
           std::to_string(G.cols()) + ", expected the shape of Z (" + std::to_string(Z.rows()) +
           " x " + std::to_string(Z.cols()) + ")";
  });
}

}  // namespace csympnet::detail
