// make_identify_config: the one builder of an IdentifyConfig for the CLI and Python.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "csympnet/core/error.hpp"
#include "csympnet/core/options.hpp"
#include "csympnet/identify/identify.hpp"

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
  EXPECT_EQ(c.dof_scales, DofScales::kLearned);
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

// make_identify_config is the boundary: a value out of its range is refused there, by key.
TEST(IdentifyConfigBuilder, OutOfRangeValuesAreRefusedByKey) {
  const auto key_of = [](const nlohmann::json& s) {
    try {
      make_identify_config(s);
    } catch (const OptionError& e) {
      return e.key();
    }
    return std::string();
  };
  EXPECT_EQ(key_of({{"window", 65}}), "window");
  EXPECT_EQ(key_of({{"window", -1}}), "window");
  EXPECT_EQ(key_of({{"epochs", -1}}), "epochs");
  EXPECT_EQ(key_of({{"epochs", 0}}), "");  // 0: automatic
  EXPECT_EQ(key_of({{"lm_iterations", 100001}}), "lm_iterations");
  EXPECT_EQ(key_of({{"lr", 0.0}}), "lr");
  EXPECT_EQ(key_of({{"val_fraction", 1.0}}), "val_fraction");
  EXPECT_EQ(key_of({{"blocks", 2}}), "blocks");
  EXPECT_EQ(key_of({{"level", 1.0}}), "level");
  EXPECT_EQ(key_of({{"level", 0.4}}), "level");
  EXPECT_EQ(key_of({{"threads", 0}}), "threads");
  EXPECT_EQ(key_of({{"threads", 257}}), "threads");
  EXPECT_EQ(key_of({{"dof_scales", "free"}}), "dof_scales");
  try {
    make_identify_config({{"level", 2.0}});
    FAIL() << "level 2 was accepted";
  } catch (const OptionError& e) {
    EXPECT_STREQ(e.what(), "level: '2' is out of range; expected a number from 0.5 to 0.9999");
  }
}

// A value of the wrong JSON kind is refused by key with what was expected (Python's
// derived_momenta=None raised nlohmann's bare "type_error.302").
TEST(IdentifyConfigBuilder, ValuesOfTheWrongKindAreRefusedByKey) {
  const auto message = [](const nlohmann::json& s) {
    try {
      make_identify_config(s);
    } catch (const OptionError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(message({{"derived_momenta", nullptr}}),
            "derived_momenta: got null; expected a string (one of set_aside, use)");
  EXPECT_EQ(message({{"derived_momenta", 1}}),
            "derived_momenta: got 1; expected a string (one of set_aside, use)");
  EXPECT_EQ(message({{"dof_scales", {{"a", 1}}}}),
            "dof_scales: got an object; expected a string (one of auto, learned, fixed)");
  EXPECT_EQ(message({{"seed", "7"}}), "seed: got a string; expected a whole number >= 0");
  EXPECT_EQ(message({{"seed", -1}}), "seed: got -1; expected a whole number >= 0");
  EXPECT_EQ(message({{"window", 1.5}}), "window: got 1.5; expected a whole number");
  EXPECT_EQ(message({{"balanced", 1}}), "balanced: got 1; expected true or false");
  EXPECT_EQ(message({{"normalize", nullptr}}), "normalize: got null; expected true or false");
  EXPECT_EQ(message({{"lr", "0.1"}}), "lr: got a string; expected a number");
  EXPECT_EQ(message({{"threads", {1, 2}}}), "threads: got a list; expected a whole number");
  for (const char* key : {"epochs", "lm_iterations", "blocks"})
    EXPECT_EQ(message({{key, true}}), std::string(key) + ": got true; expected a whole number");
  for (const char* key : {"val_fraction", "level"})
    EXPECT_EQ(message({{key, nullptr}}), std::string(key) + ": got null; expected a number");
  EXPECT_EQ(make_identify_config({{"seed", 18446744073709551615ULL}}).seed,
            18446744073709551615ULL);
  EXPECT_TRUE(make_identify_config({{"derived_momenta", "use"}}).use_derived_momenta);
}

TEST(IdentifyConfigBuilder, DofScalesSpellingsRoundTrip) {
  for (const std::string& name : dof_scales_names())
    EXPECT_EQ(to_string(parse_dof_scales(name)), name);
  EXPECT_EQ(to_string(DofScales::kFixed), "fixed");
  EXPECT_EQ(make_identify_config({{"dof_scales", "fixed"}}).dof_scales, DofScales::kFixed);
  EXPECT_THROW(parse_dof_scales("Learned"), OptionError);
  const std::vector<std::string> losses = {"balanced", "one-step"};
  EXPECT_EQ(identify_loss_names(), losses);
}

}  // namespace
}  // namespace csympnet
