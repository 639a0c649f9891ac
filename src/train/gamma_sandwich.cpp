#include "csympnet/train/gamma_sandwich.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <utility>

#include "csympnet/core/dense.hpp"
#include "csympnet/core/error.hpp"
#include "lapack.hpp"

namespace csympnet {

void to_json(nlohmann::json& j, const SandwichInterval& s) {
  j = {{"low", s.low},
       {"high", s.high},
       {"level", s.level},
       {"std_error", s.std_error},
       {"sandwich", s.sandwich},
       {"model_based", s.model_based},
       {"optimisation", s.optimisation},
       {"rounding", s.rounding},
       {"integrator", s.integrator},
       {"dof", s.dof},
       {"effective_blocks", s.effective_blocks},
       {"quantile", s.quantile},
       {"blocks", s.blocks},
       {"regularisation_ratio", s.regularisation_ratio},
       {"stable", s.stable},
       {"heldout_inflation", s.heldout_inflation},
       {"method", s.method}};
}

void inflate_interval(SandwichInterval& s, double factor) {
  require(std::isfinite(factor) && factor >= 1.0, [&] {
    return "inflate_interval: factor must be finite and >= 1, got " + std::to_string(factor);
  });
  s.std_error *= factor;
  s.low = s.gamma - factor * (s.gamma - s.low);
  s.high = s.gamma + factor * (s.high - s.gamma);
  s.heldout_inflation *= factor;
}

void add_integrator(SandwichInterval& s, double change) {
  require(std::isfinite(change) && change >= 0.0, "add_integrator: change must be finite, >= 0");
  s.integrator = change;
  s.std_error = std::hypot(s.std_error, change);
  s.low = s.gamma - s.quantile * s.std_error;
  s.high = s.gamma + s.quantile * s.std_error;
}

namespace {

// The standard normal CDF.
double normal_cdf(double x) {
  return 0.5 * std::erfc(-x / std::sqrt(2.0));
}

// Student's t CDF for x ≥ 0 by composite Simpson on its density (x ≤ 1e3 here).
double t_cdf_positive(double x, double dof) {
  const double log_c = std::lgamma(0.5 * (dof + 1.0)) - std::lgamma(0.5 * dof) -
                       0.5 * std::log(dof * 3.14159265358979323846);
  auto f = [&](double u) { return std::exp(log_c - 0.5 * (dof + 1.0) * std::log1p(u * u / dof)); };
  const int n = 4000;  // even
  const double step = x / n;
  double s = f(0.0) + f(x);
  for (int i = 1; i < n; ++i) s += (i % 2 == 1 ? 4.0 : 2.0) * f(i * step);
  return 0.5 + s * step / 3.0;
}

// The regularised incomplete beta function I_x(a, b) (a, b > 0) by its continued fraction
// (modified Lentz), evaluated on the side of the symmetry I_x(a, b) = 1 − I_{1−x}(b, a) where
// the fraction converges fast.
double incomplete_beta(double x, double a, double b) {
  if (!(x > 0.0)) return 0.0;
  if (!(x < 1.0)) return 1.0;
  if (x > (a + 1.0) / (a + b + 2.0)) return 1.0 - incomplete_beta(1.0 - x, b, a);
  constexpr double tiny = 1e-300;
  const auto guard = [](double v) { return std::abs(v) < tiny ? tiny : v; };
  double c = 1.0, e = 1.0 / guard(1.0 - (a + b) * x / (a + 1.0)), h = e;
  for (int m = 1; m <= 500; ++m) {
    const double m2 = 2.0 * m;
    const double even = m * (b - m) * x / ((a + m2 - 1.0) * (a + m2));
    e = 1.0 / guard(1.0 + even * e);
    c = guard(1.0 + even / c);
    h *= e * c;
    const double odd = -(a + m) * (a + b + m) * x / ((a + m2) * (a + m2 + 1.0));
    e = 1.0 / guard(1.0 + odd * e);
    c = guard(1.0 + odd / c);
    const double change = e * c;
    h *= change;
    if (std::abs(change - 1.0) < 1e-15) break;
  }
  const double log_front =
      a * std::log(x) + b * std::log1p(-x) + std::lgamma(a + b) - std::lgamma(a) - std::lgamma(b);
  return std::exp(log_front) * h / a;
}

// Fisher's F CDF with (d1, d2) degrees of freedom at f ≥ 0.
double f_cdf(double f, double d1, double d2) {
  return incomplete_beta(d1 * f / (d1 * f + d2), 0.5 * d1, 0.5 * d2);
}

template <class Cdf>
double bisect_quantile(double p, Cdf cdf) {
  double lo = 0.0, hi = 1.0;
  while (cdf(hi) < p && hi < 1e3) hi *= 2.0;
  for (int i = 0; i < 200 && hi - lo > 1e-13 * hi; ++i) {
    const double mid = 0.5 * (lo + hi);
    (cdf(mid) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// u = (A + μ D)⁻¹ rhs; μ grows until the factorisation succeeds. Returns the μ used.
double solve_regularised(const Matrix& a, const Vector& rhs, double mu, Vector& u) {
  const Index n = a.rows();
  const Vector diag = a.diagonal().cwiseMax(1e-300);
  // One OpenBLAS thread, as in LM: its threaded dpotrf changes the interval's last bits with
  // the thread count (a plain run on a multi-core machine against an mpirun rank bound to a
  // core), and the interval is part of the report that must not depend on it.
  const lapack::SingleThreaded one_thread;
  Matrix lhs(n, n);
  for (int tries = 0; tries < 40; ++tries, mu *= 10.0) {
    lhs = a;
    lhs.diagonal() += mu * diag;
    if (!lapack::cholesky(lhs.data(), n)) continue;
    u = rhs;
    lapack::cholesky_solve(lhs.data(), n, u.data());
    if (u.allFinite()) return mu;
  }
  throw Error("interval: the Gauss-Newton matrix could not be factored");
}

}  // namespace

double normal_quantile(double p) {
  require(p > 0.0 && p < 1.0, "normal_quantile: p must be in (0, 1)");
  if (p < 0.5) return -normal_quantile(1.0 - p);
  return bisect_quantile(p, normal_cdf);
}

double student_t_quantile(double p, double dof) {
  require(p > 0.0 && p < 1.0, "student_t_quantile: p must be in (0, 1)");
  require(dof >= 1.0, "student_t_quantile: need at least one degree of freedom");
  if (p < 0.5) return -student_t_quantile(1.0 - p, dof);
  if (dof > 1e6) return normal_quantile(p);
  // Each quantile takes about 10⁶ evaluations of the density (bisection on a Simpson rule), and
  // a fit asks for the same few (p, dof) once per interval: a Hamiltonian's terms, the modes,
  // the checks (a 10-dof chain spent 2.5 s in them). The values are kept per process, the
  // same bits as computed afresh.
  static std::mutex lock;
  static std::map<std::pair<double, double>, double> known;
  const std::pair<double, double> key{p, dof};
  {
    const std::lock_guard<std::mutex> hold(lock);
    if (const auto it = known.find(key); it != known.end()) return it->second;
  }
  const double q = bisect_quantile(p, [dof](double x) { return t_cdf_positive(x, dof); });
  const std::lock_guard<std::mutex> hold(lock);
  if (known.size() >= 4096) known.clear();
  known.emplace(key, q);
  return q;
}

double f_quantile(double p, double d1, double d2) {
  require(p > 0.0 && p < 1.0, "f_quantile: p must be in (0, 1)");
  require(d1 > 0.0 && d2 > 0.0, "f_quantile: need positive degrees of freedom");
  double hi = 1.0;
  while (f_cdf(hi, d1, d2) < p && hi < 1e300) hi *= 2.0;
  double lo = hi > 1.0 ? 0.5 * hi : 0.0;
  for (int i = 0; i < 200 && hi - lo > 1e-13 * hi; ++i) {
    const double mid = 0.5 * (lo + hi);
    (f_cdf(mid, d1, d2) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

double chi_square_quantile(double p, double n) {
  require(p > 0.0 && p < 1.0, "chi_square_quantile: p must be in (0, 1)");
  require(n > 0.0, "chi_square_quantile: need a positive number of degrees of freedom");
  const double z = normal_quantile(p), v = 2.0 / (9.0 * n);
  return n * std::pow(1.0 - v + z * std::sqrt(v), 3);
}

double hotelling_limit(double p, Index k, Index blocks) {
  require(k >= 1 && blocks > k, "hotelling_limit: need 1 <= k < blocks");
  const double kd = static_cast<double>(k), b = static_cast<double>(blocks);
  return kd * (b - 1.0) / (b - kd) * f_quantile(p, kd, b - kd);
}

JointWald negligible_together(const Matrix& a, const Matrix& scores, const Vector& theta,
                              const std::vector<Index>& at, double level, WaldReference reference) {
  const Index np = theta.size(), b = scores.cols(), k = static_cast<Index>(at.size());
  require(a.rows() == np && a.cols() == np && scores.rows() == np,
          "negligible_together: A must be P x P and the scores P x B, P = theta's size");
  require(std::all_of(at.begin(), at.end(), [np](Index j) { return j >= 0 && j < np; }),
          "negligible_together: a parameter index is out of range");
  if (k < 2 || b < 3) return {};
  Matrix lower = a.selfadjointView<Eigen::Lower>();
  lower.diagonal() += 1e-10 * lower.diagonal().cwiseAbs().cwiseMax(1e-300);
  const dense::Ldlt f(lower);
  if (!f.ok()) return {};
  Matrix unit = Matrix::Zero(np, k);
  Vector coef(k);
  for (Index j = 0; j < k; ++j) {
    unit(at[static_cast<std::size_t>(j)], j) = 1.0;
    coef(j) = theta(at[static_cast<std::size_t>(j)]);
  }
  const Matrix centred = scores.colwise() - scores.rowwise().mean();
  const Matrix m = centred.transpose() * f.solve(unit);  // B × k: each block's share of θ_S
  const Matrix cov = (m.transpose() * m) * (static_cast<double>(b) / static_cast<double>(b - 1));
  for (Index n = std::min(k, b - 1); n >= 2; --n) {
    const dense::Ldlt c(cov.topLeftCorner(n, n));
    if (!c.ok()) continue;
    const double wald = coef.head(n).dot(c.solve(Vector(coef.head(n))));
    const double limit = reference == WaldReference::kHotelling
                             ? hotelling_limit(level, n, b)
                             : chi_square_quantile(level, static_cast<double>(n));
    if (std::isfinite(wald) && wald >= 0.0 && wald <= limit) return {n, wald};
  }
  return {};
}

SandwichInterval sandwich_interval_of(const Matrix& a, const Vector& g, const Matrix& scores,
                                      const Vector& gradient, double value, Index n_residuals,
                                      double cost, double residual_scale, double data_scale,
                                      double level, const std::vector<Matrix>* block_information) {
  const Index p = a.rows();
  require(a.cols() == p && g.size() == p && scores.rows() == p && gradient.size() == p,
          "interval: inconsistent normal equations");
  require(gradient.allFinite() && gradient.squaredNorm() > 0.0,
          "interval: the gradient of the estimate must be finite and nonzero");
  require(level > 0.0 && level < 1.0, "interval: level must be in (0, 1)");
  SandwichInterval s;
  s.gamma = value;
  s.level = level;
  s.blocks = scores.cols();
  // A is only the lower triangle: symmetrise once.
  Matrix full = a.selfadjointView<Eigen::Lower>();
  // Σ_b (uᵀs_b − mean)²: the spread of the blocks' scores, before the small-sample factor.
  auto block_sum_sq = [&](const Vector& u) {
    const Index b = scores.cols();
    if (b < 2) return 0.0;
    Vector v = scores.transpose() * u;
    const double mean = v.mean();
    return (v.array() - mean).square().sum();
  };
  Vector u;
  const double mu = solve_regularised(full, gradient, 1e-9, u);
  Vector u100;
  solve_regularised(full, gradient, 100.0 * mu, u100);
  const double sum_sq = block_sum_sq(u);
  const double sum_sq100 = block_sum_sq(u100);
  s.regularisation_ratio = sum_sq > 0.0 ? std::sqrt(sum_sq100 / sum_sq) : 1.0;
  // A smaller interval at more regularisation is expected (it suppresses weak directions);
  // one that changes by more than 2× means the estimate leans on directions the data barely
  // fix.
  s.stable = std::isfinite(s.regularisation_ratio) && s.regularisation_ratio > 0.5 &&
             s.regularisation_ratio < 2.0;
  const double u_f = std::max(0.0, gradient.dot(u));
  const double n_res = static_cast<double>(n_residuals);
  const double dof_res = std::max(n_res - static_cast<double>(p), 0.25 * n_res);
  s.model_based = std::sqrt(2.0 * cost / dof_res * u_f);
  s.optimisation = std::abs(u.dot(g));
  s.rounding =
      16.0 * std::numeric_limits<double>::epsilon() * data_scale * residual_scale * std::sqrt(u_f);
  // The model-based error assumes independent residuals; overlapping windows make them
  // correlated (negatively at lag m), so it is reported but not used. Few blocks estimate the
  // variance poorly, which the t quantile with B − 1 degrees of freedom accounts for.
  s.method = "cluster-robust sandwich over blocks";
  s.dof = std::max(1.0, static_cast<double>(s.blocks - 1));
  if (block_information != nullptr && !block_information->empty()) {
    double sum = 0.0, info_sq = 0.0;
    for (const Matrix& info : *block_information) {
      const double w = std::max(0.0, u.dot(info * u));
      sum += w;
      info_sq += w * w;
    }
    if (info_sq > 0.0 && std::isfinite(sum * sum / info_sq)) {
      s.effective_blocks = sum * sum / info_sq;
      s.dof = std::clamp(s.effective_blocks - 1.0, 1.0, s.dof);
    }
  }
  // Each block's score is built from residuals the estimate has fitted, block b's in the share
  // w_b / Σw of the information: E Σ_b (uᵀs_b)² = (1 − Σ_b (w_b / Σw)²) var(γ̂) in the one-
  // parameter case, and 1 − Σ_b (w_b / Σw)² is 1 / (effective blocks) of the t quantile's count
  // (docs/derivations.md, "How many blocks an interval rests on"). The factor (dof + 1) / dof
  // undoes it, B / (B − 1) when every block carries the same share.
  s.sandwich = s.blocks >= 2 ? std::sqrt((s.dof + 1.0) / s.dof * sum_sq) : 0.0;
  s.std_error = std::sqrt(s.sandwich * s.sandwich + s.optimisation * s.optimisation +
                          s.rounding * s.rounding);
  s.quantile = student_t_quantile(0.5 * (1.0 + level), s.dof);
  s.low = value - s.quantile * s.std_error;
  s.high = value + s.quantile * s.std_error;
  return s;
}

SandwichInterval sandwich_interval(const Matrix& a, const Vector& g, const Matrix& scores,
                                   Index gamma_index, double gamma, double gamma_sign,
                                   Index n_residuals, double cost, double residual_scale,
                                   double data_scale, double level,
                                   const std::vector<Matrix>* block_information) {
  require(gamma_index >= 0 && gamma_index < a.rows(), "interval: bad damping index");
  Vector gradient = Vector::Zero(a.rows());
  gradient(gamma_index) = gamma_sign != 0.0 ? gamma_sign : 1.0;  // dγ̂/dθ
  return sandwich_interval_of(a, g, scores, gradient, gamma, n_residuals, cost, residual_scale,
                              data_scale, level, block_information);
}

}  // namespace csympnet
