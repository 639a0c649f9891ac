// Column maps (data/csv.hpp: parse_column_map, apply_column_map): a file's own header names.
#include <gtest/gtest.h>

#include <string>

#include "csympnet/core/error.hpp"
#include "csympnet/data/csv.hpp"
#include "support/refusal.hpp"

namespace csympnet {
namespace {

TEST(ColumnMap, ParsesEntriesAndRefusesWhatItCannotMean) {
  const ColumnMap m = parse_column_map("t=time_s, q1 = angle,p1=velocity");
  ASSERT_EQ(m.columns.size(), 3u);
  EXPECT_EQ(m.columns[1], (std::pair<std::string, std::string>{"q1", "angle"}));
  EXPECT_TRUE(parse_column_map("").empty());
  EXPECT_NE(testing::refusal([] { parse_column_map("t=time,q1"); }).find("'q1' is not NAME=COLUMN"),
            std::string::npos);
  EXPECT_NE(testing::refusal([] {
              parse_column_map("x=time");
            }).find("'x' is not a column csympnet reads"),
            std::string::npos);
  EXPECT_NE(testing::refusal([] { parse_column_map("q0=a"); }).find("is not a column"),
            std::string::npos);
  EXPECT_NE(testing::refusal([] { parse_column_map("q1=a,q1=b"); }).find("q1 is mapped twice"),
            std::string::npos);
  EXPECT_NE(testing::refusal([] { parse_column_map("q1=a,p1=a"); }).find("'a' is mapped twice"),
            std::string::npos);
  EXPECT_NE(testing::refusal([] { parse_column_map("t=", "--cols"); }).find("--cols: "),
            std::string::npos);
}

TEST(ColumnMap, RenamesReordersAndDropsColumnsKeepingLineNumbers) {
  const std::string file =
      "omega,temperature,time,theta\r\n"
      "0.5,20.1,0,1.0\r\n"
      "0.25,20.2,0.1,0.9\r\n";
  const ColumnMap m = parse_column_map("t=time,q1=theta,p1=omega");
  const std::string text = apply_column_map(file, "lab.csv", m);
  EXPECT_EQ(text, "t,q1,p1\n0,1.0,0.5\n0.1,0.9,0.25\n");
  // It reads like the canonical file, to the bit.
  const auto mapped = parse_trajectories_csv(text, "lab.csv");
  const auto canonical = parse_trajectories_csv("t,q1,p1\n0,1.0,0.5\n0.1,0.9,0.25\n", "c.csv");
  ASSERT_EQ(mapped.size(), 1u);
  EXPECT_EQ(mapped[0].z, canonical[0].z);
  EXPECT_EQ(mapped[0].t, canonical[0].t);
  // A bad value further down is still reported at its line of the user's file.
  const std::string bad = apply_column_map(file + "abc,1,0.2,0.8\n", "lab.csv", m);
  EXPECT_NE(testing::refusal([&] { parse_trajectories_csv(bad, "lab.csv"); }).find("lab.csv:4:"),
            std::string::npos);
  // So is a blank line in the middle, which the readers refuse where it is.
  const std::string gap = apply_column_map("time,theta,omega\n0,1,2\n\n0.1,1,2\n", "g.csv", m);
  EXPECT_NE(
      testing::refusal([&] { parse_trajectories_csv(gap, "g.csv"); }).find("g.csv:3: blank line"),
      std::string::npos);
}

TEST(ColumnMap, KeepsCanonicalColumnsItDoesNotMapAndReadsPairs) {
  // q1 and p1 are already csympnet's; only the time column has its own name.
  EXPECT_EQ(apply_column_map("p1,q1,clock\n1,2,0\n", "f.csv", parse_column_map("t=clock")),
            "t,q1,p1\n0,2,1\n");
  // A canonical name that the map gives to another column is the map's.
  EXPECT_EQ(apply_column_map("t,q1,p1,seconds\n9,2,1,0\n", "f.csv", parse_column_map("t=seconds")),
            "t,q1,p1\n0,2,1\n");
  const std::string pairs =
      apply_column_map("step,x,v,x_next,v_next\n0.1,1,0,0.99,-0.1\n", "p.csv",
                       parse_column_map("h=step,q1=x,p1=v,next_q1=x_next,next_p1=v_next"));
  EXPECT_EQ(pairs, "h,q1,p1,next_q1,next_p1\n0.1,1,0,0.99,-0.1\n");
  EXPECT_EQ(parse_pairs_csv(pairs, "p.csv").size(), 1);
  // Two degrees of freedom, ordered q1 q2 p1 p2 whatever the file's order.
  EXPECT_EQ(apply_column_map("a,b,c,d,e\n1,2,3,4,5\n", "f.csv",
                             parse_column_map("p2=a,q2=b,t=c,p1=d,q1=e")),
            "t,q1,q2,p1,p2\n3,5,2,4,1\n");
}

TEST(ColumnMap, RefusesAMissingOrRepeatedColumnAndARaggedRowNamingFileAndLine) {
  const ColumnMap m = parse_column_map("t=time,q1=theta,p1=omega");
  const std::string missing =
      testing::refusal([&] { apply_column_map("time,angle,omega\n0,1,2\n", "lab.csv", m); });
  EXPECT_NE(missing.find("lab.csv:1: --columns maps q1 to 'theta', which is not a column of the "
                         "header; expected one of 'time', 'angle', 'omega'"),
            std::string::npos)
      << missing;
  EXPECT_NE(testing::refusal([&] {
              apply_column_map("time,theta,omega,theta\n0,1,2,3\n", "lab.csv", m);
            }).find("lab.csv:1: column 'theta' appears twice"),
            std::string::npos);
  EXPECT_NE(testing::refusal([&] {
              apply_column_map("time,theta,omega\n0,1,2\n0.1,1\n", "lab.csv", m);
            }).find("lab.csv:3: 2 fields; expected 3 as in the header"),
            std::string::npos);
  // An empty map changes nothing, not even bytes the readers would refuse.
  EXPECT_EQ(apply_column_map("x\xff", "f.csv", ColumnMap{}), "x\xff");
}

}  // namespace
}  // namespace csympnet
