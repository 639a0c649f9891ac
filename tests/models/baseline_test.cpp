// The baselines: MapBaseline through the one-step-map harness, the five vector fields through
// check_vector_field_model (field_backward and field_jacobian against finite differences),
// the paper's parameter counts, the frozen structure, and the factory's round trip and errors.
#include <gtest/gtest.h>

#include <string>

#include "../src/models/map_baseline.hpp"
#include "../src/models/mlp.hpp"
#include "../src/models/vector_field_models.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/models/model.hpp"
#include "support/gradient_check.hpp"
#include "support/model_fixtures.hpp"

namespace csympnet::testing {
namespace {

using nlohmann::json;

json field_spec(const std::string& type, Index d, Index width) {
  return {{"type", type}, {"d", d}, {"width", width}};
}

// The documented init, scaled so tanh is nonlinear, plus noise so J_θ is not exactly J and L is
// O(1); β (if any) set to `beta`.
Vector random_field_theta(const VectorFieldModel& model, Rng& rng, double beta) {
  Vector theta(model.n_params());
  model.init_params(rng, theta);
  theta = 3.0 * theta + rng.normal_matrix(model.n_params(), 1, 0.3);
  if (const auto index = model.damping_param_index()) theta(*index) = beta;
  return theta;
}

struct FieldCase {
  const char* type;
  Index d;
  double beta;
  bool frozen;
};

void PrintTo(const FieldCase& c, std::ostream* out) {
  *out << c.type << " d " << c.d << " beta " << c.beta << (c.frozen ? " frozen" : "");
}

class FieldGradientTest : public ::testing::TestWithParam<FieldCase> {};

TEST_P(FieldGradientTest, BackwardAndJacobianMatchFiniteDifferences) {
  const FieldCase& c = GetParam();
  json spec = field_spec(c.type, c.d, 5);
  if (std::string(c.type) != "ode") spec["freeze_structure"] = c.frozen;
  const auto model = make_vector_field_model(spec);
  Rng rng(404, c.type);
  for (int rep = 0; rep < 2; ++rep) {
    const Vector theta = random_field_theta(*model, rng, c.beta);
    const Matrix z = rng.normal_matrix(model->dim(), 4, 1.0);
    const FieldCheck check = check_vector_field_model(*model, theta, z, rng);
    EXPECT_TRUE(check.ok()) << check.report();
  }
}

INSTANTIATE_TEST_SUITE_P(
    Fields, FieldGradientTest,
    ::testing::Values(FieldCase{"ode", 1, 0, false}, FieldCase{"ode", 3, 0, false},
                      FieldCase{"dhnn", 1, 0, false}, FieldCase{"dhnn", 3, 0, false},
                      FieldCase{"dhnn", 2, 0, true}, FieldCase{"dhnn2", 1, 0.3, false},
                      FieldCase{"dhnn2", 3, -0.4, false}, FieldCase{"dhnn2", 2, -0.2, true},
                      FieldCase{"phnn", 1, 0, false}, FieldCase{"phnn", 3, 0, false},
                      FieldCase{"phnn", 2, 0, true}, FieldCase{"phnn2", 1, 0.3, false},
                      FieldCase{"phnn2", 3, -0.4, false}, FieldCase{"phnn2", 2, 0.2, true}));

TEST(FieldGradient, PlantedWrongStructureGradientIsRejected) {
  const auto model = make_vector_field_model(field_spec("phnn", 2, 5));
  const auto& field = dynamic_cast<const HamiltonianField&>(*model);
  Rng rng(405, "planted");
  const Vector theta = random_field_theta(*model, rng, 0.0);
  const Matrix z = rng.normal_matrix(4, 3, 1.0);
  const Matrix g = rng.normal_matrix(4, 3, 1.0);
  Vector grad = Vector::Zero(model->n_params());
  model->field_backward(theta, z, g, grad);
  const Vector fd = fd_gradient(
      [&](const Vector& th) { return (g.array() * model->field(th, z).array()).sum(); }, theta);
  ASSERT_TRUE(compare(grad, fd, 1e-6).ok());
  // One wrong entry in the L block, 1% of the gradient's scale.
  grad(field.port_offset() + 5) += 0.01 * grad.norm();
  EXPECT_FALSE(compare(grad, fd, 1e-6).ok());
}

TEST(FrozenStructure, ZeroGradientSameCountAndIgnoredEntries) {
  for (const char* type : {"dhnn", "dhnn2", "phnn", "phnn2"}) {
    json spec = field_spec(type, 2, 4);
    const auto free_model = make_vector_field_model(spec);
    spec["freeze_structure"] = true;
    const auto model = make_vector_field_model(spec);
    EXPECT_EQ(model->n_params(), free_model->n_params()) << type;
    const auto& field = dynamic_cast<const HamiltonianField&>(*model);
    Rng rng(406, type);
    Vector theta = random_field_theta(*model, rng, 0.3);
    const Matrix z = rng.normal_matrix(4, 5, 1.0);
    Vector grad = Vector::Zero(model->n_params());
    model->field_backward(theta, z, rng.normal_matrix(4, 5, 1.0), grad);
    EXPECT_TRUE(grad.segment(field.structure_offset(), 16).isZero(0.0)) << type;
    EXPECT_FALSE(grad.head(field.structure_offset()).isZero(0.0)) << type;
    // The field uses the canonical J whatever those entries hold.
    const Matrix before = model->field(theta, z);
    theta.segment(field.structure_offset(), 16).setConstant(7.0);
    EXPECT_EQ(model->field(theta, z), before) << type;
  }
}

TEST(FieldInit, StructureStartsAtCanonicalJ) {
  for (const char* type : {"dhnn", "dhnn2", "phnn", "phnn2"}) {
    const auto model = make_vector_field_model(field_spec(type, 3, 4));
    const auto& field = dynamic_cast<const HamiltonianField&>(*model);
    Vector theta(model->n_params());
    Rng rng(1, "init");
    model->init_params(rng, theta);
    EXPECT_EQ(theta.segment(field.structure_offset(), 36).reshaped(6, 6), canonical_j(3)) << type;
    if (field.port_offset() >= 0) {
      const Vector l = theta.segment(field.port_offset(), 36);
      EXPECT_GT(l.cwiseAbs().minCoeff(), 0.0);
      EXPECT_LT(l.cwiseAbs().maxCoeff(), 0.06);  // N(0, 0.01²): 6σ
      EXPECT_EQ(field.port_offset() + 36, model->n_params());
    }
  }
}

TEST(FieldDamping, RateIsAbsBetaAndIndexIsLast) {
  for (const char* type : {"dhnn2", "phnn2"}) {
    json spec = field_spec(type, 1, 4);
    spec["beta_init"] = -0.25;
    const auto model = make_vector_field_model(spec);
    Vector theta(model->n_params());
    Rng rng(2, "init");
    model->init_params(rng, theta);
    ASSERT_TRUE(model->damping_param_index().has_value());
    EXPECT_EQ(*model->damping_param_index(), model->n_params() - 1);
    EXPECT_EQ(theta(model->n_params() - 1), -0.25);
    EXPECT_EQ(model->damping_rate(theta).value(), 0.25);
  }
  for (const char* type : {"ode", "dhnn", "phnn"}) {
    const auto model = make_vector_field_model(field_spec(type, 1, 4));
    EXPECT_FALSE(model->damping_param_index().has_value()) << type;
    EXPECT_FALSE(model->damping_rate(Vector::Zero(model->n_params())).has_value()) << type;
  }
}

// With J frozen (skew), dH/dt = ∇Hᵀ f = −‖Lᵀ∇H‖² (phnn) or −γ̂‖∇_p H‖² (phnn2), never > 0.
TEST(FieldStructure, PortHamiltonianFieldsDissipateH) {
  for (const char* type : {"phnn", "phnn2"}) {
    json spec = field_spec(type, 2, 6);
    spec["freeze_structure"] = true;
    const auto model = make_vector_field_model(spec);
    const Mlp h_net({4, 6, 6, 1});
    Rng rng(407, type);
    const Vector theta = random_field_theta(*model, rng, -0.5);
    const Matrix z = rng.normal_matrix(4, 50, 1.0);
    const Matrix grad_h = h_net.input_gradient(theta.head(h_net.n_params()), z);
    const Matrix f = model->field(theta, z);
    const Vector rate = (grad_h.array() * f.array()).colwise().sum().transpose();
    EXPECT_LE(rate.maxCoeff(), 1e-12) << type;
    EXPECT_LT(rate.minCoeff(), 0.0) << type;
  }
}

TEST(MapBaselineTest, OneStepMapHarness) {
  for (Index d : {1, 3}) {
    const auto model = make_one_step_map(json{{"type", "map"}, {"d", d}, {"width", 6}});
    Rng rng(408, "map");
    for (int rep = 0; rep < 2; ++rep) {
      Vector theta(model->n_params());
      model->init_params(rng, theta);
      theta *= 3.0;
      const Matrix z = rng.normal_matrix(2 * d, 5, 1.0);
      const Vector h = random_steps(5, rng);
      const ModelCheck check = check_one_step_map(*model, theta, z, h, rng);
      EXPECT_TRUE(check.ok()) << check.report();
    }
  }
}

TEST(MapBaselineTest, IncrementAndStepInput) {
  const MapBaseline model(1, 4);
  // θ = 0 except the output bias: Φ̂(z) = z + b for every h.
  Vector theta = Vector::Zero(model.n_params());
  theta.tail(2) << 0.5, -0.25;
  const Matrix z = Matrix::Ones(2, 3);
  const Matrix out = model.apply(theta, z, Vector::Constant(3, 0.1));
  EXPECT_EQ(out.row(0), RowVector::Constant(3, 1.5));
  EXPECT_EQ(out.row(1), RowVector::Constant(3, 0.75));
  // h is the last input row: a nonzero weight on it makes the output depend on h.
  Rng rng(3, "init");
  model.init_params(rng, theta);
  const Matrix a = model.apply(theta, z, Vector::Constant(3, 0.1));
  const Matrix b = model.apply(theta, z, Vector::Constant(3, 0.2));
  EXPECT_GT((a - b).norm(), 0.0);
}

struct CountRow {
  const char* type;
  Index counts[3];  // d = 1, 10, 100 with widths 32, 64, 256 (docs/protocol.md, "Baselines")
};

TEST(ParameterCounts, MatchThePaperForEveryModelAndDimension) {
  const CountRow rows[] = {{"map", {1250, 6868, 168904}},   {"ode", {1218, 6804, 168648}},
                           {"dhnn", {2374, 11538, 275010}}, {"dhnn2", {1190, 5970, 157506}},
                           {"phnn", {1193, 6369, 197505}},  {"phnn2", {1190, 5970, 157506}}};
  const Index dims[] = {1, 10, 100};
  const Index widths[] = {32, 64, 256};
  const auto direct = [](const std::string& type, Index d, Index w) -> Index {
    if (type == "map") return MapBaseline(d, w).n_params();
    if (type == "ode") return OdeField(d, w).n_params();
    const Dissipation kind = type == "dhnn"    ? Dissipation::kNetwork
                             : type == "dhnn2" ? Dissipation::kMomentumDamping
                             : type == "phnn"  ? Dissipation::kPortMatrix
                                               : Dissipation::kPortDamping;
    return HamiltonianField(kind, d, w).n_params();
  };
  for (const CountRow& row : rows) {
    for (int k = 0; k < 3; ++k) {
      const json spec = field_spec(row.type, dims[k], widths[k]);
      EXPECT_EQ(make_model(spec).n_params(), row.counts[k]) << row.type << " d " << dims[k];
      EXPECT_EQ(direct(row.type, dims[k], widths[k]), row.counts[k])
          << row.type << " d " << dims[k];
      if (std::string(row.type) != "map" && std::string(row.type) != "ode") {
        json frozen = spec;
        frozen["freeze_structure"] = true;
        EXPECT_EQ(make_model(frozen).n_params(), row.counts[k]) << row.type << " frozen";
      }
    }
  }
}

TEST(FieldFactory, HyperparamsRoundTrip) {
  const json specs[] = {
      field_spec("ode", 2, 7),
      json::parse(R"({"type":"dhnn","d":1,"width":5,"freeze_structure":true})"),
      json::parse(R"({"type":"dhnn2","d":3,"width":4,"beta_init":-0.2})"),
      json::parse(R"({"type":"phnn","d":2,"width":3})"),
      json::parse(R"({"type":"phnn2","d":1,"width":6,"beta_init":0.05,"freeze_structure":true})"),
  };
  for (const json& spec : specs) {
    const auto model = make_vector_field_model(spec);
    const auto rebuilt = make_vector_field_model(json::parse(model->hyperparams().dump()));
    EXPECT_EQ(rebuilt->hyperparams(), model->hyperparams()) << spec.dump();
    EXPECT_EQ(rebuilt->n_params(), model->n_params());
    Vector a(model->n_params()), b(model->n_params());
    Rng r1(9, "init"), r2(9, "init");
    model->init_params(r1, a);
    rebuilt->init_params(r2, b);
    EXPECT_EQ(a, b) << spec.dump();
    for (const auto& item : spec.items()) EXPECT_EQ(model->hyperparams()[item.key()], item.value());
  }
  const auto map = make_one_step_map(json{{"type", "map"}, {"d", 2}, {"width", 5}});
  EXPECT_EQ(make_one_step_map(map->hyperparams())->hyperparams(), map->hyperparams());
}

void expect_error(const json& spec, const std::string& needle) {
  try {
    make_model(spec);
    ADD_FAILURE() << "no error for " << spec.dump();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
        << "message: " << e.what() << "\nexpected to contain: " << needle;
  }
}

TEST(FieldFactory, ErrorsNameTheBadKeyOrValue) {
  try {
    make_vector_field_model(json{{"type", "hnn"}, {"d", 1}, {"width", 4}});
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'hnn'; expected one of ode, dhnn, dhnn2, phnn, phnn2"),
              std::string::npos)
        << e.what();
  }
  expect_error(json{{"type", "dhnn"}, {"d", 1}}, "missing key 'width'");
  expect_error(json{{"type", "ode"}, {"d", 0}, {"width", 4}}, "'d' = 0");
  expect_error(json{{"type", "dhnn"}, {"d", 1}, {"width", 4}, {"beta_init", 0.1}},
               "unknown key 'beta_init'");
  expect_error(json{{"type", "dhnn2"}, {"d", 1}, {"width", 4}, {"beta_init", 0.0}},
               "'beta_init' = 0.0");
  expect_error(json{{"type", "phnn"}, {"d", 1}, {"width", 4}, {"freeze_structure", 1}},
               "'freeze_structure' = 1");
  expect_error(json{{"type", "map"}, {"d", 1}, {"width", 4}, {"depth", 3}}, "unknown key 'depth'");
  expect_error(json{{"type", "map"}, {"d", 1}}, "missing key 'width'");
  const auto model = make_vector_field_model(field_spec("dhnn", 1, 3));
  EXPECT_THROW(model->field(Vector::Zero(3), Matrix::Zero(2, 1)), Error);
  EXPECT_THROW(model->field(Vector::Zero(model->n_params()), Matrix::Zero(3, 1)), Error);
  Vector grad = Vector::Zero(model->n_params());
  EXPECT_THROW(model->field_backward(Vector::Zero(model->n_params()), Matrix::Zero(2, 2),
                                     Matrix::Zero(2, 1), grad),
               Error);
}

}  // namespace
}  // namespace csympnet::testing
