// OptionError and OptionRange: the library refuses an option by its key, and each front end
// spells that key (and the options a problem names) its own way.
#include "csympnet/core/options.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace csympnet {
namespace {

// Spellings like the CLI's and Python's, written here so the test does not depend on either.
const OptionSpelling kDashed{[](const std::string& k) {
                               std::string n = "--" + k;
                               for (char& c : n)
                                 if (c == '_') c = '-';
                               return n;
                             },
                             [](const std::string& k, const std::string& v) {
                               std::string n = "--" + k;
                               for (char& c : n)
                                 if (c == '_') c = '-';
                               return n + " " + v;
                             }};
const OptionSpelling kKeyword{
    [](const std::string& k) { return k; },
    [](const std::string& k, const std::string& v) { return k + "=\"" + v + "\""; }};

std::string options_refusal(const std::function<void()>& f) {
  try {
    f();
  } catch (const OptionError& e) {
    return e.message(kDashed);
  }
  return "";
}

TEST(OptionError, EachFrontEndSpellsTheOptionAndTheOnesItNames) {
  const OptionError e("refine_solver", "needs {refine=lm}: {refine=auto} chooses; see {seed}");
  EXPECT_EQ(e.key(), "refine_solver");
  EXPECT_EQ(e.message(kDashed),
            "--refine-solver: needs --refine lm: --refine auto chooses; see --seed");
  EXPECT_EQ(e.message(kKeyword),
            "refine_solver: needs refine=\"lm\": refine=\"auto\" chooses; see seed");
  // what(): the library's own spelling, for a C++ caller.
  EXPECT_STREQ(e.what(), "refine_solver: needs refine = lm: refine = auto chooses; see seed");
  // An Error like every other refusal, so existing handlers still catch it.
  EXPECT_THROW(throw OptionError("x", "y"), Error);
  // A brace left open is kept as text.
  EXPECT_EQ(OptionError("a", "b {c").message(kDashed), "--a: b {c");
}

TEST(OptionRange, SaysWhatItExpectsInPlainDigits) {
  EXPECT_EQ((OptionRange{.key = "lr", .lo = 1e-12, .hi = 10}).expected(),
            "a number from 1e-12 to 10");
  EXPECT_EQ((OptionRange{.key = "f", .lo = 0, .hi = 1, .lo_open = true}).expected(),
            "a number > 0 and <= 1");
  EXPECT_EQ(
      (OptionRange{.key = "w", .lo = 0, .hi = std::numeric_limits<double>::infinity()}).expected(),
      "a number >= 0");
  EXPECT_EQ(
      (OptionRange{.key = "b", .lo = 10, .hi = 1e6, .whole = true, .zero_means = "off"}).expected(),
      "0 (off) or a number from 10 to 1000000");
}

TEST(OptionRange, RefusesOutsideItsEndsNonFiniteAndFractionalWholeNumbers) {
  const OptionRange f{.key = "val_fraction", .lo = 0.01, .hi = 0.99};
  EXPECT_NO_THROW(f.check(0.01));
  EXPECT_NO_THROW(f.check(0.99));
  EXPECT_EQ(options_refusal([&] { f.check(1.0); }),
            "--val-fraction: '1' is out of range; expected a number from 0.01 to 0.99");
  // The value as its user wrote it, when given (the command-line word).
  EXPECT_EQ(options_refusal([&] { f.check(1.0, "1.000"); }),
            "--val-fraction: '1.000' is out of range; expected a number from 0.01 to 0.99");
  EXPECT_THROW(f.check(std::nan("")), OptionError);
  const OptionRange w{
      .key = "weight_decay", .lo = 0, .hi = std::numeric_limits<double>::infinity()};
  EXPECT_NO_THROW(w.check(1e300));
  EXPECT_THROW(w.check(std::numeric_limits<double>::infinity()), OptionError);
  const OptionRange open{.key = "f", .lo = 0, .hi = 1, .lo_open = true, .hi_open = true};
  EXPECT_THROW(open.check(0.0), OptionError);
  EXPECT_THROW(open.check(1.0), OptionError);
  EXPECT_NO_THROW(open.check(0.5));
  const OptionRange n{.key = "epochs", .lo = 1, .hi = 1e8, .whole = true};
  EXPECT_NO_THROW(n.check(100000000L));
  EXPECT_EQ(options_refusal([&] { n.check(0L); }),
            "--epochs: '0' is out of range; expected a number from 1 to 100000000");
  EXPECT_THROW(n.check(100000001L), OptionError);
  EXPECT_THROW(n.check(2.5), OptionError);
  // Longs past 2^53 are compared exactly, not after rounding to a double.
  const OptionRange big{.key = "k", .lo = 0, .hi = 9007199254740992.0, .whole = true};
  EXPECT_THROW(big.check(9007199254740993L), OptionError);
}

TEST(OptionRange, ZeroCanStandForOffAndTheReasonFollowsARefusal) {
  const OptionRange b{.key = "bootstrap",
                      .lo = 10,
                      .hi = 1e6,
                      .whole = true,
                      .zero_means = "off",
                      .why = "a percentile interval needs at least 10 replicates"};
  EXPECT_NO_THROW(b.check(0L));
  EXPECT_NO_THROW(b.check(10L));
  EXPECT_EQ(options_refusal([&] { b.check(5L); }),
            "--bootstrap: '5' is out of range; expected 0 (off) or a number from 10 to 1000000: "
            "a percentile interval needs at least 10 replicates");
  EXPECT_THROW(b.check(-1L), OptionError);
}

TEST(OptionChecks, NonzeroAndChoices) {
  EXPECT_NO_THROW(check_nonzero("beta_init", -0.1));
  EXPECT_EQ(options_refusal([] { check_nonzero("beta_init", 0.0); }),
            "--beta-init: '0' is zero; expected a nonzero number");
  EXPECT_EQ(options_refusal([] { check_nonzero("beta_init", -0.0, "-0.0"); }),
            "--beta-init: '-0.0' is zero; expected a nonzero number");
  EXPECT_THROW(check_nonzero("beta_init", std::numeric_limits<double>::infinity()), OptionError);
  const std::vector<std::string> names = {"a", "b"};
  EXPECT_EQ(choice_index("k", names, "b"), 1u);
  EXPECT_EQ(options_refusal([&] { choice_index("some_key", names, "c"); }),
            "--some-key: 'c' is not a choice; expected one of a, b");
}

}  // namespace
}  // namespace csympnet
