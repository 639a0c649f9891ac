#include "csympnet/identify/model_checks.hpp"
#include "csympnet/core/dense.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <numeric>
#include <optional>
#include <sstream>

#include <Eigen/Eigenvalues>
#include <boost/math/distributions/fisher_f.hpp>
#include <boost/math/distributions/students_t.hpp>

#include "csympnet/core/error.hpp"
#include "csympnet/io/json_text.hpp"
#include "csympnet/train/gamma_sandwich.hpp"
#include "damping_profile.hpp"

namespace csympnet {

namespace {

using detail::BlockProfile;
using detail::DampingBasis;
using detail::DampingProfile;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// The power quoted as "detectable": the effect found with probability 0.8 at level alpha.
constexpr double kPowerZ = 0.8416;
// More blocks than this are grouped into this many folds for the one-rate comparison.
constexpr Index kMaxFolds = 40;
// Full d × d damping matrices up to this d; rates per coordinate beyond.
constexpr Index kMaxFullDamping = 8;

std::string fmt(double v, int digits = 3) {
  std::ostringstream s;
  s.precision(digits);
  s << v;
  return s.str();
}

// A share as a percentage people read: "320%", "45%", "2.5%", never "3.2e+02%".
std::string percent(double share) {
  const double v = 100.0 * share;
  if (!std::isfinite(v)) return fmt(v) + "%";
  if (std::abs(v) >= 10.0) {
    std::ostringstream s;
    s << std::fixed << std::setprecision(0) << v;
    return s.str() + "%";
  }
  return fmt(v, 2) + "%";
}

// "95%" for a level of 0.95.
std::string level_words(double level) {
  return fmt(100.0 * level, 4) + "%";
}

double upper_t_p(double t, double dof) {  // P(T > t)
  if (!std::isfinite(t)) return t > 0 ? 0.0 : 1.0;
  return boost::math::cdf(boost::math::complement(boost::math::students_t(dof), t));
}

// The signed rate's cluster-robust standard error over blocks (its estimating equation
// Σ_b g_b(c) = 0; a sandwich with one parameter).
double common_rate_se(const std::vector<BlockProfile>& bs) {
  double a = 0.0, s = 0.0;
  Index used = 0;
  for (const BlockProfile& b : bs) {
    if (b.samples == 0) continue;
    a += b.a;
    s += b.g * b.g;
    ++used;
  }
  if (used < 2 || !(a > 0.0)) return kNaN;
  const double nb = static_cast<double>(used);
  return std::sqrt(nb / (nb - 1.0) * s) / a;
}

// The common signed rate c at which Σ_b g_b = 0 (Gauss–Newton on c alone, the core fixed),
// started from the model's own rate, with the per-block sums at it. The fit ends where the next
// step would move c by less than 1e-3 of its standard error (or 1e-9 of itself): c stays where
// the sums were taken, so that they need no further pass over the data.
struct CommonRate {
  double c = 0.0;
  std::vector<BlockProfile> bs;
};
CommonRate fit_common_rate(const DampingProfile& prof, double c0,
                           const std::function<bool()>& stop) {
  constexpr double kShareOfSe = 1e-3;
  CommonRate out{c0, {}};
  for (int it = 0; it < 8; ++it) {
    out.bs = prof.blocks(out.c, nullptr, stop);
    double a = 0.0, g = 0.0;
    for (const BlockProfile& b : out.bs) {
      a += b.a;
      g += b.g;
    }
    if (!(a > 0.0) || (stop && stop())) return out;
    const double step = -g / a;
    const double se = common_rate_se(out.bs);
    if (std::abs(step) <= 1e-12 + 1e-9 * std::abs(out.c) ||
        (std::isfinite(se) && std::abs(step) <= kShareOfSe * se))
      return out;
    out.c += step;
  }
  out.bs = prof.blocks(out.c, nullptr, stop);
  return out;
}

ModelCheck dissipation_check(const CheckInput& in, double c, double se, Index n_blocks) {
  ModelCheck k;
  k.name = "dissipation";
  k.assumption = "dissipation (the motion loses energy: no energy input, no forcing)";
  k.statistic_name = "signed rate / standard error";
  k.effect_name = "growth rate (1/time unit), where the motion grows";
  k.alpha = 1.0 - in.thresholds.growth_confidence;
  const double tau = in.time_scale;
  if (!std::isfinite(se) || n_blocks < 3) {
    k.applicable = false;
    k.sentence = "too few blocks to bound the signed damping rate";
    return k;
  }
  const double dof = static_cast<double>(n_blocks - 1);
  const double tq = student_t_quantile(0.5 + 0.5 * in.level, dof);
  k.statistic = se > 0.0 ? c / se : (c < 0 ? -INFINITY : INFINITY);
  k.p_value = upper_t_p(-k.statistic, dof);  // P(T < statistic): small when c is clearly < 0
  const double upper = c + student_t_quantile(in.thresholds.growth_confidence, dof) * se;
  k.details = {{"signed_rate", c / tau},
               {"interval", {(c - tq * se) / tau, (c + tq * se) / tau}},
               {"level", in.level}};
  k.effect = std::max(0.0, -c / tau);
  k.effect_threshold = 0.0;
  k.passed = !(upper < 0.0);
  if (!k.passed) {
    k.sentence =
        "the motion grows: energy is being added (negative damping or forcing), at a rate " +
        fmt(-c / tau, 4) + " [" + fmt(-(c + tq * se) / tau, 4) + ", " +
        fmt(-(c - tq * se) / tau, 4) + "] per time unit";
  } else {
    // The same rate as γ̂: a second interval for it on the same screen (this one from the
    // blocks' t-quantiles) would only compete with γ̂'s; details keep it.
    k.sentence = "no sign of energy input: the damping rate is not below 0 with " +
                 fmt(100.0 * in.thresholds.growth_confidence, 3) +
                 "% confidence (its value and interval are gamma_hat's)";
  }
  return k;
}

// Weighted least squares of y on x with the dispersion estimated from the scatter.
struct Trend {
  double mean_x = 0.0, mean_y = 0.0, slope = 0.0, se_slope = kNaN, sigma2 = kNaN;
  double sw = 0.0, sxx = 0.0;
  Index n = 0;
  double at(double x) const { return mean_y + slope * (x - mean_x); }
  double se_at(double x) const {
    return std::sqrt(sigma2 * (1.0 / sw + (x - mean_x) * (x - mean_x) / sxx));
  }
};

Trend weighted_trend(const std::vector<double>& x, const std::vector<double>& y,
                     const std::vector<double>& w) {
  Trend t;
  t.n = static_cast<Index>(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    t.sw += w[i];
    t.mean_x += w[i] * x[i];
    t.mean_y += w[i] * y[i];
  }
  t.mean_x /= t.sw;
  t.mean_y /= t.sw;
  double sxy = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    t.sxx += w[i] * (x[i] - t.mean_x) * (x[i] - t.mean_x);
    sxy += w[i] * (x[i] - t.mean_x) * (y[i] - t.mean_y);
  }
  if (!(t.sxx > 0.0) || t.n < 3) return t;
  t.slope = sxy / t.sxx;
  double rss = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double e = y[i] - t.at(x[i]);
    rss += w[i] * e * e;
  }
  // The weights are the blocks' Gauss–Newton curvatures: relative precisions, their scale
  // set by the scatter about the line.
  t.sigma2 = rss / static_cast<double>(t.n - 2);  // Var(y_i) = sigma2 / w_i
  t.se_slope = std::sqrt(t.sigma2 / t.sxx);
  return t;
}

