// The words of the progress line and of the second stage's summary: plain, and never phrased
// as a failure when an optimiser used its budget or converged.
#include <gtest/gtest.h>

#include "progress.hpp"

namespace csympnet::cli {
namespace {

TEST(ProgressWords, StagesAreNamedInFull) {
  EXPECT_STREQ(stage_words("adamw"), "AdamW epoch");
  EXPECT_STREQ(stage_words("lm"), "Levenberg-Marquardt iteration");
  EXPECT_STREQ(stage_words("lbfgs"), "L-BFGS iteration");
  EXPECT_STREQ(stage_words("bootstrap"), "bootstrap replicate");
  EXPECT_STREQ(stage_words("other"), "other");
}

TEST(ProgressWords, AnEndOfBudgetOrAConvergenceIsSaidPlainly) {
  EXPECT_EQ(ending_words("maximum number of iterations reached"), "used the full iteration budget");
  EXPECT_EQ(ending_words("Maximum number of iterations reached. Number of iterations: 300."),
            "used the full iteration budget");
  EXPECT_EQ(ending_words("function tolerance reached"), "converged: the loss stopped changing");
  EXPECT_EQ(ending_words("Function tolerance reached. |cost_change|/cost: 1e-17"),
            "converged: the loss stopped changing");
  EXPECT_EQ(ending_words("gradient tolerance reached"), "converged: the gradient is negligible");
  EXPECT_EQ(ending_words("parameter tolerance reached"),
            "converged: the parameters stopped changing");
  EXPECT_EQ(ending_words("interrupted"), "interrupted");
}

TEST(ProgressWords, TheLmSummaryKeepsItsNumbers) {
  EXPECT_EQ(lm_summary_words(300, 290, 62, "maximum number of iterations reached"),
            "Levenberg-Marquardt: 300 iterations (290 accepted), used the full iteration budget; "
            "kept iterate 62, the best on held-out data");
}

}  // namespace
}  // namespace csympnet::cli
