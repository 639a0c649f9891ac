// RunConfig's options: the recipe's spellings, and the library's ranges and rules by key.
#include <gtest/gtest.h>

#include "csympnet/core/options.hpp"
#include "csympnet/paper/run.hpp"

namespace csympnet {
namespace {

TEST(RunOptions, RecipeSpellingsRoundTripAndOthersAreRefused) {
  for (const std::string& name : run_recipe_names())
    EXPECT_EQ(to_string(parse_run_recipe(name)), name);
  EXPECT_EQ(to_string(RunRecipe::kPaper), "paper");
  try {
    parse_run_recipe("fast");
    FAIL() << "'fast' was accepted";
  } catch (const OptionError& e) {
    EXPECT_STREQ(e.what(), "recipe: 'fast' is not a choice; expected one of default, paper");
  }
}

TEST(RunOptions, ThePaperRecipeKeepsTheBudgetAndUsesAConstantRate) {
  RunConfig c = default_run_config("s1", "csympnet");
  c.train.epochs = 123;
  apply_run_recipe(c, RunRecipe::kDefault);
  EXPECT_EQ(c.train.lr_schedule, LrSchedule::kCosine);
  apply_run_recipe(c, RunRecipe::kPaper);
  EXPECT_EQ(c.train.epochs, 123);
  EXPECT_EQ(c.train.lr_schedule, LrSchedule::kConstant);
}

TEST(RunOptions, RangesAndRulesAreRefusedByKey) {
  const auto key_of = [](const auto& set, const std::string& model = "csympnet") {
    RunConfig c = default_run_config("s1", model);
    set(c);
    try {
      c.validate();
    } catch (const OptionError& e) {
      return e.key();
    }
    return std::string();
  };
  EXPECT_EQ(key_of([](RunConfig&) {}), "");
  EXPECT_EQ(key_of([](RunConfig& c) { c.sigma = 11.0; }), "sigma");
  EXPECT_EQ(key_of([](RunConfig& c) { c.beta_init = 0.0; }), "beta_init");
  EXPECT_EQ(key_of([](RunConfig& c) { c.train.epochs = -1; }), "epochs");
  EXPECT_EQ(key_of([](RunConfig& c) { c.train.epochs = 0; }), "");  // evaluates the init
  EXPECT_EQ(key_of([](RunConfig& c) { c.train.val_every = 0; }), "val_every");
  EXPECT_EQ(key_of([](RunConfig& c) { c.train.adamw.lr = 20.0; }), "lr");
  EXPECT_EQ(key_of([](RunConfig& c) { c.refine.iterations = 0; }), "refine_iterations");
  EXPECT_EQ(key_of([](RunConfig& c) { c.warm_start = true; }, "sympnet"), "warm_start");
  EXPECT_EQ(key_of([](RunConfig& c) { c.refine.method = RefineMethod::kLm; }, "dhnn"), "refine");
}

}  // namespace
}  // namespace csympnet