// Weighted quantile of x.
double weighted_quantile(std::vector<std::pair<double, double>> xw, double q) {
  std::sort(xw.begin(), xw.end());
  double total = 0.0;
  for (const auto& p : xw) total += p.second;
  double acc = 0.0;
  for (const auto& p : xw) {
    acc += p.second;
    if (acc >= q * total) return p.first;
  }
  return xw.back().first;
}

ModelCheck linear_damping_check(const CheckInput& in, double c, double se_c,
                                const std::vector<BlockProfile>& bs) {
  ModelCheck k;
  k.name = "linear_damping";
  k.assumption = "linear damping (a rate that does not depend on the amplitude)";
  k.statistic_name = "slope of the block rate on log energy / standard error";
  k.effect_name = "relative change of the rate across the amplitudes observed";
  k.alpha = in.thresholds.alpha_linear_damping;
  k.effect_threshold = in.thresholds.rate_change;
  const double tau = in.time_scale;
  std::vector<double> x, y, w;
  std::vector<std::pair<double, double>> xw;
  for (const BlockProfile& b : bs) {
    if (b.samples < 1 || !(b.a > 0.0) || !(b.energy > 0.0)) continue;
    x.push_back(std::log(b.energy));
    y.push_back(c - b.g / b.a);
    w.push_back(b.a);
    xw.emplace_back(x.back(), w.back());
  }
  if (x.size() < 5) {
    k.applicable = false;
    k.sentence = "too few blocks (" + std::to_string(x.size()) +
                 ") to estimate the rate at different amplitudes";
    return k;
  }
  if (!(std::abs(c) > 2.0 * se_c)) {
    k.applicable = false;
    k.sentence = "no damping is clearly visible, so its dependence on amplitude cannot be tested";
    return k;
  }
  const double lo = weighted_quantile(xw, 0.1), hi = weighted_quantile(xw, 0.9);
  const double range = hi - lo;
  k.details["energy_ratio"] = std::exp(range);
  if (range < in.thresholds.min_log_energy_range) {
    k.applicable = false;
    k.sentence = "the blocks span energies within a factor " + fmt(std::exp(range), 2) +
                 " of each other: too narrow to tell amplitude-dependent damping from a constant "
                 "rate";
    return k;
  }
  const Trend t = weighted_trend(x, y, w);
  const double dof = static_cast<double>(t.n - 2);
  if (!std::isfinite(t.se_slope)) {
    k.applicable = false;
    k.sentence = "the block rates could not be regressed on energy";
    return k;
  }
  k.statistic = t.se_slope > 0.0 ? t.slope / t.se_slope : (t.slope == 0.0 ? 0.0 : INFINITY);
  k.p_value = 2.0 * upper_t_p(std::abs(k.statistic), dof);
  k.effect = t.slope * range / std::abs(c);
  const double tq = student_t_quantile(1.0 - 0.5 * k.alpha, dof);
  k.detectable_effect = (tq + kPowerZ) * t.se_slope * range / std::abs(c);
  const double tl = student_t_quantile(0.5 + 0.5 * in.level, dof);
  const auto rate_at = [&](double lx) {
    const double r = t.at(lx), s = t.se_at(lx);
    return nlohmann::json{{"rate", r / tau},
                          {"interval", {(r - tl * s) / tau, (r + tl * s) / tau}}};
  };
  k.details["high_energy"] = rate_at(hi);
  k.details["low_energy"] = rate_at(lo);
  k.details["level"] = in.level;
  // The rate at small amplitude over the rate at large amplitude, R = y(lo)/y(hi), with its
  // interval by the delta method (the trend's mean and slope are uncorrelated about the
  // weighted mean of x).
  const double y_lo = t.at(lo), y_hi = t.at(hi);
  const double ratio = y_lo / y_hi;
  const double d_mean = (y_hi - y_lo) / (y_hi * y_hi);
  const double d_slope = ((lo - t.mean_x) * y_hi - (hi - t.mean_x) * y_lo) / (y_hi * y_hi);
  const double se_ratio =
      std::sqrt(t.sigma2 * (d_mean * d_mean / t.sw + d_slope * d_slope / t.sxx));
  k.details["rate_ratio_small_to_large"] = {
      {"ratio", ratio}, {"interval", {ratio - tl * se_ratio, ratio + tl * se_ratio}}};
  const bool significant = k.p_value < k.alpha;
  k.passed = !(significant && std::abs(k.effect) > k.effect_threshold);
  k.warning = significant && k.passed;
  const std::string hl = "the rate is " + fmt(t.at(hi) / tau, 4) +
                         " at the largest amplitudes and " + fmt(t.at(lo) / tau, 4) +
                         " at the smallest";
  const std::string ratio_words =
      "the rate at small amplitude is " + fmt(ratio, 3) + "x the rate at large amplitude [" +
      fmt(ratio - tl * se_ratio, 3) + ", " + fmt(ratio + tl * se_ratio, 3) +
      "] (p = " + fmt(k.p_value, 2) + ")";
  if (k.warning) {
    k.sentence = "significant but small: " + ratio_words + ", a change of " +
                 fmt(100.0 * std::abs(k.effect), 3) + "% across the amplitudes, below the " +
                 fmt(100.0 * k.effect_threshold, 3) + "% that fails the check" +
                 (t.slope < 0.0 ? " (dry friction raises the rate at small amplitude)"
                                : " (quadratic drag raises the rate at large amplitude)");
  } else if (k.passed) {
    // The effect with its interval, in plain words: how much the rate changes from the
    // smallest amplitudes to the largest.
    const double half = tl * t.se_slope * range / std::abs(c);
    const auto pct = [](double v) { return (v > 0 ? "+" : "") + percent(v); };
    k.sentence =
        "no clear dependence on amplitude: from the smallest to the largest "
        "amplitudes (energies a factor " +
        fmt(std::exp(range), 2) + " apart) the rate changes by " + pct(k.effect) + " [" +
        pct(k.effect - half) + ", " + pct(k.effect + half) + "] (" + hl + ")";
  } else if (t.slope < 0.0) {
    k.sentence = "the damping rate rises as the amplitude falls, as dry (Coulomb) friction does: " +
                 ratio_words + "; " + hl;
  } else {
    k.sentence = "the damping rate rises with the amplitude, as quadratic (fluid) drag does: " +
                 ratio_words + "; " + hl;
  }
  return k;
}

