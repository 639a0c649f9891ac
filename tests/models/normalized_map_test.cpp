// The change of units (data/normalization.hpp) and the map in the user's units
// (models/normalized_map.hpp): exact structure at random parameters and random units, the
// derivatives against central differences, and the model-file round trip.
#include "csympnet/models/normalized_map.hpp"
#include "csympnet/models/dof_scaled_map.hpp"

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "csympnet/data/normalization.hpp"
#include "support/gradient_check.hpp"
#include "support/model_fixtures.hpp"

namespace csympnet {
namespace {

using testing::random_theta;

// Random units: per-dof q scales α_i, β_i = c / α_i, shifts and a time scale, each over four
// orders of magnitude.
Normalization random_units(Index d, Rng& rng) {
  Normalization n;
  n.q_shift = rng.normal_matrix(d, 1, 100.0);
  n.q_scale.resize(d);
  n.p_scale.resize(d);
  const double c = std::pow(10.0, rng.uniform(-2.0, 2.0));
  for (Index i = 0; i < d; ++i) {
    n.q_scale(i) = std::pow(10.0, rng.uniform(-2.0, 2.0));
    n.p_scale(i) = c / n.q_scale(i);
  }
  n.time_scale = std::pow(10.0, rng.uniform(-3.0, 3.0));
  return n;
}

const char* kSpecs[] = {
    R"({"type":"csympnet","d":1,"core":{"type":"la","layers":3,"sublayers":4}})",
    R"({"type":"csympnet","d":3,"core":{"type":"g","layers":3,"width":6}})",
    R"({"type":"csympnet","d":2,"core":{"type":"la","layers":2,"sublayers":3,"step_terms":2}})"};

TEST(NormalizedMap, IsExactlyConformallySymplecticInTheUsersUnits) {
  // DΦᵀ J DΦ = e^{−γh} J with γ = γ̂/τ, at random parameters, units, points and steps.
  for (const char* s : kSpecs) {
    Rng rng(31, s);
    for (int rep = 0; rep < 20; ++rep) {
      nlohmann::json spec = nlohmann::json::parse(s);
      const Index d = spec["d"].get<Index>();
      const Normalization n = random_units(d, rng);
      spec["normalization"] = n;
      const auto map = make_one_step_map(spec);
      const Vector theta = random_theta(*map, rng, 0.5, rng.uniform(0.05, 2.0));
      const Vector z = n.from_normal(rng.normal_matrix(2 * d, 1, 1.0));
      const double h = n.time_scale * rng.uniform(0.05, 0.3);
      const Matrix jac = map->jacobian(theta, z, h);
      const double lambda = std::exp(-*map->damping_rate(theta) * h);
      // Nᵀ J N = J / c makes DΦᵀ J DΦ = λ J exactly; in floating point to ε ‖DΦ‖².
      const Matrix jj = canonical_j(d);
      EXPECT_LE((jac.transpose() * jj * jac - lambda * jj).norm(),
                1e-13 * std::max(1.0, jac.squaredNorm()))
          << s;
      EXPECT_NEAR(*map->damping_rate(theta),
                  std::abs(theta(*map->damping_param_index())) / n.time_scale,
                  1e-15 * *map->damping_rate(theta));
    }
  }
}

TEST(NormalizedMap, DerivativesMatchFiniteDifferences) {
  for (const char* s : kSpecs) {
    Rng rng(32, s);
    nlohmann::json spec = nlohmann::json::parse(s);
    const Index d = spec["d"].get<Index>();
    Normalization n;  // moderate units: finite differences need comparable magnitudes
    n.q_shift = rng.normal_matrix(d, 1, 1.0);
    n.q_scale = rng.uniform_vector(d, 0.5, 2.0);
    n.p_scale = 1.3 * n.q_scale.cwiseInverse();
    n.time_scale = 0.7;
    spec["normalization"] = n;
    const auto map = make_one_step_map(spec);
    const Vector theta = random_theta(*map, rng, 0.3, 0.4);
    const Matrix z = n.from_normal(rng.normal_matrix(2 * d, 3, 1.0));
    const Vector h = rng.uniform_vector(3, 0.05, 0.2);
    const auto check = testing::check_one_step_map(*map, theta, z, h, rng);
    EXPECT_TRUE(check.ok()) << s << "\n" << check.report();
  }
}

TEST(NormalizedMap, IsTheInnerMapConjugatedByTheUnits) {
  nlohmann::json spec = nlohmann::json::parse(kSpecs[1]);
  const auto inner = make_one_step_map(spec);
  Rng rng(33, "conjugate");
  const Normalization n = random_units(3, rng);
  spec["normalization"] = n;
  const auto map = make_one_step_map(spec);
  const Vector theta = random_theta(*map, rng, 0.4, 0.3);
  const Matrix zn = rng.normal_matrix(6, 4, 1.0);
  const Vector hn = rng.uniform_vector(4, 0.05, 0.2);
  const Matrix direct = inner->apply(theta, zn, hn);
  const Matrix via = n.to_normal(map->apply(theta, n.from_normal(zn), hn * n.time_scale));
  EXPECT_LE((direct - via).norm(), 1e-9 * direct.norm());
  // The spec round-trips through hyperparams, normalisation included.
  EXPECT_EQ(make_one_step_map(map->hyperparams())->hyperparams(), map->hyperparams());
}

TEST(Normalization, RemovesUnitsOffsetsAndTimeScale) {
  // Data scaled q → k_q q + s, p → k_p p, t → c t normalise to the same states and steps,
  // for scalings from 1e-6 to 1e6.
  Rng rng(34, "units");
  std::vector<Trajectory> base;
  for (int k = 0; k < 3; ++k) {
    Trajectory t;
    t.z = rng.normal_matrix(4, 30, 1.0);
    t.z.row(1) *= 7.0;  // dofs of different spread
    t.t = Vector::LinSpaced(30, 0.0, 3.0);
    base.push_back(t);
  }
  const Normalization n0 = fit_normalization(base);
  const auto ref = normalize(n0, base);
  for (double kq : {1e-6, 3e-2, 1.0, 57.29577951308232, 1e6})
    for (double kp : {1e-6, 1e3, 1e6})
      for (double c : {1e-3, 1.0, 1e3}) {
        std::vector<Trajectory> scaled = base;
        for (Trajectory& t : scaled) {
          t.z.topRows(2) = (t.z.topRows(2) * kq).array() + 123.0 * kq;
          t.z.bottomRows(2) *= kp;
          t.t = t.t * c;
          t.t.array() += 10.0 * c;
        }
        const Normalization n = fit_normalization(scaled);
        const auto got = normalize(n, scaled);
        EXPECT_NEAR(n.time_scale / n0.time_scale, c, 1e-14 * c);
        for (std::size_t k = 0; k < got.size(); ++k) {
          EXPECT_LE((got[k].z - ref[k].z).cwiseAbs().maxCoeff(), 1e-9);
          EXPECT_LE((got[k].t - ref[k].t).cwiseAbs().maxCoeff(), 1e-12);
        }
      }
}

TEST(Normalization, KeepsTheProductOfScalesEqualAndRefusesFlatCoordinates) {
  Rng rng(35, "product");
  std::vector<Trajectory> trajs(1);
  trajs[0].z = rng.normal_matrix(6, 40, 1.0);
  trajs[0].z.row(0) *= 1e4;
  trajs[0].z.row(5) *= 1e-3;
  trajs[0].t = Vector::LinSpaced(40, 0.0, 1.0);
  const Normalization n = fit_normalization(trajs);
  for (Index i = 1; i < 3; ++i)
    EXPECT_NEAR(n.q_scale(i) * n.p_scale(i), n.q_scale(0) * n.p_scale(0),
                1e-14 * n.q_scale(0) * n.p_scale(0));
  // Each dof's q and p come out with the same spread.
  const Matrix zn = n.to_normal(trajs[0].z);
  for (Index i = 0; i < 3; ++i) {
    const double sq = std::sqrt((zn.row(i).array() - zn.row(i).mean()).square().mean());
    const double sp = std::sqrt((zn.row(3 + i).array() - zn.row(3 + i).mean()).square().mean());
    EXPECT_NEAR(sq, sp, 1e-12 * sq);
  }
  trajs[0].z.row(4).setConstant(2.0);
  try {
    fit_normalization(trajs);
    FAIL() << "a constant p2 must be refused";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("p2 does not vary"), std::string::npos) << e.what();
  }
  Normalization bad = n;
  bad.p_scale(1) *= 1.001;
  EXPECT_THROW(bad.validate(), Error);
}

}  // namespace
}  // namespace csympnet

