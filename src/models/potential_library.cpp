#include "csympnet/models/potential_library.hpp"

#include <cmath>
#include <regex>

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

LibraryTerm parse_term(const std::string& name, Index d, const std::string& where) {
  const auto refuse = [&](const std::string& why) -> Error {
    return Error(where + ": term '" + name + "': " + why +
                 "; expected one of qI, qI^N (N = 2..4), (qI-qJ)^N, sin(qI), cos(qI), "
                 "sin(qI-qJ), cos(qI-qJ), exp(qI), exp(-qI), exp(qI-qJ), with I, J in 1.." +
                 std::to_string(d) + " and I != J");
  };
  static const std::regex power(R"(q(\d+)(\^(\d))?)");
  static const std::regex diff_power(R"(\(q(\d+)-q(\d+)\)\^(\d))");
  static const std::regex func(R"((sin|cos|exp)\((-?)q(\d+)(-q(\d+))?\))");
  std::smatch m;
  LibraryTerm t;
  const auto index = [&](const std::string& s) {
    const long v = std::stol(s);
    if (v < 1 || v > d) throw refuse("coordinate " + s + " out of range");
    return static_cast<Index>(v - 1);
  };
  if (std::regex_match(name, m, power)) {
    t.i = index(m[1]);
    t.power = m[3].matched ? std::stoi(m[3]) : 1;
    if (t.power < 1 || t.power > 4) throw refuse("power out of range");
  } else if (std::regex_match(name, m, diff_power)) {
    t.i = index(m[1]);
    t.j = index(m[2]);
    t.power = std::stoi(m[3]);
    if (t.power < 2 || t.power > 4) throw refuse("a difference's power must be 2..4");
  } else if (std::regex_match(name, m, func)) {
    const std::string f = m[1];
    t.shape = f == "sin" ? TermShape::kSin : f == "cos" ? TermShape::kCos : TermShape::kExp;
    t.power = 0;
    t.i = index(m[3]);
    if (m[5].matched) t.j = index(m[5]);
    if (m[2].length() > 0) {
      if (t.shape != TermShape::kExp || t.j >= 0) throw refuse("a minus sign only in exp(-qI)");
      t.kappa_sign = -1.0;
    }
  } else {
    throw refuse("not a library term");
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

TermValues term_values(const LibraryTerm& t, double u, double kappa) {
  TermValues v;
  switch (t.shape) {
    case TermShape::kPower: {
      const int n = t.power;
      const double u2 = u * u;
      switch (n) {
        case 1:
          v = {u, 1.0, 0.0, 0.0, 0.0};
          break;
        case 2:
          v = {u2, 2.0 * u, 2.0, 0.0, 0.0};
          break;
        case 3:
          v = {u2 * u, 3.0 * u2, 6.0 * u, 0.0, 0.0};
          break;
        default:
          v = {u2 * u2, 4.0 * u2 * u, 12.0 * u2, 0.0, 0.0};
          break;
      }
      return v;
    }
    case TermShape::kSin: {
      const double s = std::sin(kappa * u), c = std::cos(kappa * u);
      v.phi = s;
      v.d1 = kappa * c;
      v.d2 = -kappa * kappa * s;
      v.d1_kappa = c - kappa * u * s;
      v.phi_kappa = u * c;
      return v;
    }
    case TermShape::kCos: {
      const double s = std::sin(kappa * u), c = std::cos(kappa * u);
      v.phi = c;
      v.d1 = -kappa * s;
      v.d2 = -kappa * kappa * c;
      v.d1_kappa = -s - kappa * u * c;
      v.phi_kappa = -u * s;
      return v;
    }
    case TermShape::kExp: {
      const double e = std::exp(kappa * u);
      v.phi = e;
      v.d1 = kappa * e;
      v.d2 = kappa * kappa * e;
      v.d1_kappa = e * (1.0 + kappa * u);
      v.phi_kappa = u * e;
      return v;
    }
  }
  return v;
}

}  // namespace csympnet