// Real parts of the eigenvalues of C, ascending.
std::vector<double> sorted_rates(const Matrix& c) {
  const dense::Eigensystem es = dense::eigensystem(c, false);
  std::vector<double> r;
  for (Index i = 0; i < c.rows(); ++i) r.push_back(es.values(i).real());
  std::sort(r.begin(), r.end());
  return r;
}

struct FoldSums {
  Matrix a;
  Vector g;
  double sa = 0.0, sg = 0.0;
};

// The freedom given to C: a rate per mode of the core's linearisation where its modes are
// well defined (d − 1 constraints: the alternative the model's assumption names). Otherwise
// all d² entries while their d² − 1 constraints leave half the blocks' degrees of freedom
// (and d ≤ 8), else the d diagonal entries.
DampingBasis basis_for(const DampingProfile& prof,
                       const std::optional<detail::LinearModes>& modes) {
  const Index d = prof.dofs();
  if (modes) {
    DampingBasis b = detail::modal_damping_basis(modes->p);
    b.name += " (" + modes->where + ")";
    return b;
  }
  const Index room = (prof.n_blocks() - 1) / 2;
  return d <= kMaxFullDamping && d * d - 1 <= room ? detail::full_damping_basis(d)
                                                   : detail::coordinate_damping_basis(d);
}