namespace csympnet {
namespace {

const char* kScaledSpecs[] = {
    R"({"type":"csympnet","d":2,"core":{"type":"la","layers":2,"sublayers":3},"dof_scales":"learned"})",
    R"({"type":"csympnet","d":3,"core":{"type":"g","layers":3,"width":5},"dof_scales":"learned"})"};

// θ with the learned log-scales ν drawn too (the wrapped map's init leaves them at 0).
Vector random_scaled_theta(const OneStepMap& map, Rng& rng) {
  Vector theta = testing::random_theta(map, rng, 0.3, rng.uniform(0.1, 1.5));
  const Index d = map.dim() / 2;
  theta.tail(d - 1) = rng.uniform_vector(d - 1, -1.5, 1.5);
  return theta;
}

TEST(DofScaledMap, DerivativesMatchFiniteDifferences) {
  for (const char* s : kScaledSpecs) {
    const auto map = make_one_step_map(nlohmann::json::parse(s));
    Rng rng(36, s);
    for (int rep = 0; rep < 3; ++rep) {
      const Vector theta = random_scaled_theta(*map, rng);
      const Matrix z = rng.normal_matrix(map->dim(), 3, 1.0);
      const Vector h = rng.uniform_vector(3, 0.05, 0.2);
      const auto check = testing::check_one_step_map(*map, theta, z, h, rng);
      EXPECT_TRUE(check.ok()) << s << "\n" << check.report();
    }
  }
}

TEST(DofScaledMap, IsConformallySymplecticForTheLearnedForm) {
  // DΦᵀ (Dᵀ J D) DΦ = e^{−γh} Dᵀ J D with D = diag(1, μ), at random parameters and scales.
  for (const char* s : kScaledSpecs) {
    const auto map = make_one_step_map(nlohmann::json::parse(s));
    const auto& scaled = dynamic_cast<const DofScaledMap&>(*map);
    Rng rng(37, s);
    double worst = 0.0;
    for (int rep = 0; rep < 30; ++rep) {
      const Vector theta = random_scaled_theta(*map, rng);
      const Index d = map->dim() / 2;
      Vector diag = Vector::Ones(2 * d);
      diag.tail(d) = scaled.scales(theta);
      const Matrix form = diag.asDiagonal() * canonical_j(d) * diag.asDiagonal();
      const Vector z = rng.normal_matrix(2 * d, 1, 1.0);
      const double h = rng.uniform(0.05, 0.2);
      const Matrix jac = map->jacobian(theta, z, h);
      const double lambda = std::exp(-*map->damping_rate(theta) * h);
      worst = std::max(worst, (jac.transpose() * form * jac - lambda * form).norm() /
                                  std::max(1.0, jac.squaredNorm() * form.norm()));
    }
    EXPECT_LE(worst, 1e-14) << s;
  }
}

TEST(DofScaledMap, StartsAsTheWrappedMapAndRoundTrips) {
  const nlohmann::json spec = nlohmann::json::parse(kScaledSpecs[0]);
  const auto map = make_one_step_map(spec);
  nlohmann::json plain = spec;
  plain.erase("dof_scales");
  const auto inner = make_one_step_map(plain);
  EXPECT_EQ(map->n_params(), inner->n_params() + 1);
  Rng a(38, "init"), b(38, "init");
  Vector ta(map->n_params()), tb(inner->n_params());
  map->init_params(a, ta);
  inner->init_params(b, tb);
  EXPECT_EQ(ta.head(inner->n_params()), tb);
  EXPECT_EQ(ta(inner->n_params()), 0.0);
  Rng rng(39, "apply");
  const Matrix z = rng.normal_matrix(4, 5, 1.0);
  const Vector h = rng.uniform_vector(5, 0.05, 0.2);
  EXPECT_EQ(map->apply(ta, z, h), inner->apply(tb, z, h));
  EXPECT_EQ(make_one_step_map(map->hyperparams())->hyperparams(), map->hyperparams());
}

}  // namespace
}  // namespace csympnet
