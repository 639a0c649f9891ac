#include "csympnet/models/potential_library.hpp"

#include <cmath>
#include <string_view>
#include <utility>

#include "csympnet/core/error.hpp"

namespace csympnet {

namespace {

std::string coordinate(Index i) {
  return "q" + std::to_string(i + 1);
}

std::string argument(const LibraryTerm& t) {
  if (t.j < 0) return coordinate(t.i);
  return coordinate(t.i) + "-" + coordinate(t.j);
}

}  // namespace

std::string term_name(const LibraryTerm& t) {
  switch (t.shape) {
    case TermShape::kPower: {
      const std::string base = t.j < 0 ? argument(t) : "(" + argument(t) + ")";
      return t.power == 1 ? base : base + "^" + std::to_string(t.power);
    }
    case TermShape::kSin:
      return "sin(" + argument(t) + ")";
    case TermShape::kCos:
      return "cos(" + argument(t) + ")";
    case TermShape::kExp:
      if (t.kappa_sign > 0.0) return "exp(" + argument(t) + ")";
      // A difference in the other direction reads as that difference; a coordinate, as −q.
      if (t.j >= 0) return "exp(" + coordinate(t.j) + "-" + coordinate(t.i) + ")";
      return "exp(-" + coordinate(t.i) + ")";
  }
  return "?";
}

namespace {

// A name as a message quotes it: a long one cut to its first 40 characters (a name of 50,000
// digits is one line of an error, not 50 kB of it).
std::string quoted_name(const std::string& name) {
  constexpr std::size_t kShown = 40;
  return name.size() <= kShown ? name : name.substr(0, kShown) + "\u2026";
}

// A left-to-right reading of one name: no recursion and no allocation per character, so a name
// of any length costs its length (std::regex_match recursed per character and overflowed the
// stack past about 30,000). The grammar is the one term_name() writes:
//   qI | qI^N | (qI-qJ)^N | F(qI) | F(-qI) | F(qI-qJ),  F in sin, cos, exp,  N one digit.
class NameReader {
 public:
  explicit NameReader(const std::string& text) : s_(text) {}
  bool at_end() const { return at_ == s_.size(); }
  bool eat(std::string_view literal) {
    if (s_.compare(at_, literal.size(), literal) != 0) return false;
    at_ += literal.size();
    return true;
  }
  // "q" and one or more digits; the digits' text in `digits`.
  bool coordinate(std::string_view& digits) {
    if (!eat("q")) return false;
    const std::size_t from = at_;
    while (at_ < s_.size() && s_[at_] >= '0' && s_[at_] <= '9') ++at_;
    digits = std::string_view(s_).substr(from, at_ - from);
    return !digits.empty();
  }
  bool digit(int& value) {
    if (at_ >= s_.size() || s_[at_] < '0' || s_[at_] > '9') return false;
    value = s_[at_++] - '0';
    return true;
  }