// Cluster-robust Wald test that the step Δ = −A⁻¹g from cI lies along the common rate: the
// block scores at the unrestricted (one-step) estimate, g_b + A_b Δ, give
// V = A⁻¹ (B/(B−1) Σ_b s_b s_bᵀ) A⁻¹; W = (PΔ)ᵀ (P V P)⁺ (PΔ) with P the projection off vec(I),
// q = n_c − 1 constraints, and Hotelling's correction F = (B − q) / (q (B − 1)) W ~ F(q, B − q).
struct Wald {
  double f = kNaN, p = kNaN;
  Index q = 0;
};
Wald robust_wald(const std::vector<BlockProfile>& bs, const Matrix& a_inv, const Vector& delta,
                 const Vector& common) {
  const Index ne = delta.size();
  Matrix s = Matrix::Zero(ne, ne);
  Index used = 0;
  for (const BlockProfile& b : bs) {
    if (b.samples == 0) continue;
    const Vector sb = b.big_g + b.big_a * delta;
    s.noalias() += sb * sb.transpose();
    ++used;
  }
  Wald w;
  w.q = ne - 1;
  const double nb = static_cast<double>(used);
  if (used - w.q < 1) return w;
  const Matrix v = a_inv * (nb / (nb - 1.0) * s) * a_inv;
  const Vector u = common / common.norm();
  const Matrix proj = Matrix::Identity(ne, ne) - u * u.transpose();
  const Vector pd = proj * delta;
  const Matrix pv = proj * v * proj;
  const dense::SymmetricEigen es = dense::symmetric_eigen(0.5 * (pv + pv.transpose()));
  const double top = es.values.cwiseAbs().maxCoeff();
  double wald = 0.0;
  for (Index i = 0; i < ne; ++i) {
    const double ev = es.values(i);
    if (ev <= 1e-12 * top) continue;  // the common direction, and any the data do not see
    const double x = es.vectors.col(i).dot(pd);
    wald += x * x / ev;
  }
  const double q = static_cast<double>(w.q);
  w.f = (nb - q) / (q * (nb - 1.0)) * wald;
  w.p = boost::math::cdf(boost::math::complement(boost::math::fisher_f(q, nb - q), w.f));
  return w;
}

