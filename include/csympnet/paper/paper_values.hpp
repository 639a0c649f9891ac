// The paper's published numbers (Tables 2–5, seed 42, σ = 0), for side-by-side output.
#pragma once

#include <optional>
#include <string>

namespace csympnet {

struct PaperValues {
  long params = 0;
  double l2_error = 0.0;                      // Table 2 / Table 5
  std::optional<double> residual_mean;        // Table 3 / Table 5: E[R]
  std::optional<double> residual_max;         // Table 3: max R
  std::optional<double> lambda_abs_err_mean;  // Table 3 / Table 5: E|λ̂ − λ*|
  std::optional<double> gamma_hat;            // Table 4 (CSympNet-ID only)
  std::optional<double> gamma_abs_err;        // Table 4 (CSympNet-ID only)
};

// Model names: csympnet, sympnet, map, ode, dhnn, dhnn2, phnn, phnn2.
std::optional<PaperValues> paper_values(const std::string& preset, const std::string& model);

}  // namespace csympnet
