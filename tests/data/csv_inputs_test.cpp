// Known inputs in CSV records (data/csv.hpp: columns u1..um after the states):
//   - positions and trajectories files with inputs read into Trajectory::u, with or without a
//     traj column, and written back to the bit;
//   - --columns maps a logger's input column (u1=volts_in);
//   - refused where they cannot be used, naming file, line and column: a NaN, a missing value, a
//     short row, inputs out of order, a pairs file with inputs, a reader that does not take
//     them, and pairs built from a driven trajectory.
#include <gtest/gtest.h>

#include <string>

#include "csympnet/core/error.hpp"
#include "csympnet/data/csv.hpp"
#include "csympnet/data/dataset.hpp"
#include "support/refusal.hpp"

namespace csympnet {
namespace {

#define EXPECT_REFUSED(call, words)                                         \
  EXPECT_NE(testing::refusal([&] { call; }).find(words), std::string::npos) \
      << testing::refusal([&] { call; })

TEST(CsvInputs, PositionsAndTrajectoriesCarryTheirInputs) {
  const auto pos = parse_positions_csv("t,q1,u1,u2\n0,1,0.5,-1\n0.1,0.9,0.25,2\n", "pos.csv",
                                       InputColumns::kRead);
  ASSERT_EQ(pos.size(), 1u);
  EXPECT_EQ(pos[0].z, (Matrix(1, 2) << 1, 0.9).finished());
  EXPECT_EQ(pos[0].u, (Matrix(2, 2) << 0.5, 0.25, -1, 2).finished());
  const std::string text = "traj,t,q1,p1,u1\n0,0,1,0,3\n0,0.1,0.9,-0.1,4\n1,0,2,1,5\n";
  const auto trajs = parse_trajectories_csv(text, "tr.csv", InputColumns::kRead);
  ASSERT_EQ(trajs.size(), 2u);
  EXPECT_EQ(trajs[0].u, (Matrix(1, 2) << 3, 4).finished());
  EXPECT_EQ(trajs[1].u, (Matrix(1, 1) << 5).finished());
  EXPECT_EQ(trajs[1].z, (Matrix(2, 1) << 2, 1).finished());
  // Written and read back to the bit, inputs included.
  const auto again =
      parse_trajectories_csv(trajectories_csv_text(trajs), "again.csv", InputColumns::kRead);
  ASSERT_EQ(again.size(), 2u);
  EXPECT_EQ(again[0].u, trajs[0].u);
  EXPECT_EQ(again[0].z, trajs[0].z);
  // A free record reads as before: no inputs.
  EXPECT_EQ(parse_positions_csv("t,q1\n0,1\n0.1,2\n", "f.csv", InputColumns::kRead)[0].u.size(), 0);
}

TEST(CsvInputs, ColumnsMapALoggersInputColumn) {
  const std::string file = "volts_in,time_s,angle,temp\n1.5,0,0.3,20\n-2,0.1,0.25,21\n";
  const ColumnMap m = parse_column_map("t=time_s,q1=angle,u1=volts_in");
  const std::string text = apply_column_map(file, "log.csv", m);
  EXPECT_EQ(text, "t,q1,u1\n0,0.3,1.5\n0.1,0.25,-2\n");
  const auto pos = parse_positions_csv(text, "log.csv", InputColumns::kRead);
  EXPECT_EQ(pos[0].u, (Matrix(1, 2) << 1.5, -2).finished());
  EXPECT_REFUSED(parse_column_map("w1=volts"), "the inputs u1..um");
}

TEST(CsvInputs, RefusedWithFileLineAndColumnWhereTheyCannotBeUsed) {
  const InputColumns read = InputColumns::kRead;
  EXPECT_REFUSED(parse_positions_csv("t,q1,u1\n0,1,0.5\n0.1,0.9,nan\n", "a.csv", read),
                 "a.csv:3: column 'u1': expected a finite number");
  EXPECT_REFUSED(parse_positions_csv("t,q1,u1\n0,1,\n", "b.csv", read),
                 "b.csv:2: column 'u1': expected a finite number");
  EXPECT_REFUSED(parse_positions_csv("t,q1,u1\n0,1,2\n0.1,0.9\n", "c.csv", read),
                 "c.csv:3: found 2 fields; expected 3");
  EXPECT_REFUSED(parse_positions_csv("t,q1,u2,u1\n0,1,2,3\n", "d.csv", read),
                 "header column 3 is 'u2'; expected 'u1'");
  EXPECT_REFUSED(parse_trajectories_csv("t,q1,u1,p1\n0,1,2,3\n", "e.csv", read),
                 "header column 3 is 'u1'; expected 'p1'");
  EXPECT_REFUSED(parse_pairs_csv("h,q1,p1,next_q1,next_p1,u1\n0.1,1,0,1,0,2\n", "f.csv"),
                 "a pair carries no inputs");
  // A reader whose consumer has no use for inputs refuses them rather than drop them.
  EXPECT_REFUSED(parse_positions_csv("t,q1,u1\n0,1,2\n", "g.csv"),
                 "g.csv:1: the header 't,q1,u1' has 1 input columns (u1..um), which this "
                 "command does not read");
  EXPECT_REFUSED(parse_trajectories_csv("t,q1,p1,u1\n0,1,2,3\n", "h.csv"),
                 "which this command does not read");
  EXPECT_REFUSED(parse_any_as_pairs("t,q1,p1,u1\n0,1,2,3\n0.1,1,2,3\n", "i.csv"),
                 "which this command does not read");
  const auto driven = parse_trajectories_csv("t,q1,p1,u1\n0,1,2,3\n0.1,1,2,3\n", "j.csv", read);
  EXPECT_REFUSED(pairs_from_trajectories(driven), "has 1 inputs; pairs carry none");
  // Inputs with the wrong number of samples.
  Trajectory bad = driven[0];
  bad.u = Matrix::Zero(1, 3);
  EXPECT_REFUSED(bad.validate("k"), "k: u has 3 columns but t has 2 entries");
}

}  // namespace
}  // namespace csympnet