// The blocks held out in turn (K folds): the gain in predicting fold f of the damping matrix
// fitted on the others over that of one rate fitted on the others; the t statistic of the
// mean gain (reported; informative when the violation is spread over many blocks).
double heldout_gain_t(const std::vector<FoldSums>& f, const FoldSums& all, double ridge) {
  const Index ne = all.g.size();
  std::vector<double> gain;
  for (const FoldSums& s : f) {
    const Vector delta =
        -dense::Ldlt(all.a - s.a + ridge * Matrix::Identity(ne, ne)).solve(Vector(all.g - s.g));
    const double out_full = -2.0 * s.g.dot(delta) - delta.dot(s.a * delta);
    const double rest = all.sa - s.sa;
    const double dc = rest > 0.0 ? -(all.sg - s.sg) / rest : 0.0;
    gain.push_back(out_full - (-2.0 * s.sg * dc - s.sa * dc * dc));
  }
  const double nf = static_cast<double>(gain.size());
  const double mean = std::accumulate(gain.begin(), gain.end(), 0.0) / nf;
  double var = 0.0;
  for (double x : gain) var += (x - mean) * (x - mean);
  var /= nf - 1.0;
  return var > 0.0 ? mean / std::sqrt(var / nf) : 0.0;
}

// Rates per mode and their jackknife standard errors over the folds. With modes, the rate of
// mode k is c + δ_k, in the modes' order (ascending frequency); otherwise the real parts of
// C's eigenvalues, ascending.
struct ModeRates {
  std::vector<double> rate, se;
  double spread_se = 0.0;  // of max − min
};
ModeRates mode_rates(const DampingBasis& basis, const std::optional<detail::LinearModes>& modes,
                     double c, const Vector& delta, const std::vector<FoldSums>& f,
                     const FoldSums& all, double ridge) {
  const Index ne = basis.size();
  const auto rates_of = [&](const Vector& dl) {
    if (!modes) return sorted_rates(basis.matrix(c, dl));
    std::vector<double> r;
    for (Index i = 0; i < ne; ++i) r.push_back(c + dl(i));
    return r;
  };
  const auto spread = [](const std::vector<double>& r) {
    const auto [lo, hi] = std::minmax_element(r.begin(), r.end());
    return *hi - *lo;
  };
  ModeRates out;
  out.rate = rates_of(delta);
  std::vector<std::vector<double>> fold_rates;
  for (const FoldSums& s : f)
    fold_rates.push_back(rates_of(
        -dense::Ldlt(all.a - s.a + ridge * Matrix::Identity(ne, ne)).solve(Vector(all.g - s.g))));
  const double nf = static_cast<double>(f.size());
  const auto jackknife_se = [&](const std::function<double(const std::vector<double>&)>& stat) {
    double m = 0.0, v = 0.0;
    for (const auto& fr : fold_rates) m += stat(fr) / nf;
    for (const auto& fr : fold_rates) v += (stat(fr) - m) * (stat(fr) - m);
    return std::sqrt((nf - 1.0) / nf * v);
  };
  for (std::size_t i = 0; i < out.rate.size(); ++i)
    out.se.push_back(jackknife_se([i](const std::vector<double>& r) { return r[i]; }));
  out.spread_se = jackknife_se(spread);
  return out;
}

