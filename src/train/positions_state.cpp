#include "csympnet/train/positions_state.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "csympnet/core/error.hpp"
#include "csympnet/train/shooting.hpp"

namespace csympnet {

namespace {

// The rms distance of the positions from their mean, over every coordinate.
double spread_of(const Matrix& q) {
  if (q.cols() == 0) return 0.0;
  const Vector mean = q.rowwise().mean();
  return std::sqrt((q.colwise() - mean).squaredNorm() / static_cast<double>(q.size()));
}

// The noise in the positions as their fourth differences show it: for white noise of sd σ,
// Δ⁴q has variance 70σ²; a motion sampled 10 times per period adds (ωh)⁴ ≈ 0.16 of its
// amplitude, 25 times per period 0.004. An upper estimate of σ, 0 below 5 samples.
double noise_from_differences(const Matrix& q) {
  if (q.cols() < 5) return 0.0;
  double sum = 0.0;
  Index n = 0;
  for (Index i = 0; i < q.rows(); ++i)
    for (Index k = 4; k < q.cols(); ++k) {
      const double d4 =
          q(i, k) - 4.0 * q(i, k - 1) + 6.0 * q(i, k - 2) - 4.0 * q(i, k - 3) + q(i, k - 4);
      sum += d4 * d4;
      ++n;
    }
  return std::sqrt(sum / (70.0 * static_cast<double>(n)));
}

}  // namespace

void check_positions_window(const Matrix& q, const Vector& t, const std::string& what) {
  require(q.cols() == t.size() && t.size() >= 2,
          [&] { return what + ": expected at least 2 positions, each with its time"; });
  std::vector<double> steps;
  for (Index k = 1; k < t.size(); ++k) {
    const double s = t(k) - t(k - 1);
    if (!(std::isfinite(s) && s > 0.0))
      throw Error(what + ": the times " + number_text(t(k - 1)) + " and " + number_text(t(k)) +
                  " do not increase; expected strictly increasing times");
    steps.push_back(s);
  }
  std::vector<double> sorted = steps;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2),
                   sorted.end());
  const double median = sorted[sorted.size() / 2];
  for (std::size_t k = 0; k < steps.size(); ++k)
    if (steps[k] > kWindowGapFactor * median)
      throw Error(what + ": a gap from t = " + number_text(t(static_cast<Index>(k))) +
                  " to t = " + number_text(t(static_cast<Index>(k) + 1)) + " (a step of " +
                  number_text(steps[k]) + ", more than " + number_text(kWindowGapFactor) +
                  " times the median step " + number_text(median) +
                  "); expected a window without gaps: keep the positions after the gap");
}

void check_state_fit(const Matrix& q, const Vector& z, double rms, const std::string& what,
                     const Matrix* white_residuals) {
  const double spread = spread_of(q);
  // A window where the motion has decayed to a few times the noise: a state that misses it by
  // the noise explains it (a 2-cart record's last 10 s, 0.35 px rms of 0.4 px noise in a
  // spread of 2.6 px, was refused).
  const double noise = noise_from_differences(q);
  const bool finite_state = z.allFinite();
  const double near_noise =
      std::max(kStateFitMaxRelativeRms * spread, kStateFitMaxNoiseMultiple * noise);
  // Residuals that look like white noise: their own fourth differences see as much noise as
  // their rms (a smooth misfit is suppressed by differencing and shows far less).
  const bool white = white_residuals != nullptr && white_residuals->cols() >= 5 &&
                     std::isfinite(rms) &&
                     kStateFitMaxNoiseMultiple * noise_from_differences(*white_residuals) >= rms;
  const double limit = white ? near_noise : std::min(kStateFitNoiseCap * spread, near_noise);
  if (!std::isfinite(rms) || !finite_state || rms > limit)
    throw Error(
        what + ": the model does not explain this window of positions: the fitted motion " +
        (finite_state && std::isfinite(rms)
             ? "misses the positions by " + number_text(rms) + " rms, more than " +
                   number_text(100.0 * kStateFitMaxRelativeRms) + "% of their spread " +
                   number_text(spread) +
                   (limit > kStateFitMaxRelativeRms * spread
                        ? " and more than " + number_text(limit) + " (" +
                              number_text(kStateFitMaxNoiseMultiple) + " times their noise " +
                              number_text(noise) + " from their fourth differences, at most " +
                              number_text(100.0 * kStateFitNoiseCap) + "% of the spread)"
                        : std::string())
             : std::string("is not finite")) +
        "; expected a recent window of the system the model was fitted to, in the same units "
        "and sampled as the data it was fitted on (no forecast is made from such a state)");
}

Vector checked_state_from_positions(const OneStepMap& map, ConstParams theta, const Matrix& q,
                                    const Vector& t, double* rms, const std::string& what,
                                    const Matrix& u) {
  check_positions_window(q, t, what);
  double r = 0.0;
  Matrix residuals;
  const Vector z = state_from_positions(map, theta, q, t, &r, u, &residuals);
  check_state_fit(q, z, r, what, u.rows() > 0 ? &residuals : nullptr);
  if (rms != nullptr) *rms = r;
  return z;
}

}  // namespace csympnet
