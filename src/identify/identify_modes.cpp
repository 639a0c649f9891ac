// The modes of the fitted map: natural frequencies and damping ratios from its linearisation at
// the equilibrium, with intervals from the same sandwich as γ̂'s (identify_stages.hpp,
// modal_analysis; docs/derivations.md, "Modes of the fitted map").
#include <algorithm>
#include <cmath>
#include <complex>
#include <functional>
#include <optional>
#include <vector>

#include <Eigen/Eigenvalues>

#include "csympnet/core/dense.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "damping_profile.hpp"
#include "identify_stages.hpp"

namespace csympnet::detail {

namespace {

using Complex = std::complex<double>;

double frequency_of(Complex s) {
  return std::abs(s);
}
double ratio_of(Complex s) {
  return -s.real() / std::abs(s);
}

// The continuous-time eigenvalues s = log(μ) / h of the map's oscillating modes (μ with
// positive imaginary part) at its fixed point, ascending in |s|; the fixed point in `z`. A
// point where the map moves by at most `tolerance` counts as the equilibrium: a fitted map
// whose true equilibria form a line (a free chain's translation) keeps a slight drift along it.
std::optional<std::vector<Complex>> mode_eigenvalues(const OneStepMap& map, const Vector& theta,
                                                     Vector& z, double h, double tolerance) {
  const FixedPoint fixed = nearest_fixed_point(map, theta, z, h);
  if (!(fixed.residual <= tolerance)) return std::nullopt;
  z = fixed.z;
  const dense::Eigensystem es = dense::eigensystem(map.jacobian(theta, z, h), false);
  if (!es.ok) return std::nullopt;
  std::vector<Complex> s;
  for (Index i = 0; i < es.values.size(); ++i) {
    const Complex mu = es.values(i);
    // An oscillation: an angle per step beyond rounding, and a decay slower than critical.
    const Complex x = std::log(mu) / h;
    if (std::arg(mu) > 1e-6 && ratio_of(x) < 0.999 && ratio_of(x) > -0.999) s.push_back(x);
  }
  std::sort(s.begin(), s.end(), [](Complex a, Complex b) { return std::abs(a) < std::abs(b); });
  return s;
}

// ∂ω_k/∂θ and ∂ζ_k/∂θ by central differences, each perturbed map's modes matched to the
// nearest of s; false when a perturbation loses a mode. Entries of `held` (θ indices) are not
// perturbed: their derivatives are 0 (the dry friction the modes are taken without).
bool mode_gradients(const OneStepMap& map, const Vector& theta, const Vector& z0, double h,
                    double tolerance, const std::vector<Complex>& s,
                    const std::function<bool()>& stop, const std::vector<Index>& held,
                    Matrix& d_freq, Matrix& d_ratio) {
  const Index p = theta.size(), m = static_cast<Index>(s.size());
  d_freq.resize(p, m);
  d_ratio.resize(p, m);
  Vector t = theta;
  for (Index j = 0; j < p; ++j) {
    if (stop && stop()) return false;
    if (std::find(held.begin(), held.end(), j) != held.end()) {
      d_freq.row(j).setZero();
      d_ratio.row(j).setZero();
      continue;
    }
    const double eps = 1e-6 * std::max(1.0, std::abs(theta(j)));
    std::vector<Complex> side[2];
    for (int k = 0; k < 2; ++k) {
      t(j) = theta(j) + (k == 0 ? eps : -eps);
      Vector z = z0;
      const std::optional<std::vector<Complex>> e = mode_eigenvalues(map, t, z, h, tolerance);
      if (!e || static_cast<Index>(e->size()) != m) return false;
      for (Complex target : s)  // the nearest perturbed eigenvalue
        side[k].push_back(*std::min_element(e->begin(), e->end(), [&](Complex a, Complex b) {
          return std::abs(a - target) < std::abs(b - target);
        }));
    }
    t(j) = theta(j);
    for (Index k = 0; k < m; ++k) {
      const auto ks = static_cast<std::size_t>(k);
      d_freq(j, k) = (frequency_of(side[0][ks]) - frequency_of(side[1][ks])) / (2.0 * eps);
      d_ratio(j, k) = (ratio_of(side[0][ks]) - ratio_of(side[1][ks])) / (2.0 * eps);
    }
  }
  return d_freq.allFinite() && d_ratio.allFinite();
}

}  // namespace

Modes modal_analysis(const OneStepMap& map, ConstParams theta_fitted, const WindowSet& train,
                     double time_scale, double level, const ModeIntervalInput& in) {
  Modes out;
  const Index n = train.size();
  if (n == 0) return out;
  std::vector<double> hs(train.h.row(0).data(), train.h.row(0).data() + n);
  std::nth_element(hs.begin(), hs.begin() + n / 2, hs.end());
  const double h = hs[static_cast<std::size_t>(n / 2)];
  Vector z = train.z0.rowwise().mean();
  // The equilibrium to 1e-3 of the data's typical motion over a window.
  const double tolerance = 1e-3 * (train.zm - train.z0).norm() / std::sqrt(static_cast<double>(n));
  // At an equilibrium Coulomb friction holds p in its stick band, where the map's derivative
  // in p is 0: there is nothing to linearise. The modes are those of the map without its dry
  // friction (the potential, the mass and the viscous rate: small oscillations as they would
  // be without the friction), and the note says so.
  Vector theta = theta_fitted;
  std::string friction_note;
  std::vector<Index> held;
  if (const auto* lib = dynamic_cast<const HamiltonianLibraryMap*>(&map))
    for (Index k = 0; k < static_cast<Index>(lib->dissipation().size()); ++k)
      if (lib->dissipation()[static_cast<std::size_t>(k)].kind == DissipationKind::kCoulomb) {
        theta(lib->dissipation_index(k)) = 0.0;
        held.push_back(lib->dissipation_index(k));
        friction_note =
            "the modes of the fitted map without its dry friction (Coulomb friction has no "
            "linearisation at rest)";
      }
  if (!friction_note.empty()) out.note = friction_note;
  const std::optional<std::vector<Complex>> s = mode_eigenvalues(map, theta, z, h, tolerance);
  const Index d = train.dim() / 2;
  if (!s) {
    out.note = "the fitted map has no equilibrium near the data: no modes";
    return out;
  }
  if (static_cast<Index>(s->size()) < d)
    out.note += (out.note.empty() ? "" : "; ") + std::to_string(d - static_cast<Index>(s->size())) +
                " of the " + std::to_string(d) +
                " modes do not oscillate at the equilibrium (overdamped, or no restoring force)";
  const double tau = time_scale;
  for (Complex x : *s) out.list.push_back({frequency_of(x) / tau, ratio_of(x), {}, {}});
  if (in.ne == nullptr || s->empty()) return out;
  Matrix d_freq, d_ratio;
  if (!mode_gradients(map, theta, z, h, tolerance, *s, in.should_stop, held, d_freq, d_ratio)) {
    if (in.should_stop && in.should_stop()) {
      out.stopped = true;  // interrupted: the modes without intervals
      return out;
    }
    out.note += (out.note.empty() ? "" : "; ") +
                std::string(
                    "a mode is lost under a small change of the parameters: no "
                    "intervals for the modes");
    return out;
  }
  const NormalEquations& ne = *in.ne;
  const auto interval_of = [&](const Vector& grad, double value, double unit) {
    if (!(grad.squaredNorm() > 0.0)) return std::optional<SandwichInterval>();
    SandwichInterval iv =
        sandwich_interval_of(ne.a, ne.g, ne.scores, grad, value, in.n_residuals, ne.cost,
                             in.residual_scale, in.data_scale, level, &ne.block_information);
    inflate_interval(iv, in.inflation);
    for (double* v : {&iv.gamma, &iv.low, &iv.high, &iv.std_error, &iv.sandwich, &iv.model_based,
                      &iv.optimisation, &iv.rounding})
      *v /= unit;
    return std::optional<SandwichInterval>(iv);
  };
  for (std::size_t k = 0; k < out.list.size(); ++k) {
    const Index kk = static_cast<Index>(k);
    out.list[k].frequency_interval = interval_of(d_freq.col(kk), frequency_of((*s)[k]), tau);
    out.list[k].damping_ratio_interval = interval_of(d_ratio.col(kk), ratio_of((*s)[k]), 1.0);
  }
  return out;
}

}  // namespace csympnet::detail