ModelCheck one_rate_check(const CheckInput& in, const DampingProfile& prof, double c,
                          const std::function<bool()>& stop) {
  ModelCheck k;
  k.name = "one_rate";
  k.assumption = "one damping rate for every mode";
  k.statistic_name = "cluster-robust Wald F of a damping matrix against one rate";
  k.effect_name = "spread of the rates per mode over the common rate";
  k.alpha = in.thresholds.alpha;
  k.effect_threshold = in.thresholds.rate_spread;
  const Index d = prof.dofs();
  if (d == 1) {
    k.applicable = false;
    k.sentence = "one degree of freedom: one mode";
    return k;
  }
  if (prof.n_blocks() - (d - 1) < 3) {
    k.applicable = false;
    k.sentence = "too few blocks to test a rate per degree of freedom";
    return k;
  }
  const std::optional<detail::LinearModes> modes = prof.linear_modes();
  const DampingBasis basis = basis_for(prof, modes);
  const Index ne = basis.size();
  k.details["freedom"] = basis.name;
  const std::vector<BlockProfile> bs = prof.blocks(c, &basis, stop);
  const Index folds = std::min<Index>(static_cast<Index>(bs.size()), kMaxFolds);
  std::vector<FoldSums> f(static_cast<std::size_t>(folds),
                          FoldSums{Matrix::Zero(ne, ne), Vector::Zero(ne)});
  FoldSums all{Matrix::Zero(ne, ne), Vector::Zero(ne)};
  for (std::size_t b = 0; b < bs.size(); ++b) {
    FoldSums& s = f[b % static_cast<std::size_t>(folds)];
    s.a += bs[b].big_a;
    s.g += bs[b].big_g;
    s.sa += bs[b].a;
    s.sg += bs[b].g;
  }
  for (const FoldSums& s : f) {
    all.a += s.a;
    all.g += s.g;
    all.sa += s.sa;
    all.sg += s.sg;
  }
  const double ridge = 1e-10 * all.a.trace() / static_cast<double>(ne) + 1e-300;
  const Matrix a_inv = dense::inverse(all.a + ridge * Matrix::Identity(ne, ne));
  const Vector delta = -a_inv * all.g;
  const Wald w = robust_wald(bs, a_inv, delta, basis.common);
  k.statistic = w.f;
  k.p_value = w.p;
  k.details["wald_constraints"] = w.q;
  k.details["heldout_gain_t"] = heldout_gain_t(f, all, ridge);
  const ModeRates mr = mode_rates(basis, modes, c, delta, f, all, ridge);
  const double nf = static_cast<double>(folds);
  const double tl = student_t_quantile(0.5 + 0.5 * in.level, nf - 1.0);
  const double tau = in.time_scale;
  nlohmann::json per_mode = nlohmann::json::array();
  for (std::size_t i = 0; i < mr.rate.size(); ++i) {
    nlohmann::json m = {
        {"rate", mr.rate[i] / tau},
        {"interval", {(mr.rate[i] - tl * mr.se[i]) / tau, (mr.rate[i] + tl * mr.se[i]) / tau}}};
    if (modes) m["angular_frequency"] = modes->frequency(static_cast<Index>(i)) / tau;
    per_mode.push_back(m);
  }
  k.details["rates"] = per_mode;
  k.details["level"] = in.level;
  const auto [lo, hi] = std::minmax_element(mr.rate.begin(), mr.rate.end());
  const std::vector<double>& rates = mr.rate;
  k.effect = (*hi - *lo) / std::abs(c);
  const double tq = student_t_quantile(1.0 - k.alpha, nf - 1.0);
  k.detectable_effect = (tq + kPowerZ) * mr.spread_se / std::abs(c);
  k.passed = !(k.p_value < k.alpha && k.effect > k.effect_threshold);
  std::string list;
  for (std::size_t i = 0; i < rates.size(); ++i) {
    list += (list.empty() ? "" : ", ") + fmt(rates[i] / tau, 4) + " [" +
            fmt((rates[i] - tl * mr.se[i]) / tau, 3) + ", " +
            fmt((rates[i] + tl * mr.se[i]) / tau, 3) + "]";
    if (modes)
      list +=
          " (at angular frequency " + fmt(modes->frequency(static_cast<Index>(i)) / tau, 3) + ")";
  }
  if (!k.passed) {
    k.sentence =
        "the modes damp at different rates: " + list + " per time unit, where the model has one";
  } else if (k.detectable_effect > k.effect_threshold) {
    k.sentence =
        "these data cannot tell one rate from rates per mode unless they differ by "
        "more than " +
        percent(k.detectable_effect) + " of the common rate (rates per mode, with " +
        level_words(in.level) + " intervals: " + list + ")";
  } else {
    k.sentence = "one rate fits all modes: no spread beyond " +
                 percent(std::max(k.effect, k.detectable_effect)) +
                 " of the common rate (rates per mode, with " + level_words(in.level) +
                 " intervals: " + list + ")";
  }
  return k;
}

