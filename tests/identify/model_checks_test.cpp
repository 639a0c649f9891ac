// The checks of the model's assumptions (identify/model_checks.hpp) and the damping profile
// behind them (src/identify/damping_profile.hpp):
//  - the profile's residuals are the fit's balanced window residuals, at random parameters;
//  - its hand-written derivatives in C and c agree with central finite differences;
//  - calibration without training: with the exact core of a linear system the checks'
//    false alarms on valid noisy data are counted over hundreds of data sets, and their
//    detection of energy gain, dry friction and mode-dependent damping over dozens.
#include "csympnet/identify/model_checks.hpp"

#include <gtest/gtest.h>

#include <unsupported/Eigen/MatrixFunctions>

#include <cmath>
#include <optional>

#include "../../src/identify/damping_profile.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/models/model.hpp"
#include "csympnet/train/window_loss.hpp"

namespace csympnet {
namespace {

using detail::DampingBasis;
using detail::DampingProfile;

// S_a Ψ S_a with Ψ the exact symplectic core of the damped linear system dq/dt = p,
// dp/dt = −K q − γ0 p: Ψ_h = S_{a0}⁻¹ exp((G − γ0 P) h) S_{a0}⁻¹, a0 = e^{−γ0 h/2}. θ = (β),
// γ = |β|. At β = γ0 the map is the system's exact flow; for other β it is conformally
// symplectic with factor e^{−|β| h}. A stand-in for a perfectly fitted core.
class LinearFlowMap final : public OneStepMap {
 public:
  LinearFlowMap(Matrix k, double gamma0) : k_(std::move(k)), gamma0_(gamma0), d_(k_.rows()) {}
  std::string type() const override { return "linear-flow"; }
  Index dim() const override { return 2 * d_; }
  Index n_params() const override { return 1; }
  void init_params(Rng&, ParamsRef theta) const override { theta(0) = gamma0_; }
  Matrix step(double beta, double h) const {
    Matrix g = Matrix::Zero(2 * d_, 2 * d_);
    g.topRightCorner(d_, d_) = Matrix::Identity(d_, d_);
    g.bottomLeftCorner(d_, d_) = -k_;
    g.bottomRightCorner(d_, d_) = -gamma0_ * Matrix::Identity(d_, d_);
    const Matrix flow = (g * h).exp();
    Vector s = Vector::Ones(2 * d_);
    s.tail(d_).setConstant(std::exp(-0.5 * (std::abs(beta) - gamma0_) * h));
    return s.asDiagonal() * flow * s.asDiagonal();
  }
  Matrix forward(ConstParams theta, const Matrix& z, const Vector& h,
                 ForwardCache*) const override {
    Matrix out(z.rows(), z.cols());
    for (Index j = 0; j < z.cols(); ++j) out.col(j) = step(theta(0), h(j)) * z.col(j);
    return out;
  }
  void backward(ConstParams, const ForwardCache&, const Matrix&, ParamsRef,
                Matrix*) const override {
    throw Error("LinearFlowMap: no backward pass");
  }
  Matrix jacobian(ConstParams theta, const Vector&, double h) const override {
    return step(theta(0), h);
  }
  std::optional<double> damping_rate(ConstParams theta) const override {
    return std::abs(theta(0));
  }
  std::optional<Index> damping_param_index() const override { return 0; }
  nlohmann::json hyperparams() const override { return {{"type", type()}}; }

