// Argument checks shared by every OneStepMap: each failure names the argument, the size
// found and the size expected, so a caller never meets an Eigen assertion or a segfault.
// They run on every forward and backward call, so a message is built only when its check
// fails.
#pragma once

#include <string>

#include "csympnet/core/error.hpp"
#include "csympnet/models/one_step_map.hpp"

namespace csympnet {

inline void check_theta(const OneStepMap& model, ConstParams theta, const char* where) {
  require(theta.size() == model.n_params(), [&] {
    return model.type() + "::" + where + ": theta has " + std::to_string(theta.size()) +
           " entries, expected n_params() = " + std::to_string(model.n_params());
  });
}

inline void check_forward_args(const OneStepMap& model, ConstParams theta, const Matrix& z,
                               const Vector& h) {
  check_theta(model, theta, "forward");
  require(z.rows() == model.dim(), [&] {
    return model.type() + "::forward: Z has " + std::to_string(z.rows()) +
           " rows, expected 2d = " + std::to_string(model.dim());
  });
  require(h.size() == z.cols(), [&] {
    return model.type() + "::forward: h has " + std::to_string(h.size()) +
           " entries, expected one step per column of Z (" + std::to_string(z.cols()) + ")";
  });
}

// `batch` is the batch size recorded by forward(), or -1 when the cache holds no forward pass.
inline void check_backward_args(const OneStepMap& model, ConstParams theta, Index batch,
                                const Matrix& dz_out, ParamsRef grad) {
  check_theta(model, theta, "backward");
  require(batch >= 0, [&] {
    return model.type() +
           "::backward: the cache holds no forward pass (call forward with a cache first)";
  });
  require(dz_out.rows() == model.dim() && dz_out.cols() == batch, [&] {
    return model.type() + "::backward: dZout is " + std::to_string(dz_out.rows()) + " x " +
           std::to_string(dz_out.cols()) + ", expected " + std::to_string(model.dim()) + " x " +
           std::to_string(batch) + " (the forward batch)";
  });
  require(grad.size() == model.n_params(), [&] {
    return model.type() + "::backward: grad has " + std::to_string(grad.size()) +
           " entries, expected n_params() = " + std::to_string(model.n_params());
  });
}

inline void check_jacobian_args(const OneStepMap& model, ConstParams theta, const Vector& z) {
  check_theta(model, theta, "jacobian");
  require(z.size() == model.dim(), [&] {
    return model.type() + "::jacobian: z has " + std::to_string(z.size()) +
           " entries, expected 2d = " + std::to_string(model.dim());
  });
}

}  // namespace csympnet