 private:
  const std::string& s_;
  std::size_t at_ = 0;
};

struct ParsedName {
  TermShape shape = TermShape::kPower;
  std::string_view first, second;  // the coordinates' digits (second empty: one coordinate)
  int power = 1;
  bool minus = false;  // F(-qI)
};

bool read_name(const std::string& name, ParsedName& out) {
  NameReader r(name);
  for (const auto& [f, shape] :
       {std::pair{"sin(", TermShape::kSin}, std::pair{"cos(", TermShape::kCos},
        std::pair{"exp(", TermShape::kExp}}) {
    if (!r.eat(f)) continue;
    out.shape = shape;
    out.power = 0;
    out.minus = r.eat("-");
    if (!r.coordinate(out.first)) return false;
    if (r.eat("-") && !r.coordinate(out.second)) return false;
    return r.eat(")") && r.at_end();
  }
  if (r.eat("(")) {
    return r.coordinate(out.first) && r.eat("-") && r.coordinate(out.second) && r.eat(")^") &&
           r.digit(out.power) && r.at_end();
  }
  if (!r.coordinate(out.first)) return false;
  if (r.eat("^") && !r.digit(out.power)) return false;
  return r.at_end();
}

}  // namespace

LibraryTerm parse_term(const std::string& name, Index d, const std::string& where) {
  const auto refuse = [&](const std::string& why) -> Error {
    return Error(where + ": term '" + quoted_name(name) + "': " + why +
                 "; expected one of qI, qI^N (N = 2..4), (qI-qJ)^N, sin(qI), cos(qI), "
                 "sin(qI-qJ), cos(qI-qJ), exp(qI), exp(-qI), exp(qI-qJ), with I, J in 1.." +
                 std::to_string(d) + " and I != J");
  };
  ParsedName parsed;
  if (!read_name(name, parsed)) throw refuse("not a library term");
  // 1..d, read without std::stol: digits past any d (hundreds of them) are out of range, not
  // an exception of the standard library.
  const auto index = [&](std::string_view digits) {
    Index v = 0;
    for (const char c : digits) {
      v = v * 10 + (c - '0');
      if (v > d) throw refuse("coordinate " + quoted_name(std::string(digits)) + " out of range");
    }
    if (v < 1) throw refuse("coordinate " + std::string(digits) + " out of range");
    return v - 1;
  };
  LibraryTerm t;
  t.shape = parsed.shape;
  t.power = parsed.power;
  t.i = index(parsed.first);
  if (!parsed.second.empty()) t.j = index(parsed.second);
  if (t.shape == TermShape::kPower) {
    if (t.j < 0 && (t.power < 1 || t.power > 4)) throw refuse("power out of range");
    if (t.j >= 0 && (t.power < 2 || t.power > 4)) throw refuse("a difference's power must be 2..4");
  } else if (parsed.minus) {
    if (t.shape != TermShape::kExp || t.j >= 0) throw refuse("a minus sign only in exp(-qI)");
    t.kappa_sign = -1.0;
  }
  if (t.j == t.i) throw refuse("a difference of a coordinate with itself");
  // exp(qJ-qI) with J < I is stored as the difference (qI − qJ) with κ starting negative.
  if (t.shape == TermShape::kExp && t.j >= 0 && t.j < t.i) {
    std::swap(t.i, t.j);
    t.kappa_sign = -1.0;
  }
  if (t.shape != TermShape::kExp && t.shape != TermShape::kPower && t.j >= 0 && t.j < t.i)
    std::swap(t.i, t.j);  // sin, cos of qJ − qI: the same family as of qI − qJ
  if (t.shape == TermShape::kPower && t.j >= 0 && t.j < t.i) std::swap(t.i, t.j);
  if (term_name(t) != name) throw refuse("write it as '" + term_name(t) + "'");
  return t;
}

std::vector<LibraryTerm> full_library(Index d) {
  require(d >= 1, "full_library: d must be >= 1");
  std::vector<LibraryTerm> lib;
  const auto functions = [&lib](Index i, Index j) {
    lib.push_back({i, j, TermShape::kSin, 0, 1.0});
    lib.push_back({i, j, TermShape::kCos, 0, 1.0});
    lib.push_back({i, j, TermShape::kExp, 0, 1.0});
    lib.push_back({i, j, TermShape::kExp, 0, -1.0});
  };
  for (Index i = 0; i < d; ++i) {
    for (int n = 1; n <= 4; ++n) lib.push_back({i, -1, TermShape::kPower, n, 1.0});
    functions(i, -1);
  }
  for (Index i = 0; i < d; ++i)
    for (Index j = i + 1; j < d; ++j) {
      if (d > 4 && j != i + 1) continue;
      for (int n = 2; n <= 4; ++n) lib.push_back({i, j, TermShape::kPower, n, 1.0});
      functions(i, j);
    }
  return lib;
}

}  // namespace csympnet