ModelCheck residuals_check(const CheckInput& in, const std::vector<BlockProfile>& bs) {
  ModelCheck k;
  k.name = "residuals";
  k.assumption = "nothing left over (one-step residuals hold no structure beyond noise)";
  k.statistic_name = "lag-2 residual covariance / standard error";
  k.effect_name = "structured residual per step over the motion per step";
  k.alpha = in.thresholds.alpha;
  k.effect_threshold = in.thresholds.residual_share;
  double lag0 = 0.0, lag1 = 0.0, lag2 = 0.0, motion = 0.0, rss = 0.0;
  Index pairs = 0, samples = 0, used = 0;
  for (const BlockProfile& b : bs) {
    lag2 += b.lag2;
    lag1 += b.lag1;
    lag0 += b.lag0;
    pairs += b.lag2_pairs;
    motion += b.motion;
    rss += b.rss;
    samples += b.samples;
    if (b.lag2_pairs > 0) ++used;
  }
  if (used < 3 || pairs < 10 || !(motion > 0.0)) {
    k.applicable = false;
    k.sentence = "too few consecutive steps along trajectories to look for structure";
    return k;
  }
  const double c2 = lag2 / static_cast<double>(pairs);
  double v = 0.0;
  for (const BlockProfile& b : bs) {
    if (b.lag2_pairs == 0) continue;
    const double e = b.lag2 - c2 * static_cast<double>(b.lag2_pairs);
    v += e * e;
  }
  const double nb = static_cast<double>(used);
  const double se = std::sqrt(nb / (nb - 1.0) * v) / static_cast<double>(pairs);
  k.statistic = se > 0.0 ? c2 / se : (c2 > 0.0 ? INFINITY : 0.0);
  k.p_value = upper_t_p(k.statistic, nb - 1.0);
  const double step_motion = motion / static_cast<double>(samples);
  k.effect = std::sqrt(std::max(0.0, c2) / step_motion);
  const double tq = student_t_quantile(1.0 - k.alpha, nb - 1.0);
  k.detectable_effect = std::sqrt((tq + kPowerZ) * se / step_motion);
  const double rho1 = rss > 0.0 ? lag1 / rss : 0.0;
  k.details = {{"lag1_correlation", rho1},
               {"lag2_correlation", lag0 > 0.0 ? lag2 / lag0 : 0.0},
               {"relative_residual", std::sqrt(rss / motion)}};
  k.passed = !(k.p_value < k.alpha && k.effect > k.effect_threshold);
  k.sentence = (k.passed ? "the residuals keep a structured part of "
                         : "the model leaves a structured error of ") +
               percent(k.effect) + " of the motion per step (lag-1 correlation " + fmt(rho1, 2) +
               ")" +
               (k.passed ? ""
                         : ": a force or dissipation the model lacks (forcing, a drifting "
                           "equilibrium, nonlinear damping), or forces too intricate for the core");
  return k;
}

}  // namespace

