// Parameter counts of the paper's presets, hyperparams round-trips, deterministic init,
// and the factory's and models' input validation.
#include <gtest/gtest.h>

#include "../src/models/csympnet_id.hpp"
#include "../src/models/g_sympnet.hpp"
#include "../src/models/la_sympnet.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/models/model.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "support/model_fixtures.hpp"

namespace csympnet::testing {
namespace {

using nlohmann::json;

json la_core(Index layers, Index sublayers) {
  return {{"type", "la"}, {"layers", layers}, {"sublayers", sublayers}};
}
json g_core(Index layers, Index width) {
  return {{"type", "g"}, {"layers", layers}, {"width", width}};
}
json wrap(const char* type, Index d, const json& core) {
  return {{"type", type}, {"d", d}, {"core", core}};
}

// Expects make_one_step_map(spec) to throw an Error whose message contains `needle`.
void expect_spec_error(const json& spec, const std::string& needle) {
  try {
    make_one_step_map(spec);
    ADD_FAILURE() << "no error for " << spec.dump();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
        << "message '" << e.what() << "' lacks '" << needle << "'";
  }
}

TEST(ModelCounts, PaperPresets) {
  struct Preset {
    Index d;
    json core;
    Index sympnet;
  };
  const Preset presets[] = {{1, la_core(5, 20), 114},
                            {10, la_core(4, 10), 4110},
                            {10, g_core(7, 50), 4200},
                            {100, la_core(4, 4), 161100}};
  for (const Preset& p : presets) {
    EXPECT_EQ(make_one_step_map(wrap("sympnet", p.d, p.core))->n_params(), p.sympnet);
    const auto csympnet = make_one_step_map(wrap("csympnet", p.d, p.core));
    EXPECT_EQ(csympnet->n_params(), p.sympnet + 1);
    EXPECT_EQ(csympnet->damping_param_index(), p.sympnet);
  }
}

TEST(ModelCounts, Formulas) {
  for (Index d : {1, 2, 5}) {
    for (Index layers : {1, 2, 6}) {
      for (Index m : {1, 3}) {
        EXPECT_EQ(LaSympNet(d, layers, m).n_params(),
                  layers * (m * d * d + 2 * d) + (layers - 1) * d);
      }
      EXPECT_EQ(GSympNet(d, layers, 7).n_params(), layers * 7 * (d + 2));
    }
  }
}

TEST(ModelFactory, HyperparamsRoundTripAndBitIdenticalForward) {
  const json specs[] = {
      json::parse(
          R"({"type":"csympnet","d":1,"core":{"type":"la","layers":5,"sublayers":20},"beta_init":0.1})"),
      json::parse(R"({"type":"sympnet","d":10,"core":{"type":"g","layers":7,"width":50}})"),
      json::parse(
          R"({"type":"csympnet","d":3,"core":{"type":"g","layers":2,"width":4},"beta_init":-0.25})"),
      json::parse(R"({"type":"la","d":2,"layers":2,"sublayers":3})"),
      json::parse(R"({"type":"g","d":2,"layers":3,"width":5})")};
  Rng rng(3, "round-trip");
  for (const json& spec : specs) {
    const auto model = make_one_step_map(spec);
    EXPECT_EQ(model->hyperparams(), spec);
    EXPECT_EQ(model->type(), spec.at("type").get<std::string>());
    const auto rebuilt = make_one_step_map(json::parse(model->hyperparams().dump()));
    EXPECT_EQ(rebuilt->hyperparams(), model->hyperparams());
    const Vector theta = random_theta(*model, rng, 0.3);
    const Matrix z = rng.normal_matrix(model->dim(), 6, 1.0);
    const Vector h = random_steps(6, rng);
    const Matrix a = model->apply(theta, z, h);
    const Matrix b = rebuilt->apply(theta, z, h);
    EXPECT_EQ(a, b) << spec.dump();  // exact equality: same code, same inputs
  }
}

// Sizes every option check accepts must not end in std::bad_alloc: a model beyond
// kMaxModelParams is refused with its count before any parameter vector exists; the largest
// allowed one is built.
TEST(ModelFactory, RefusesModelsTooLargeToHoldBeforeAllocating) {
  for (const char* spec :
       {R"({"type":"csympnet","d":1,"core":{"type":"la","layers":100000,"sublayers":100000}})",
        R"({"type":"sympnet","d":4000,"core":{"type":"la","layers":10,"sublayers":10}})",
        R"({"type":"csympnet","d":2,"core":{"type":"g","layers":100000,"width":100000}})"}) {
    try {
      (void)make_model(nlohmann::json::parse(spec));
      ADD_FAILURE() << "accepted " << spec;
    } catch (const Error& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("parameters, more than the 50000000"), std::string::npos) << msg;
    }
  }
  // The Hamiltonian fields hold dense 2d x 2d matrices: refused by d, before allocating them.
  for (const char* type : {"dhnn", "dhnn2", "phnn", "phnn2"}) {
    nlohmann::json spec = {{"type", type}, {"d", 100000}, {"width", 2}};
    try {
      (void)make_model(spec);
      ADD_FAILURE() << "accepted " << type << " with d = 100000";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("expected d <= 4096"), std::string::npos) << e.what();
    }
  }
  // G(L, w) with d = 2 has 4 L w parameters: 50,000,000 exactly is allowed.
  const Model largest = make_model(nlohmann::json::parse(
      R"({"type":"sympnet","d":2,"core":{"type":"g","layers":12500,"width":1000}})"));
  EXPECT_EQ(largest.n_params(), kMaxModelParams);
}

