#include "csympnet/paper/paper_values.hpp"

#include <array>
#include <string_view>

namespace csympnet {

namespace {
struct Row {
  std::string_view preset, model;
  long params;
  double l2, r_mean, r_max, lam;  // r_max < 0: not reported
};

// Tables 2 and 3 (d = 10 and d = 1) and Table 5 (d = 100; no max R there).
constexpr std::array<Row, 40> kRows{{
    {"s1", "csympnet", 115, 2.175e-4, 4.6e-7, 8.4e-7, 3.9e-7},
    {"s1", "sympnet", 114, 2.108e-1, 1.4e-2, 1.4e-2, 1.0e-2},
    {"s1", "map", 1250, 1.611e-1, 1.1e-2, 1.3e-2, 7.7e-3},
    {"s1", "ode", 1218, 6.321e-3, 6.2e-5, 1.8e-4, 4.4e-5},
    {"s1", "dhnn", 2374, 5.891e-3, 1.1e-4, 1.8e-4, 7.8e-5},
    {"s1", "dhnn2", 1190, 8.686e-3, 2.1e-5, 4.4e-5, 1.5e-5},
    {"s1", "phnn", 1193, 9.777e-3, 6.1e-5, 8.0e-5, 4.3e-5},
    {"s1", "phnn2", 1190, 5.248e-3, 5.8e-5, 8.2e-5, 4.1e-5},
    {"s2", "csympnet", 4111, 2.513e-2, 2.7e-6, 3.0e-6, 5.7e-7},
    {"s2", "sympnet", 4110, 1.192, 4.4e-2, 4.4e-2, 1.0e-2},
    {"s2", "map", 6868, 22.74, 3.6e-1, 3.8e-1, 7.8e-2},
    {"s2", "ode", 6804, 2.605e-1, 1.2e-2, 1.6e-2, 1.8e-4},
    {"s2", "dhnn", 11538, 4.664e-1, 2.3e-2, 3.3e-2, 6.0e-4},
    {"s2", "dhnn2", 5970, 2.453e-1, 1.1e-2, 1.3e-2, 3.9e-4},
    {"s2", "phnn", 6369, 1.791e-1, 3.3e-3, 3.4e-3, 2.2e-4},
    {"s2", "phnn2", 5970, 2.305e-1, 2.0e-3, 2.3e-3, 3.9e-4},
    {"s3", "csympnet", 4201, 4.096e-2, 2.6e-5, 2.6e-5, 5.8e-6},
    {"s3", "sympnet", 4200, 1.245, 4.4e-2, 4.4e-2, 1.0e-2},
    {"s3", "map", 6868, 34.72, 3.6e-1, 3.7e-1, 7.8e-2},
    {"s3", "ode", 6804, 1.764e-1, 1.1e-2, 1.4e-2, 1.7e-4},
    {"s3", "dhnn", 11538, 7.159e-1, 2.4e-2, 3.0e-2, 1.3e-3},
    {"s3", "dhnn2", 5970, 3.973e-1, 1.7e-2, 2.3e-2, 7.5e-4},
    {"s3", "phnn", 6369, 3.699e-1, 2.3e-3, 2.5e-3, 3.8e-5},
    {"s3", "phnn2", 5970, 4.992e-1, 2.6e-3, 2.8e-3, 5.2e-4},
    {"s2-100", "csympnet", 161101, 2.609, 2.9e-5, -1, 2.0e-6},
    {"s2-100", "sympnet", 161100, 7.067, 1.4e-1, -1, 1.0e-2},
    {"s2-100", "map", 168904, 2.391e9, 1.2e1, -1, 3.9e-1},
    {"s2-100", "ode", 168648, 61.50, 2.2, -1, 5.1e-3},
    {"s2-100", "dhnn", 275010, 37.73, 8.2e-1, -1, 3.9e-3},
    {"s2-100", "dhnn2", 157506, 22.93, 1.0, -1, 2.4e-2},
    {"s2-100", "phnn", 197505, 11.02, 2.0e-1, -1, 4.8e-3},
    {"s2-100", "phnn2", 157506, 18.08, 2.0e-1, -1, 1.3e-2},
    {"s3-100", "csympnet", 161101, 2.632, 3.8e-4, -1, 2.7e-5},
    {"s3-100", "sympnet", 161100, 4.642, 1.4e-1, -1, 1.0e-2},
    {"s3-100", "map", 168904, 1.336e9, 9.9, -1, 3.7e-1},
    {"s3-100", "ode", 168648, 44.60, 1.4, -1, 2.7e-3},
    {"s3-100", "dhnn", 275010, 13.45, 4.1e-1, -1, 1.1e-3},
    {"s3-100", "dhnn2", 157506, 14.40, 9.5e-1, -1, 2.9e-2},
    {"s3-100", "phnn", 197505, 10.17, 1.1e-1, -1, 2.1e-3},
    {"s3-100", "phnn2", 157506, 31.72, 8.3e-1, -1, 4.8e-2},
}};
}  // namespace

std::optional<PaperValues> paper_values(const std::string& preset, const std::string& model) {
  for (const Row& r : kRows) {
    if (r.preset != preset || r.model != model) continue;
    PaperValues v;
    v.params = r.params;
    v.l2_error = r.l2;
    v.residual_mean = r.r_mean;
    if (r.r_max >= 0) v.residual_max = r.r_max;
    v.lambda_abs_err_mean = r.lam;
    if (model == "csympnet") {
      if (preset == "s1") v.gamma_hat = 4.9998e-2, v.gamma_abs_err = 1.7911e-6;
      if (preset == "s2") v.gamma_hat = 5.0003e-2, v.gamma_abs_err = 3.1821e-6;
      if (preset == "s3") v.gamma_hat = 4.9971e-2, v.gamma_abs_err = 2.9355e-5;
    }
    return v;
  }
  return std::nullopt;
}

}  // namespace csympnet