void to_json(nlohmann::json& j, const ModelCheck& c) {
  j = {{"name", c.name},
       {"assumption", c.assumption},
       {"applicable", c.applicable},
       {"passed", c.passed},
       {"warning", c.warning},
       {"statistic_name", c.statistic_name},
       {"statistic", finite_or_null(c.statistic)},
       {"p_value", finite_or_null(c.p_value)},
       {"alpha", finite_or_null(c.alpha)},
       {"effect_name", c.effect_name},
       {"effect", finite_or_null(c.effect)},
       {"effect_threshold", finite_or_null(c.effect_threshold)},
       {"detectable_effect", finite_or_null(c.detectable_effect)},
       {"sentence", c.sentence},
       {"details", c.details.is_null() ? nlohmann::json::object() : c.details}};
}

double student_t_two_sided_p(double t, double dof) {
  require(dof >= 1.0, "student_t_two_sided_p: need at least one degree of freedom");
  return 2.0 * upper_t_p(std::abs(t), dof);
}

ModelCheck amplitude_check(const CheckInput& in, const std::function<bool()>& should_stop) {
  require(in.map != nullptr, "amplitude_check: no map");
  require(!in.blocks.empty(), "amplitude_check: no blocks");
  const double c0 = in.map->damping_rate(in.theta).value_or(0.0);
  DampingProfile prof(*in.map, in.theta, in.damping_index, windows_from_trajectories(in.blocks, 1));
  const CommonRate fit = fit_common_rate(prof, c0, should_stop);
  return linear_damping_check(in, fit.c, common_rate_se(fit.bs), fit.bs);
}

std::vector<ModelCheck> check_model(const CheckInput& in,
                                    const std::function<bool()>& should_stop) {
  require(in.map != nullptr, "check_model: no map");
  require(!in.blocks.empty(), "check_model: no blocks");
  require(std::isfinite(in.time_scale) && in.time_scale > 0.0, "check_model: bad time scale");
  const double c0 = in.map->damping_rate(in.theta).value_or(0.0);
  DampingProfile prof(*in.map, in.theta, in.damping_index, windows_from_trajectories(in.blocks, 1));
  const CommonRate fit = fit_common_rate(prof, c0, should_stop);
  const double c = fit.c;
  const std::vector<BlockProfile>& bs = fit.bs;
  const double se = common_rate_se(bs);
  std::vector<ModelCheck> out;
  out.push_back(dissipation_check(in, c, se, prof.n_blocks()));
  ModelCheck one_rate = one_rate_check(in, prof, c, should_stop);
  ModelCheck linear = linear_damping_check(in, c, se, bs);
  if (!one_rate.passed && !linear.passed) {
    // Modes damped at different rates change the block rates too, as the faster modes die
    // out: the trend with amplitude is then explained, not a second finding.
    linear.applicable = false;
    linear.passed = true;
    linear.warning = false;
    linear.sentence =
        "not decided: with different rates per mode the block rates change as the "
        "faster modes die out (" +
        linear.sentence + ")";
  }
  out.push_back(std::move(linear));
  out.push_back(std::move(one_rate));
  out.push_back(residuals_check(in, bs));
  // A significant statistic is never "ok": below its size threshold it is a warning that
  // says so (linear_damping words its own, with the effect's interval).
  for (ModelCheck& k : out)
    if (k.applicable && k.passed && !k.warning && k.p_value < k.alpha) {
      k.warning = true;
      k.sentence = "significant but small (p = " + fmt(k.p_value, 2) + "; " + k.effect_name + " " +
                   fmt(k.effect, 3) + ", below the " + fmt(k.effect_threshold, 3) +
                   " that fails the check): " + k.sentence;
    }
  return out;
}

}  // namespace csympnet