TEST(ModelFactory, DefaultBetaInitIsWrittenOut) {
  const auto model = make_one_step_map(wrap("csympnet", 1, la_core(1, 1)));
  EXPECT_DOUBLE_EQ(model->hyperparams().at("beta_init").get<double>(), 0.1);
}

TEST(ModelInit, DeterministicAndDocumented) {
  const auto model = make_one_step_map(json::parse(
      R"({"type":"csympnet","d":2,"core":{"type":"la","layers":3,"sublayers":2},"beta_init":0.4})"));
  Vector first(model->n_params());
  Vector second(model->n_params());
  Rng rng1(9, "init");
  Rng rng2(9, "init");
  model->init_params(rng1, first);
  model->init_params(rng2, second);
  EXPECT_EQ(first, second);
  // The core part equals the bare core's init from the same stream.
  const auto core =
      make_one_step_map(json::parse(R"({"type":"la","d":2,"layers":3,"sublayers":2})"));
  Vector bare(core->n_params());
  Rng rng3(9, "init");
  core->init_params(rng3, bare);
  EXPECT_EQ(first.head(core->n_params()), bare);
  EXPECT_EQ(first(model->n_params() - 1), 0.4);
  EXPECT_DOUBLE_EQ(*model->damping_rate(first), 0.4);
  // Layout: module k = [A_{k,0}, A_{k,1}, b_p, b_q, a_k]; biases are zero, the rest are small.
  const Index module = 2 * 4 + 3 * 2;
  for (Index k = 0; k < 3; ++k) {
    EXPECT_TRUE(first.segment(k * module + 8, 4).isZero(0.0)) << "biases of module " << k;
    EXPECT_LT(first.segment(k * module, 8).cwiseAbs().maxCoeff(), 0.06);
    EXPECT_GT(first.segment(k * module, 8).cwiseAbs().maxCoeff(), 0.0);
  }
  const auto g = make_one_step_map(json::parse(R"({"type":"g","d":2,"layers":2,"width":3})"));
  Vector gtheta(g->n_params());
  Rng rng4(9, "init");
  g->init_params(rng4, gtheta);
  // Layout: module k = [K (3x2), a (3), b (3)].
  EXPECT_TRUE(gtheta.segment(9, 3).isZero(0.0));
  EXPECT_TRUE(gtheta.segment(21, 3).isZero(0.0));
  EXPECT_GT(gtheta.head(9).cwiseAbs().minCoeff(), 0.0);
}