 private:
  Matrix k_;
  double gamma0_;
  Index d_;
};

// A damping force: the rate of change of p from dissipation and forcing, given (t, q, p).
using DissipationField = std::function<Vector(double, const Vector&, const Vector&)>;

// RK4 of dq/dt = p, dp/dt = −K q + f(t, q, p), 50 substeps per sample step.
Trajectory integrate(const Matrix& k, const DissipationField& f, const Vector& z0, double h,
                     Index points) {
  const Index d = k.rows();
  Trajectory t;
  t.t.resize(points);
  t.z.resize(2 * d, points);
  t.t(0) = 0.0;
  t.z.col(0) = z0;
  const auto rhs = [&](double time, const Vector& z) {
    Vector out(2 * d);
    out.head(d) = z.tail(d);
    out.tail(d) = -k * z.head(d) + f(time, z.head(d), z.tail(d));
    return out;
  };
  Vector z = z0;
  double time = 0.0;
  const int sub = 50;
  const double dt = h / sub;
  for (Index n = 1; n < points; ++n) {
    for (int s = 0; s < sub; ++s) {
      const Vector k1 = rhs(time, z), k2 = rhs(time + dt / 2, z + dt / 2 * k1),
                   k3 = rhs(time + dt / 2, z + dt / 2 * k2), k4 = rhs(time + dt, z + dt * k3);
      z += dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
      time += dt;
    }
    t.t(n) = static_cast<double>(n) * h;
    t.z.col(n) = z;
  }
  return t;
}

// One long record cut into `blocks` segments (as identify's blocks), with noise sigma times
// each coordinate's spread.
std::vector<Trajectory> blocks_of(const Trajectory& t, int blocks, double sigma, Rng& rng) {
  Trajectory noisy = t;
  for (Index i = 0; i < t.z.rows(); ++i) {
    const double sd = std::sqrt((t.z.row(i).array() - t.z.row(i).mean()).square().mean());
    for (Index j = 0; j < t.z.cols(); ++j) noisy.z(i, j) += sigma * sd * rng.normal();
  }
  std::vector<Trajectory> out;
  const Index steps = t.t.size() - 1;
  for (int b = 0; b < blocks; ++b) {
    const Index a = steps * b / blocks, e = steps * (b + 1) / blocks;
    Trajectory s;
    s.t = noisy.t.segment(a, e - a + 1);
    s.z = noisy.z.middleCols(a, e - a + 1);
    out.push_back(s);
  }
  return out;
}

Matrix chain_stiffness(Index d) {
  Matrix k = 2.0 * Matrix::Identity(d, d);
  for (Index i = 0; i + 1 < d; ++i) k(i, i + 1) = k(i + 1, i) = -1.0;
  return k;
}

std::vector<ModelCheck> run(const Matrix& k, double gamma_core, std::vector<Trajectory> blocks) {
  LinearFlowMap map(k, gamma_core);
  CheckInput in;
  in.map = &map;
  in.theta = Vector::Constant(1, gamma_core);
  in.damping_index = 0;
  in.blocks = std::move(blocks);
  return check_model(in);
}

const ModelCheck& by_name(const std::vector<ModelCheck>& c, const std::string& name) {
  for (const ModelCheck& k : c)
    if (k.name == name) return k;
  throw Error("no check " + name);
}

TEST(DampingProfile, ResidualsAreTheFitsBalancedWindowResidualsAtRandomParameters) {
  for (int trial = 0; trial < 4; ++trial) {
    Rng rng(trial, "profile-residuals");
    const Index d = 1 + trial % 3;
    nlohmann::json spec = {
        {"type", "csympnet"},
        {"d", d},
        {"core", trial % 2 == 0 ? nlohmann::json{{"type", "la"}, {"layers", 2}, {"sublayers", 2}}
                                : nlohmann::json{{"type", "g"}, {"layers", 2}, {"width", 4}}},
        {"beta_init", 0.3}};
    if (d > 1) spec["dof_scales"] = "learned";
    Model m = make_model(spec);
    Vector theta(m.n_params());
    m.init_params(rng, theta);
    theta += 0.1 * rng.uniform_vector(theta.size(), -1.0, 1.0);
    std::vector<Trajectory> trajs;
    for (int b = 0; b < 3; ++b) {
      Trajectory t;
      t.t = Vector::LinSpaced(6, 0.0, 0.5) + 0.01 * rng.uniform_vector(6, 0.0, 1.0);
      t.z = Matrix::Random(2 * d, 6);
      trajs.push_back(t);
    }
    const WindowSet w = windows_from_trajectories(trajs, 1);
    const Index bi = *m.map->damping_param_index();
    DampingProfile prof(*m.map, theta, bi, w);
    const Vector want = window_residuals(*m.map, theta, w, true);
    const Matrix got = prof.residuals(std::abs(theta(bi)));
    const Vector flat = Eigen::Map<const Vector>(got.data(), got.size());
    EXPECT_LT((flat - want).cwiseAbs().maxCoeff(), 1e-12 * (1.0 + want.cwiseAbs().maxCoeff()))
        << "trial " << trial;
  }
}

// r(C) = Ψ(S_C z0) − S_C⁻¹ z1 computed directly with matrix exponentials.
Vector residual_with_matrix(const OneStepMap& map, const Vector& core_theta, const Matrix& c,
                            const Vector& z0, const Vector& z1, double h) {
  const Index d = c.rows();
  Vector x = z0, y = z1;
  x.tail(d) = (-0.5 * h * c).exp() * z0.tail(d);
  y.tail(d) = (0.5 * h * c).exp() * z1.tail(d);
  return map.apply(core_theta, x, Vector::Constant(1, h)).col(0) - y;
}

// The core's p-Jacobian comes from its Jacobian (a neural core) or from forward-mode tangents
// (the library core): both against central differences.
TEST(DampingProfile, DerivativesInTheDampingMatrixMatchFiniteDifferences) {
  for (int trial = 0; trial < 6; ++trial) {
    Rng rng(trial, "profile-derivative");
    const Index d = 2 + trial % 2;
    const bool library = trial >= 3;
    nlohmann::json terms = {"(q1-q2)^4", "sin(q1)", "q2"};
    for (Index i = 1; i <= d; ++i) terms.push_back("q" + std::to_string(i) + "^2");
    Model m = make_model(
        library
            ? nlohmann::json{{"type", "csympnet"},
                             {"d", d},
                             {"core", {{"type", "library"}, {"mass", "full"}, {"terms", terms}}},
                             {"beta_init", 0.2}}
            : nlohmann::json{{"type", "csympnet"},
                             {"d", d},
                             {"core", {{"type", "g"}, {"layers", 2}, {"width", 5}}},
                             {"beta_init", 0.2},
                             {"dof_scales", "learned"}});
    ASSERT_EQ(m.map->has_step_tangents(), library);
    Vector theta(m.n_params());
    m.init_params(rng, theta);
    theta += 0.2 * rng.uniform_vector(theta.size(), -1.0, 1.0);
    Trajectory t;
    t.t = Vector::LinSpaced(4, 0.0, 0.3);
    t.z = Matrix::Random(2 * d, 4);
    const WindowSet w = windows_from_trajectories({t}, 1);
    const Index bi = *m.map->damping_param_index();
    DampingProfile prof(*m.map, theta, bi, w);
    Vector core = theta;
    core(bi) = 0.0;
    const double c = rng.uniform(-0.5, 0.5);
    const double eps = 1e-6;
    const Matrix random_modes = Matrix::Identity(d, d) + 0.3 * Matrix::Random(d, d);
    for (const DampingBasis& f :
         {detail::full_damping_basis(d), detail::coordinate_damping_basis(d),
          detail::modal_damping_basis(random_modes)}) {
      for (Index k = 0; k < w.size(); ++k) {
        const Matrix got = prof.entry_jacobian(c, k, f);
        const Index ne = f.size();
        for (Index e = 0; e < ne; ++e) {
          Vector delta = Vector::Zero(ne);
          delta(e) = eps;
          const Vector plus = residual_with_matrix(*m.map, core, f.matrix(c, delta), w.z0.col(k),
                                                   w.zm.col(k), w.h(0, k));
          const Vector minus = residual_with_matrix(*m.map, core, f.matrix(c, -delta), w.z0.col(k),
                                                    w.zm.col(k), w.h(0, k));
          const Vector fd = (plus - minus) / (2 * eps);
          EXPECT_LT((got.col(e) - fd).cwiseAbs().maxCoeff(),
                    1e-7 * (1.0 + fd.cwiseAbs().maxCoeff()))
              << "trial " << trial << " window " << k << " entry " << e;
        }
        const Vector fd_rate =
            (residual_with_matrix(*m.map, core, (c + eps) * Matrix::Identity(d, d), w.z0.col(k),
                                  w.zm.col(k), w.h(0, k)) -
             residual_with_matrix(*m.map, core, (c - eps) * Matrix::Identity(d, d), w.z0.col(k),
                                  w.zm.col(k), w.h(0, k))) /
            (2 * eps);
        EXPECT_LT((prof.rate_jacobian(c, k) - fd_rate).cwiseAbs().maxCoeff(),
                  1e-7 * (1.0 + fd_rate.cwiseAbs().maxCoeff()));
      }
    }
  }
}

// A wrong derivative is caught: the same comparison with the p1 term dropped fails.
TEST(DampingProfile, TheFiniteDifferenceComparisonCatchesAPlantedError) {
  Rng rng(7, "profile-planted");
  const Matrix k = chain_stiffness(2);
  LinearFlowMap map(k, 0.1);
  Trajectory t;
  t.t = Vector::LinSpaced(3, 0.0, 0.2);
  t.z = Matrix::Random(4, 3);
  const WindowSet w = windows_from_trajectories({t}, 1);
  DampingProfile prof(map, Vector::Constant(1, 0.1), 0, w);
  const Vector core = Vector::Zero(1);
  const double eps = 1e-6, c = 0.1;
  Vector got = prof.rate_jacobian(c, 0);
  const double h = w.h(0, 0);
  got.tail(2) -= -0.5 * h * w.zm.col(0).tail(2) / std::exp(-0.5 * c * h);  // the planted error
  const Vector fd = (residual_with_matrix(map, core, (c + eps) * Matrix::Identity(2, 2),
                                          w.z0.col(0), w.zm.col(0), h) -
                     residual_with_matrix(map, core, (c - eps) * Matrix::Identity(2, 2),
                                          w.z0.col(0), w.zm.col(0), h)) /
                    (2 * eps);
  EXPECT_GT((got - fd).cwiseAbs().maxCoeff(), 1e-3);
}

// Valid data: a damped linear oscillator (d = 1) or chain (d = 2, 3), one long noisy record
// in 20 blocks, the exact core. Each check's false alarms over 300 data sets must stay within
// what its thresholds allow: at most 3% for each, 5% for all together (a binomial count of
// 15 of 300 is 5%; the thresholds aim at about 1% each).
TEST(ModelChecks, FalseAlarmsOnValidDataAreRare) {
  const int cases = 300;
  std::map<std::string, int> failed, warned;
  int any = 0;
  for (int n = 0; n < cases; ++n) {
    Rng rng(n, "checks-valid");
    const Index d = 1 + n % 3;
    const Matrix k = d == 1 ? Matrix::Identity(1, 1) : chain_stiffness(d);
    const double gamma = std::exp(rng.uniform(std::log(0.003), std::log(0.3)));
    const double sigma =
        std::vector<double>{0.0, 1e-3, 1e-2, 5e-2}[static_cast<std::size_t>(n % 4)];
    const Vector z0 = rng.uniform_vector(2 * d, -1.0, 1.0);
    const DissipationField f = [gamma](double, const Vector&, const Vector& p) -> Vector {
      return -gamma * p;
    };
    const Trajectory t = integrate(k, f, z0, 0.25, 400);
    const std::vector<ModelCheck> c = run(k, gamma, blocks_of(t, 20, sigma, rng));
    bool one = false;
    for (const ModelCheck& x : c) {
      if (!x.passed) {
        ++failed[x.name];
        one = true;
      }
      if (x.warning) ++warned[x.name];  // significant but small: a warning, not a failure
    }
    any += one ? 1 : 0;
  }
  for (const auto& [name, count] : failed) EXPECT_LE(count, cases * 3 / 100) << name;
  EXPECT_LE(any, cases * 5 / 100);
  // linear_damping tests at 0.01 two-sided, and the friction selection of `fit` relies on
  // that test. Measured (2026-11-29): significant on 12 of these 300 valid records (4%, so
  // its t test is anti-conservative by about 4x); bounded here so that it cannot drift
  // further unseen. The one_rate and residuals tests at 0.001 are significant far more often
  // (53 and 43 of 300: their p-values are not calibrated, their size thresholds protect the
  // verdict); they are printed, and docs/identification.md reports them.
  EXPECT_LE(warned["linear_damping"] + failed["linear_damping"], cases * 5 / 100);
  std::printf("false alarms over %d valid data sets: any %d", cases, any);
  for (const auto& [name, count] : failed) std::printf(", %s %d", name.c_str(), count);
  std::printf("; warnings");
  for (const auto& [name, count] : warned) std::printf(", %s %d", name.c_str(), count);
  std::printf("\n");
}

// Passed checks in plain words: the amplitude check states the change of the rate with its
// interval ("changes by +3% [-20%, +26%]"), and the dissipation check points at γ̂'s interval
// rather than printing a second one for the same rate.
TEST(ModelChecks, PassedChecksSayTheirFindingInPlainWords) {
  Rng rng(7, "checks-words");
  const Matrix k = Matrix::Identity(1, 1);
  const double gamma = 0.1;
  const DissipationField f = [gamma](double, const Vector&, const Vector& p) -> Vector {
    return -gamma * p;
  };
  Vector z0(2);
  z0 << 1.0, 0.0;
  const Trajectory t = integrate(k, f, z0, 0.25, 400);
  const std::vector<ModelCheck> c = run(k, gamma, blocks_of(t, 20, 1e-3, rng));
  const ModelCheck& g = by_name(c, "dissipation");
  ASSERT_TRUE(g.passed) << g.sentence;
  EXPECT_NE(g.sentence.find("gamma_hat's"), std::string::npos) << g.sentence;
  EXPECT_EQ(g.sentence.find('['), std::string::npos) << g.sentence;
  EXPECT_TRUE(g.details.contains("interval"));  // still in the report
  const ModelCheck& l = by_name(c, "linear_damping");
  ASSERT_TRUE(l.passed) << l.sentence;
  if (l.applicable) {
    EXPECT_NE(l.sentence.find("the rate changes by "), std::string::npos) << l.sentence;
    EXPECT_EQ(l.sentence.find("beyond a change"), std::string::npos) << l.sentence;
    EXPECT_NE(l.sentence.find("%, "), std::string::npos) << l.sentence;  // the interval
  }
}

TEST(ModelChecks, EnergyGainIsNamedWithItsRate) {
  int named = 0;
  for (int n = 0; n < 40; ++n) {
    Rng rng(n, "checks-growth");
    const Matrix k = Matrix::Identity(1, 1);
    const double gamma = -0.05;
    const DissipationField f = [gamma](double, const Vector&, const Vector& p) -> Vector {
      return -gamma * p;
    };
    const Trajectory t = integrate(k, f, rng.uniform_vector(2, -1.0, 1.0), 0.25, 300);
    // The core as a fit with γ̂ = |β| ≥ 0 leaves it: the conservative part, β near 0.
    const std::vector<ModelCheck> c = run(k, 1e-6, blocks_of(t, 20, 1e-2, rng));
    const ModelCheck& g = by_name(c, "dissipation");
    if (!g.passed && g.sentence.find("grows") != std::string::npos &&
        std::abs(g.effect - 0.05) < 0.01)
      ++named;
  }
  EXPECT_GE(named, 38);
  std::printf("energy gain named with its rate: %d of 40\n", named);
}

// Dry friction as half of the dissipation at the start: the block rates rise as the
// amplitude falls.
TEST(ModelChecks, DryFrictionIsDetected) {
  int detected = 0;
  const int cases = 40;
  for (int n = 0; n < cases; ++n) {
    Rng rng(n, "checks-coulomb");
    const Matrix k = Matrix::Identity(1, 1);
    const double gv = 0.05, a0 = 1.0;
    const double mu = gv * M_PI * a0 / 4.0;  // γ_c = 4μ/(π ω A0) = γ_v: half at the start
    const DissipationField f = [gv, mu](double, const Vector&, const Vector& p) -> Vector {
      return -gv * p - mu * (p / 1e-3).array().tanh().matrix();
    };
    Vector z0(2);
    z0 << a0, 0.0;
    const Trajectory t = integrate(k, f, z0, 0.3, 600);
    const std::vector<ModelCheck> c = run(k, 2 * gv, blocks_of(t, 20, 1e-2, rng));
    const ModelCheck& l = by_name(c, "linear_damping");
    if (!l.passed && l.sentence.find("Coulomb") != std::string::npos) ++detected;
  }
  EXPECT_GE(detected, cases * 9 / 10);
  std::printf("dry friction (half the dissipation) detected: %d of %d\n", detected, cases);
}

// Pairs (each its own block, as a pairs file gives) at amplitudes from 0.2 to 2: the rate per
// pair still shows dry friction's trend with amplitude.
TEST(ModelChecks, DryFrictionIsDetectedInPairs) {
  int detected = 0;
  const int cases = 20;
  for (int n = 0; n < cases; ++n) {
    Rng rng(n, "checks-coulomb-pairs");
    const Matrix k = Matrix::Identity(1, 1);
    const double gv = 0.05, mu = gv * M_PI / 4.0;
    const DissipationField f = [gv, mu](double, const Vector&, const Vector& p) -> Vector {
      return -gv * p - mu * (p / 1e-3).array().tanh().matrix();
    };
    std::vector<Trajectory> pairs;
    for (int j = 0; j < 400; ++j) {
      const double amp = std::exp(rng.uniform(std::log(0.2), std::log(2.0)));
      const double phase = rng.uniform(0.0, 2.0 * M_PI);
      Vector z0(2);
      z0 << amp * std::cos(phase), amp * std::sin(phase);
      Trajectory t = integrate(k, f, z0, 0.3, 2);
      for (Index i = 0; i < t.z.size(); ++i) t.z.data()[i] += 0.005 * rng.normal();
      pairs.push_back(t);
    }
    const std::vector<ModelCheck> checks = run(k, 2 * gv, pairs);
    const ModelCheck& l = by_name(checks, "linear_damping");
    if (!l.passed && l.sentence.find("Coulomb") != std::string::npos) ++detected;
  }
  EXPECT_GE(detected, cases * 9 / 10);
  std::printf("dry friction detected in pairs: %d of %d\n", detected, cases);
}

// Two modes of a chain damped at rates in ratio 3: the full damping matrix predicts held-out
// blocks better than one rate, and its eigenvalues are the modal rates.
TEST(ModelChecks, ModeDependentDampingIsDetectedWithTheRates) {
  int detected = 0;
  const int cases = 40;
  const Matrix k = chain_stiffness(2);
  Eigen::SelfAdjointEigenSolver<Matrix> es(k);
  const Matrix v = es.eigenvectors();
  for (int n = 0; n < cases; ++n) {
    Rng rng(n, "checks-modes");
    Vector rates(2);
    rates << 0.05, 0.15;
    const Matrix c = v * rates.asDiagonal() * v.transpose();
    const DissipationField f = [c](double, const Vector&, const Vector& p) -> Vector {
      return -c * p;
    };
    const Trajectory t = integrate(k, f, rng.uniform_vector(4, -1.0, 1.0), 0.25, 600);
    const std::vector<ModelCheck> checks = run(k, 0.1, blocks_of(t, 20, 1e-2, rng));
    const ModelCheck& o = by_name(checks, "one_rate");
    if (o.passed) continue;
    const auto& r = o.details.at("rates");
    const double lo = r[0].at("rate").get<double>(), hi = r[1].at("rate").get<double>();
    if (std::abs(lo - 0.05) < 0.02 && std::abs(hi - 0.15) < 0.03) ++detected;
  }
  EXPECT_GE(detected, cases * 9 / 10);
  std::printf("rates per mode in ratio 3 detected and recovered: %d of %d\n", detected, cases);
}

// Four modes of a chain with rates spread by 3 (γ, 3^{1/3} γ, 3^{2/3} γ, 3γ in a random
// order), in 12 blocks: too few for a full 4 × 4 matrix (15 constraints), so only a rate per
// mode of the core's linearisation can see it; the rates come back in the modes' order.
TEST(ModelChecks, ModeDependentDampingIsDetectedPerModeWhenAFullMatrixIsTooMuch) {
  int detected = 0, modal = 0;
  const int cases = 20;
  const Matrix k = chain_stiffness(4);
  Eigen::SelfAdjointEigenSolver<Matrix> es(k);  // ascending frequencies
  const Matrix v = es.eigenvectors();
  for (int n = 0; n < cases; ++n) {
    Rng rng(n, "checks-modes-4");
    Vector rates(4);
    for (Index i = 0; i < 4; ++i) rates(i) = 0.05 * std::pow(3.0, static_cast<double>(i) / 3.0);
    for (Index i = 3; i > 0; --i)
      std::swap(rates(i), rates(std::min<Index>(
                              i, static_cast<Index>(rng.uniform() * static_cast<double>(i + 1)))));
    const Matrix c = v * rates.asDiagonal() * v.transpose();
    const DissipationField f = [c](double, const Vector&, const Vector& p) -> Vector {
      return -c * p;
    };
    const Trajectory t = integrate(k, f, rng.uniform_vector(8, -1.0, 1.0), 0.25, 600);
    const std::vector<ModelCheck> checks = run(k, rates.mean(), blocks_of(t, 12, 1e-2, rng));
    const ModelCheck& o = by_name(checks, "one_rate");
    if (o.details.value("freedom", std::string()).find("mode") == std::string::npos) continue;
    ++modal;
    if (o.passed) continue;
    const auto& r = o.details.at("rates");
    bool recovered = true;
    for (Index i = 0; i < 4; ++i) {
      const double got = r[static_cast<std::size_t>(i)].at("rate").get<double>();
      recovered = recovered && std::abs(got - rates(i)) < 0.2 * rates(i);
      const double freq = r[static_cast<std::size_t>(i)].at("angular_frequency").get<double>();
      EXPECT_NEAR(freq, std::sqrt(es.eigenvalues()(i)), 1e-2) << "case " << n << " mode " << i;
    }
    if (recovered) ++detected;
  }
  EXPECT_EQ(modal, cases);
  EXPECT_GE(detected, cases * 9 / 10);
  std::printf("four rates per mode in ratio 3 detected and recovered: %d of %d\n", detected, cases);
}

// The core's linear modes at random stiffness and mass-free chains: the frequencies are the
// square roots of K's eigenvalues (of the damped flow's, as the exact core carries γ0 in its
// conformal scaling) and the momentum directions K's eigenvectors; the modal basis sums to
// the identity along its common direction.
TEST(DampingProfile, LinearModesAreTheCoresNormalModesAtRandomStiffness) {
  int tested = 0;
  for (int trial = 0; trial < 10; ++trial) {
    Rng rng(trial, "profile-modes");
    const Index d = 2 + trial % 3;
    const Matrix a = Matrix::Random(d, d);
    const Matrix k = a * a.transpose() + 0.5 * Matrix::Identity(d, d);
    LinearFlowMap map(k, 0.0);
    Trajectory t;
    t.t = Vector::LinSpaced(6, 0.0, 0.1);
    t.z = Matrix::Random(2 * d, 6);
    DampingProfile prof(map, Vector::Constant(1, 0.0), 0, windows_from_trajectories({t}, 1));
    const std::optional<detail::LinearModes> modes = prof.linear_modes();
    Eigen::SelfAdjointEigenSolver<Matrix> es(k);
    const Vector freq = es.eigenvalues().cwiseSqrt();
    bool distinct = true;
    for (Index i = 1; i < d; ++i) distinct = distinct && freq(i) - freq(i - 1) > 0.03 * freq(i);
    if (!distinct) continue;
    ++tested;
    ASSERT_TRUE(modes.has_value()) << "trial " << trial;
    for (Index i = 0; i < d; ++i) {
      EXPECT_NEAR(modes->frequency(i), freq(i), 1e-8 * freq(i)) << "trial " << trial;
      const double align = std::abs(modes->p.col(i).normalized().dot(es.eigenvectors().col(i)));
      EXPECT_NEAR(align, 1.0, 1e-8) << "trial " << trial << " mode " << i;
    }
    const DampingBasis b = detail::modal_damping_basis(modes->p);
    EXPECT_LT((b.matrix(0.0, b.common) - Matrix::Identity(d, d)).norm(), 1e-10);
  }
  EXPECT_GE(tested, 6);  // most random stiffnesses have distinct frequencies
}

TEST(ModelChecks, OneDegreeOfFreedomHasOneModeAndShortDataAreUntestable) {
  Rng rng(3, "checks-short");
  const Matrix k = Matrix::Identity(1, 1);
  const DissipationField f = [](double, const Vector&, const Vector& p) -> Vector {
    return -0.1 * p;
  };
  const Trajectory t = integrate(k, f, rng.uniform_vector(2, -1.0, 1.0), 0.25, 12);
  const std::vector<ModelCheck> c = run(k, 0.1, blocks_of(t, 3, 0.0, rng));
  EXPECT_FALSE(by_name(c, "one_rate").applicable);
  EXPECT_FALSE(by_name(c, "linear_damping").applicable);
  for (const ModelCheck& x : c) EXPECT_TRUE(x.passed) << x.name;  // untestable is not a failure
}

}  // namespace
}  // namespace csympnet
