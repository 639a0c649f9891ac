// make_identify_config: the one builder of an IdentifyConfig for the CLI and Python.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "csympnet/core/error.hpp"
#include "csympnet/experiments/identify.hpp"

namespace csympnet {
namespace {

nlohmann::json as_json(const IdentifyConfig& c) {
  nlohmann::json j = c;
  j["threads"] = c.threads;  // not part of the report's configuration
  return j;
}

TEST(IdentifyConfigBuilder, NoSettingsGiveTheDefaults) {
  EXPECT_EQ(as_json(make_identify_config(nlohmann::json::object())), as_json(IdentifyConfig{}));
}

TEST(IdentifyConfigBuilder, EveryKeyOverridesItsField) {
  const nlohmann::json s = {{"core", {{"type", "g"}, {"layers", 2}, {"width", 4}}},
                            {"seed", 7},
                            {"window", 3},
                            {"balanced", false},
                            {"normalize", false},
                            {"dof_scales", "learned"},
                            {"epochs", 123},
                            {"lr", 2.5e-3},
                            {"lm_iterations", 9},
                            {"val_fraction", 0.3},
                            {"blocks", 12},
                            {"level", 0.9},
                            {"threads", 2}};
  const IdentifyConfig c = make_identify_config(s);
  EXPECT_EQ(c.core, s["core"]);
  EXPECT_EQ(c.seed, 7u);
  EXPECT_EQ(c.window, 3);
  EXPECT_FALSE(c.balanced);
  EXPECT_FALSE(c.normalize);
  EXPECT_EQ(c.dof_scales, "learned");
  EXPECT_EQ(c.epochs, 123);
  EXPECT_EQ(c.lr, 2.5e-3);
  EXPECT_EQ(c.lm_iterations, 9);
  EXPECT_EQ(c.val_fraction, 0.3);
  EXPECT_EQ(c.target_blocks, 12);
  EXPECT_EQ(c.level, 0.9);
  EXPECT_EQ(c.threads, 2);
  // Each key alone changes only its own field.
  const nlohmann::json defaults = as_json(IdentifyConfig{});
  for (const auto& item : s.items()) {
    const nlohmann::json one = as_json(make_identify_config({{item.key(), item.value()}}));
    int changed = 0;
    for (const auto& field : defaults.items()) changed += one[field.key()] != field.value();
    EXPECT_EQ(changed, 1) << item.key();
  }
}

TEST(IdentifyConfigBuilder, UnknownKeysAndNonObjectsAreRefusedByName) {
  try {
    make_identify_config({{"blocks", 10}, {"windw", 2}});
    FAIL() << "an unknown key was accepted";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "identify settings: unknown key 'windw'");
  }
  EXPECT_THROW(make_identify_config(nlohmann::json::array()), Error);
}

}  // namespace
}  // namespace csympnet
