// ForwardCache holds one typed context per map (one_step_map.hpp). What must hold of it: a cache
// reused across batch sizes and across models gives the bits of a fresh one; a cache filled by
// one model and handed to the backward pass of another is refused with an Error, never read as
// the wrong type; and a forward pass of the size already held allocates nothing new.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../src/models/csympnet_id.hpp"
#include "../src/models/la_sympnet.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "support/model_fixtures.hpp"
#include "support/same_bits.hpp"

namespace csympnet::testing {
namespace {

using nlohmann::json;

// One of every kind of context: both cores alone and inside CSympNet-ID (d = 1 runs the single-
// row sweeps, d = 2 the column passes), the step-polynomial core, the MLP baseline, and the two
// wrappers (learned dof scales around CSympNet-ID; normalization around a SympNet).
std::vector<json> model_specs() {
  const json la = {{"type", "la"}, {"layers", 2}, {"sublayers", 3}};
  const json la_poly = {{"type", "la"}, {"layers", 2}, {"sublayers", 2}, {"step_terms", 2}};
  const json g = {{"type", "g"}, {"layers", 3}, {"width", 4}};
  return {
      {{"type", "csympnet"}, {"d", 1}, {"core", la}},
      {{"type", "csympnet"}, {"d", 2}, {"core", la}},
      {{"type", "csympnet"}, {"d", 2}, {"core", g}},
      {{"type", "csympnet"}, {"d", 1}, {"core", la_poly}},
      {{"type", "sympnet"}, {"d", 2}, {"core", g}},
      {{"type", "la"}, {"d", 1}, {"layers", 2}, {"sublayers", 2}},
      {{"type", "map"}, {"d", 2}, {"width", 5}},
      {{"type", "csympnet"}, {"d", 2}, {"core", g}, {"dof_scales", "learned"}},
      {{"type", "sympnet"},
       {"d", 1},
       {"core", la},
       {"normalization",
        {{"q_shift", {0.5}}, {"q_scale", {2.0}}, {"p_scale", {0.5}}, {"time_scale", 3.0}}}},
  };
}

struct Pass {
  Matrix out;
  Vector grad;
  Matrix dz_in;
};

Pass run_pass(const OneStepMap& model, ForwardCache& cache, Index n, std::uint64_t seed) {
  Rng rng(seed, "forward-cache");
  const Vector theta = random_theta(model, rng, 0.4, -0.3);
  const Matrix z = rng.normal_matrix(model.dim(), n, 1.0);
  const Vector h = random_steps(n, rng);
  const Matrix dz_out = rng.normal_matrix(model.dim(), n, 1.0);
  Pass pass;
  pass.out = model.forward(theta, z, h, &cache);
  pass.grad = Vector::Zero(model.n_params());
  model.backward(theta, cache, dz_out, pass.grad, &pass.dz_in);
  return pass;
}

TEST(ForwardCache, ReusedAcrossModelsAndBatchSizesGivesTheBitsOfAFreshOne) {
  std::vector<std::unique_ptr<OneStepMap>> models;
  for (const json& spec : model_specs()) models.push_back(make_one_step_map(spec));
  ForwardCache shared;
  const Index sizes[] = {9, 3, 17};
  // Every model runs on the shared cache after every other has (and after itself at another
  // size), so each finds a foreign or a differently sized context in it.
  for (const Index n : sizes) {
    for (std::size_t m = 0; m < models.size(); ++m) {
      SCOPED_TRACE(models[m]->hyperparams().dump() + ", N = " + std::to_string(n));
      const auto seed = static_cast<std::uint64_t>(100 * n + static_cast<Index>(m));
      ForwardCache fresh;
      const Pass expected = run_pass(*models[m], fresh, n, seed);
      const Pass reused = run_pass(*models[m], shared, n, seed);
      EXPECT_TRUE(same_bits(reused.out, expected.out));
      EXPECT_TRUE(same_bits(reused.grad, expected.grad));
      EXPECT_TRUE(same_bits(reused.dz_in, expected.dz_in));
    }
  }
}

// backward() on what another model's forward() recorded: an Error, whichever pair.
TEST(ForwardCache, BackwardRefusesAnotherModelsContext) {
  std::vector<std::unique_ptr<OneStepMap>> models;
  for (const json& spec : model_specs()) models.push_back(make_one_step_map(spec));
  Rng rng(5, "foreign");
  for (const auto& writer : models) {
    ForwardCache cache;
    const Index n = 4;
    writer->forward(random_theta(*writer, rng, 0.3), rng.normal_matrix(writer->dim(), n, 1.0),
                    random_steps(n, rng), &cache);
    for (const auto& reader : models) {
      if (reader->hyperparams() == writer->hyperparams()) continue;
      SCOPED_TRACE(writer->hyperparams().dump() + " -> " + reader->hyperparams().dump());
      Vector grad = Vector::Zero(reader->n_params());
      EXPECT_THROW(reader->backward(random_theta(*reader, rng, 0.3), cache,
                                    Matrix::Zero(reader->dim(), n), grad, nullptr),
                   Error);
    }
  }
}

TEST(ForwardCache, RefusalNamesWhatTheCacheHolds) {
  const auto g = make_one_step_map({{"type", "g"}, {"d", 1}, {"layers", 2}, {"width", 3}});
  const auto map = make_one_step_map({{"type", "map"}, {"d", 1}, {"width", 3}});
  Rng rng(6, "names");
  ForwardCache cache;
  g->forward(random_theta(*g, rng, 0.3), rng.normal_matrix(2, 3, 1.0), random_steps(3, rng),
             &cache);
  Vector grad = Vector::Zero(map->n_params());
  try {
    map->backward(random_theta(*map, rng, 0.3), cache, Matrix::Zero(2, 3), grad, nullptr);
    FAIL() << "backward accepted a g core's cache";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("symplectic core"), std::string::npos) << e.what();
  }
}

// The same context type from a core of another size: the core's own check refuses it.
TEST(ForwardCache, BackwardRefusesACoreOfAnotherSize) {
  const auto g2 = make_one_step_map({{"type", "g"}, {"d", 2}, {"layers", 2}, {"width", 3}});
  const auto g3 = make_one_step_map({{"type", "g"}, {"d", 2}, {"layers", 3}, {"width", 3}});
  const auto la2 = make_one_step_map({{"type", "csympnet"},
                                      {"d", 1},
                                      {"core", {{"type", "la"}, {"layers", 2}, {"sublayers", 2}}}});
  const auto la3 = make_one_step_map({{"type", "csympnet"},
                                      {"d", 1},
                                      {"core", {{"type", "la"}, {"layers", 3}, {"sublayers", 2}}}});
  Rng rng(7, "sizes");
  const std::pair<const OneStepMap*, const OneStepMap*> pairs[] = {
      {g3.get(), g2.get()}, {g2.get(), g3.get()}, {la3.get(), la2.get()}, {la2.get(), la3.get()}};
  for (const auto& [writer, reader] : pairs) {
    ForwardCache cache;
    writer->forward(random_theta(*writer, rng, 0.3), rng.normal_matrix(writer->dim(), 5, 1.0),
                    random_steps(5, rng), &cache);
    Vector grad = Vector::Zero(reader->n_params());
    EXPECT_THROW(reader->backward(random_theta(*reader, rng, 0.3), cache,
                                  Matrix::Zero(reader->dim(), 5), grad, nullptr),
                 Error);
  }
}

// A training epoch's forward pass at the batch size already held keeps every buffer where it
// was: the storage is reused, not reallocated.
TEST(ForwardCache, SameBatchSizeKeepsTheStorage) {
  for (const Index d : {Index{1}, Index{2}}) {
    SCOPED_TRACE("d = " + std::to_string(d));
    const auto model =
        make_one_step_map({{"type", "csympnet"},
                           {"d", d},
                           {"core", {{"type", "la"}, {"layers", 2}, {"sublayers", 2}}}});
    Rng rng(8, "storage");
    const Vector theta = random_theta(*model, rng, 0.3);
    const Vector h = random_steps(16, rng);
    ForwardCache cache;
    auto buffers = [&] {
      const auto& ctx = cache.context<CSympNetId::Context>("test");
      std::vector<const double*> ptrs = {ctx.h.data(), ctx.a.data(), ctx.p_in.data(),
                                         ctx.p_core.data(), ctx.q.data()};
      for (const Matrix& s : ctx.core.context<LaSympNet::FlowContext>("test").steps) {
        ptrs.push_back(s.data());
      }
      return ptrs;
    };
    model->forward(theta, rng.normal_matrix(2 * d, 16, 1.0), h, &cache);
    const std::vector<const double*> first = buffers();
    model->forward(theta, rng.normal_matrix(2 * d, 16, 1.0), h, &cache);
    EXPECT_EQ(buffers(), first);
  }
}

}  // namespace
}  // namespace csympnet::testing
