// The --columns suggested for a header csympnet does not read: positions unless a name says
// velocity or momentum, and the message says positions alone are read.
#include "../src/data/column_hint.hpp"

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "csympnet/data/csv.hpp"

namespace csympnet {
namespace {

using csv_detail::ColumnRole;
using csv_detail::columns_example;
using csv_detail::guess_column_role;

std::string hint(std::vector<std::string_view> names) {
  return columns_example(names);
}

TEST(ColumnHint, UnknownNamesArePositions) {
  // Two carts in pixels: both positions, never a position read as a momentum.
  EXPECT_EQ(hint({"timestamp_s", "left_cart_px", "right_cart_px"}),
            "--columns t=timestamp_s,q1=left_cart_px,q2=right_cart_px");
  EXPECT_EQ(hint({"t_ms", "encoder"}), "--columns t=t_ms,q1=encoder");
  EXPECT_EQ(hint({"a", "b", "c", "d"}), "--columns t=a,q1=b,q2=c,q3=d");
}

TEST(ColumnHint, VelocityAndMomentumNamesArePaired) {
  EXPECT_EQ(hint({"time_s", "angle_deg", "omega_degps"}),
            "--columns t=time_s,q1=angle_deg,p1=omega_degps");
  EXPECT_EQ(hint({"x", "y", "x_vel", "yDot", "t"}), "--columns t=t,q1=x,q2=y,p1=x_vel,p2=yDot");
  EXPECT_EQ(hint({"traj_id", "t (ms)", "theta", "thetadot"}),
            "--columns traj=traj_id,t=t (ms),q1=theta,p1=thetadot");
  // A velocity beside two positions does not pair: all three are read as positions.
  EXPECT_EQ(hint({"t", "x1", "x2", "v"}), "--columns t=t,q1=x1,q2=x2,q3=v");
}

TEST(ColumnHint, Roles) {
  EXPECT_EQ(guess_column_role("t[s]"), ColumnRole::kTime);
  EXPECT_EQ(guess_column_role("time_ms"), ColumnRole::kTime);
  EXPECT_EQ(guess_column_role("px"), ColumnRole::kPosition);
  EXPECT_EQ(guess_column_role("p2"), ColumnRole::kMomentum);
  EXPECT_EQ(guess_column_role("v1"), ColumnRole::kMomentum);
  EXPECT_EQ(guess_column_role("angular_velocity_deg_s"), ColumnRole::kMomentum);
  EXPECT_EQ(guess_column_role("cart_momentum"), ColumnRole::kMomentum);
  EXPECT_EQ(guess_column_role("trajectory"), ColumnRole::kTraj);
}

TEST(ColumnHint, ReaderMessageSaysPositionsAloneAreRead) {
  for (const char* text : {"timestamp_s,left_cart_px,right_cart_px\n0,1,2\n", "t_ms,encoder\n0,1\n",
                           "t,encoder\n0,1\n"}) {
    std::string what;
    try {
      parse_any_as_pairs(text, "d.csv");
    } catch (const Error& e) {
      what = e.what();
    }
    EXPECT_NE(what.find("positions alone '[traj,]t,q1..qd'"), std::string::npos) << what;
    EXPECT_EQ(what.find(",p1="), std::string::npos) << what;
    EXPECT_NE(what.find("--columns t="), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace csympnet
