// The model-selection table (src/identify/identify_selection.cpp) read from the stages'
// records: which side is "chosen", the runner-up, and the margin in the criterion's unit.
#include <gtest/gtest.h>

#include <cmath>

#include "csympnet/identify/identify.hpp"

namespace csympnet {
namespace {

// The selection table from the stages' records: the positions' core choice names the library's
// terms and measures the runner-up in standard errors of the chosen loss; a term family's row
// turns with the side kept (a trial's bic_change is BIC(powers) − BIC(group)).
TEST(IdentifySelection, RowsFollowTheRecordsSides) {
  IdentifyResult r;
  r.observed = "positions";
  const nlohmann::json lib = {{"type", "library"}, {"terms", {"q1^2", "cos(q1)"}}};
  nlohmann::json& p = r.choices["positions"];
  p["core_choice"] = {{"validation_residuals", 200.0},
                      {"candidates",
                       {{{"model", {{"type", "la"}, {"layers", 3}, {"sublayers", 8}}},
                         {"held_out_position_loss", 1.3},
                         {"chosen", false}},
                        {{"model", lib}, {"held_out_position_loss", 1.2}, {"chosen", true}}}}};
  // Two swaps tried on the linked chain: the exp group's made, the sin/cos group's not.
  p["polynomial_preferred"] = {{"residuals", 500},
                               {"trials",
                                {{{"term", "sin(q1), cos(q1)"},
                                  {"replaced_by", "q1^4"},
                                  {"loss_before", 1.0},
                                  {"loss_after", 1.1},
                                  {"bic_change", 7.5}},
                                 {{"term", "exp(q1)"},
                                  {"replaced_by", "q1^3"},
                                  {"loss_before", 1.0},
                                  {"loss_after", 1.001},
                                  {"bic_change", -4.0}},
                                 {{"dropped", "exp(q1)"}, {"bic_change", -4.0}},
                                 {{"term", "sin(q1), cos(q1)"},
                                  {"replaced_by", "q1^4"},
                                  {"loss_before", 1.001},
                                  {"loss_after", 1.2},
                                  {"bic_change", 9.0}}}}};
  const nlohmann::json rows = model_selection(r);
  ASSERT_EQ(rows.size(), 3u) << rows.dump(1);
  EXPECT_EQ(rows[0]["chosen"], "library (q1^2, cos(q1))");
  EXPECT_EQ(rows[0]["runner_up"], "la:3:8");
  EXPECT_NEAR(rows[0]["margin"].get<double>(), 0.1 / (1.2 * std::sqrt(2.0 / 200.0)), 1e-12);
  // The last trial of each group decides its row.
  EXPECT_EQ(rows[1]["chosen"], "sin(q1), cos(q1)");
  EXPECT_EQ(rows[1]["runner_up"], "q1^4 instead of sin(q1), cos(q1)");
  EXPECT_EQ(rows[1]["chosen_value"], 1.001);
  EXPECT_EQ(rows[1]["runner_up_value"], 1.2);
  EXPECT_EQ(rows[1]["margin"], 9.0);
  EXPECT_EQ(rows[2]["chosen"], "q1^3 instead of exp(q1)");
  EXPECT_EQ(rows[2]["runner_up"], "exp(q1)");
  EXPECT_EQ(rows[2]["chosen_value"], 1.001);
  EXPECT_EQ(rows[2]["margin"], 4.0);
  // A record with momenta reads no positions stage.
  r.observed = "positions and momenta";
  EXPECT_TRUE(model_selection(r).empty());
}

// With momenta: the group kept in a round against the best other group of that round, a last
// round that kept none against its best group, and each friction kind tried or pruned as
// "with" against "without".
TEST(IdentifySelection, WindowsRoundsAndFrictionKinds) {
  IdentifyResult r;
  nlohmann::json& lib = r.choices["library"];
  lib["forward"] = {
      {{"terms", "q1^3, q1^4"}, {"val_loss_before", 2.0}, {"val_loss_after", 1.5}},
      {{"terms", "sin(q1), cos(q1)"}, {"val_loss_before", 2.0}, {"val_loss_after", 1.2}},
      {{"kept", "sin(q1), cos(q1)"}, {"val_loss", 1.2}},
      {{"terms", "exp(q1)"}, {"val_loss_before", 1.2}, {"val_loss_after", 1.19}},
      {{"terms", "q1^3, q1^4"}, {"val_loss_before", 1.2}, {"val_loss_after", 1.18}}};
  lib["dissipation"]["rounds"] = {
      {{"when", "after the start"},
       {"tried", "coulomb"},
       {"earns_its_place", true},
       {"val_loss_before", 4.0},
       {"val_loss_after", 1.0}},
      {{"when", "after the start"}, {"decision", "none added"}, {"val_loss_before", 1.0}},
      {{"when", "pruning"},
       {"tried_without", "drag"},
       {"dropped", true},
       {"val_loss_before", 1.0},
       {"val_loss_after", 1.001}}};
  const nlohmann::json rows = model_selection(r);
  ASSERT_EQ(rows.size(), 4u) << rows.dump(1);
  EXPECT_EQ(rows[0]["chosen"], "sin(q1), cos(q1)");
  EXPECT_EQ(rows[0]["runner_up"], "q1^3, q1^4");
  EXPECT_NEAR(rows[0]["margin"].get<double>(), 1.5 / 1.2 - 1.0, 1e-15);
  EXPECT_EQ(rows[1]["chosen"], "none");
  EXPECT_EQ(rows[1]["runner_up"], "q1^3, q1^4");
  EXPECT_NEAR(rows[1]["margin"].get<double>(), 1.18 / 1.2 - 1.0, 1e-15);
  EXPECT_EQ(rows[2]["chosen"], "with Coulomb friction");
  EXPECT_NEAR(rows[2]["margin"].get<double>(), 3.0, 1e-15);
  EXPECT_EQ(rows[3]["chosen"], "without quadratic drag");
  EXPECT_EQ(rows[3]["chosen_value"], 1.001);
  EXPECT_NEAR(rows[3]["margin"].get<double>(), 1.0 / 1.001 - 1.0, 1e-15);
}

}  // namespace
}  // namespace csympnet
