// require(): a message given as a callable is built only when its check fails, so the checks
// on hot paths (every forward/backward shape check, every pair of a data check) cost no
// allocation when they pass.
#include <string>

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "csympnet/data/dataset.hpp"

namespace csympnet {
namespace {

TEST(Require, BuildsALazyMessageOnlyOnFailure) {
  int built = 0;
  const auto message = [&] {
    ++built;
    return std::string("x = ") + std::to_string(3) + ", expected 4";
  };
  for (int k = 0; k < 1000; ++k) require(true, message);
  EXPECT_EQ(built, 0);
  try {
    require(false, message);
    FAIL() << "require(false, ...) did not throw";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "x = 3, expected 4");
  }
  EXPECT_EQ(built, 1);
}

TEST(Require, LiteralAndBuiltMessagesThrowTheirText) {
  EXPECT_NO_THROW(require(true, "never shown"));
  try {
    require(false, "a literal");
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "a literal");
  }
  const std::string built = "built " + std::to_string(7);
  try {
    require(false, built);
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "built 7");
  }
}

// PairSet::validate runs on every residual evaluation of the second stage; its per-pair
// message must still name the pair when a step is bad.
TEST(Require, PairChecksStillNameTheBadPair) {
  PairSet p;
  p.z0 = Matrix::Zero(2, 3);
  p.z1 = Matrix::Zero(2, 3);
  p.h = Vector::Constant(3, 0.1);
  EXPECT_NO_THROW(p.validate("pairs"));
  p.h(2) = -0.5;
  try {
    p.validate("pairs");
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "pairs: h[2] = -0.5 must be > 0");
  }
}

// A message's list: ", " between items, nothing around them.
TEST(Messages, CommaSeparatedLists) {
  EXPECT_EQ(comma_separated({}), "");
  EXPECT_EQ(comma_separated({"s1"}), "s1");
  EXPECT_EQ(comma_separated({"s1", "s2", "large"}), "s1, s2, large");
  EXPECT_EQ(comma_separated({"", "a"}), ", a");
}

}  // namespace
}  // namespace csympnet