TEST(ModelFactory, RejectsBadSpecs) {
  expect_spec_error(json::parse(R"({"type":"mlp","d":1})"),
                    "expected one of csympnet, sympnet, map, ode, dhnn, dhnn2, phnn, phnn2");
  expect_spec_error(json::parse(R"({"d":1})"), "'type'");
  expect_spec_error(json::parse(R"([1,2])"), "JSON object");
  expect_spec_error(wrap("sympnet", 0, la_core(1, 1)), "'d' = 0");
  expect_spec_error(json{{"type", "sympnet"}, {"core", la_core(1, 1)}}, "missing key 'd'");
  expect_spec_error(json{{"type", "csympnet"}, {"d", 1}}, "missing key 'core'");
  expect_spec_error(wrap("sympnet", 1, la_core(0, 1)), "'layers' = 0");
  expect_spec_error(wrap("sympnet", 1, la_core(2, 0)), "'sublayers' = 0");
  expect_spec_error(wrap("sympnet", 1, g_core(2, 0)), "'width' = 0");
  expect_spec_error(wrap("sympnet", 1, json{{"type", "la"}, {"layers", 2}}),
                    "missing key 'sublayers'");
  expect_spec_error(wrap("sympnet", 1, json{{"type", "g"}, {"width", 2}}), "missing key 'layers'");
  expect_spec_error(wrap("sympnet", 1, json{{"type", "h"}, {"layers", 2}}),
                    "expected one of la, g");
  expect_spec_error(wrap("sympnet", 1, json{{"type", "la"}, {"layers", 1.5}, {"sublayers", 2}}),
                    "'layers' = 1.5");
  json beta_zero = wrap("csympnet", 1, la_core(1, 1));
  beta_zero["beta_init"] = 0.0;
  expect_spec_error(beta_zero, "beta_init");
  json typo = wrap("csympnet", 1, la_core(1, 1));
  typo["beta"] = 0.3;
  expect_spec_error(typo, "unknown key 'beta'");
  json mismatch = wrap("sympnet", 2, la_core(1, 1));
  mismatch["core"]["d"] = 3;
  expect_spec_error(mismatch, "disagrees");
  EXPECT_THROW(CSympNetId(std::make_unique<LaSympNet>(1, 1, 1), 0.0), Error);
}

TEST(ModelShapes, ForwardBackwardJacobianRejectBadShapes) {
  for (const char* type : {"csympnet", "sympnet"}) {
    const auto model = make_one_step_map(wrap(type, 2, la_core(2, 2)));
    const Vector theta = Vector::Zero(model->n_params());
    const Matrix z = Matrix::Zero(4, 3);
    const Vector h = Vector::Constant(3, 0.1);
    EXPECT_THROW(model->apply(theta, Matrix::Zero(3, 3), h), Error);
    EXPECT_THROW(model->apply(theta, z, Vector::Constant(2, 0.1)), Error);
    EXPECT_THROW(model->apply(Vector::Zero(model->n_params() + 1), z, h), Error);
    EXPECT_THROW(model->jacobian(theta, Vector::Zero(3), 0.1), Error);
    Vector grad = Vector::Zero(model->n_params());
    ForwardCache empty;
    EXPECT_THROW(model->backward(theta, empty, z, grad, nullptr), Error);
    ForwardCache cache;
    model->forward(theta, z, h, &cache);
    EXPECT_THROW(model->backward(theta, cache, Matrix::Zero(4, 2), grad, nullptr), Error);
    Vector short_grad = Vector::Zero(2);
    EXPECT_THROW(model->backward(theta, cache, z, short_grad, nullptr), Error);
    EXPECT_NO_THROW(model->backward(theta, cache, z, grad, nullptr));
  }
}

TEST(ModelCache, ReusedCacheGivesSameGradients) {
  const auto model = make_one_step_map(wrap("csympnet", 2, g_core(3, 4)));
  Rng rng(21, "cache");
  const Vector theta = random_theta(*model, rng, 0.4, -0.6);
  ForwardCache cache;
  Vector grads[2];
  for (Vector& grad : grads) {
    // Each round first fills the cache with a different batch size, then reuses it.
    model->forward(theta, rng.normal_matrix(4, 7, 1.0), random_steps(7, rng), &cache);
    Rng fixed(4, "batch");
    const Matrix z = fixed.normal_matrix(4, 5, 1.0);
    const Vector h = random_steps(5, fixed);
    model->forward(theta, z, h, &cache);
    grad = Vector::Zero(model->n_params());
    model->backward(theta, cache, fixed.normal_matrix(4, 5, 1.0), grad, nullptr);
  }
  EXPECT_EQ(grads[0], grads[1]);
}

TEST(CSympNetId, ZeroBetaUsesSubgradientZero) {
  const auto model = make_one_step_map(wrap("csympnet", 1, la_core(2, 2)));
  Rng rng(8, "beta-zero");
  Vector theta = random_theta(*model, rng, 0.3, 0.0);
  const Matrix z = rng.normal_matrix(2, 4, 1.0);
  const Vector h = random_steps(4, rng);
  ForwardCache cache;
  model->forward(theta, z, h, &cache);
  Vector grad = Vector::Zero(model->n_params());
  model->backward(theta, cache, rng.normal_matrix(2, 4, 1.0), grad, nullptr);
  EXPECT_EQ(grad(model->n_params() - 1), 0.0);
  EXPECT_EQ(*model->damping_rate(theta), 0.0);
}

}  // namespace
}  // namespace csympnet::testing
