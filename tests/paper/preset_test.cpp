#include "csympnet/paper/preset.hpp"

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "csympnet/models/model.hpp"

namespace csympnet {
namespace {

TEST(Preset, ProtocolDataSizesAndSteps) {
  const Preset s1 = preset_by_name("s1");
  EXPECT_EQ(s1.system.kind, "oscillator");
  EXPECT_EQ(s1.n_train, 80);
  EXPECT_EQ(s1.n_val, 20);
  EXPECT_EQ(s1.train_steps.h_min, 0.05);
  EXPECT_EQ(s1.train_steps.h_max, 0.15);
  for (const std::string name : {"s2", "s3", "s2-100", "s3-100"}) {
    const Preset p = preset_by_name(name);
    EXPECT_EQ(p.n_train, 400) << name;
    EXPECT_EQ(p.n_val, 100) << name;
    EXPECT_EQ(p.train_steps.h_min, 0.1) << name;
    EXPECT_EQ(p.train_steps.h_max, 0.1) << name;
    EXPECT_EQ(p.system.d, name.size() > 2 ? 100 : 10) << name;
  }
  EXPECT_EQ(preset_by_name("s3").system.alpha, 0.005);
  EXPECT_EQ(preset_by_name("s3-100").system.alpha, 1e-4);
  for (const std::string& name : preset_names()) {
    const Preset p = preset_by_name(name);
    EXPECT_EQ(p.h_test, 0.2);
    EXPECT_EQ(p.horizon, 10.0);
    EXPECT_EQ(p.n_test, 10);
    EXPECT_EQ(p.system.gamma, 0.05);
  }
  EXPECT_THROW(preset_by_name("s4"), Error);
}

TEST(Preset, ParameterCountsMatchTheProtocol) {
  const std::pair<const char*, long> expected[] = {
      {"s1", 115}, {"s2", 4111}, {"s3", 4201}, {"s2-100", 161101}, {"s3-100", 161101}};
  for (const auto& [name, n] : expected) {
    const Preset p = preset_by_name(name);
    EXPECT_EQ(make_model(model_spec_for(p, "csympnet")).n_params(), n) << name;
    EXPECT_EQ(make_model(model_spec_for(p, "sympnet")).n_params(), n - 1) << name;
  }
}

TEST(Preset, RecipesAreNamed) {
  EXPECT_EQ(describe_recipe(paper_recipe(100)), "paper");
  TrainOptions t = preset_by_name("s3").train;
  EXPECT_EQ(describe_recipe(t), "paper+cosine-lr,lr=0.01");
  t.adamw.decay_damping = false;
  EXPECT_EQ(describe_recipe(t), "paper+cosine-lr,lr=0.01,no-beta-decay");
}

}  // namespace
}  // namespace csympnet
