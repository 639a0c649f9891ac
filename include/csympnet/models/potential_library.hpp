// The library of the Hamiltonian-library core (docs/derivations.md, "The Hamiltonian-library
// core"): potentials V(q) = Σ_k c_k φ_k(q) built from a few general families of terms, each a
// function of one coordinate q_i or of one difference q_i − q_j:
//
//   power      u^n, n = 1..4 of q_i; n = 2..4 of q_i − q_j   ("q1", "q1^3", "(q1-q2)^4")
//   sin, cos   sin(κ u), cos(κ u)                             ("sin(q1)", "cos(q1-q2)")
//   exp        exp(κ u), κ starting at +1 or −1               ("exp(q1)", "exp(-q1)",
//                                                               "exp(q1-q2)", "exp(q2-q1)")
//
// The wavenumber κ of a sin, cos or exp term is a parameter of its own (users' units are
// arbitrary: degrees, millimetres, pixels), so the name gives the term's shape and its
// starting sign, not the value of κ. Powers need none: a polynomial of degree ≤ 4 stays one
// under any change of origin and scale, and so does each family above with a learned κ.
//
// To extend the library, add a TermShape, its name in term_name()/parse_term() and its
// derivatives in term_values(); the map and the selection take any term through these.
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include "csympnet/core/types.hpp"

namespace csympnet {

enum class TermShape { kPower, kSin, kCos, kExp };

struct LibraryTerm {
  Index i = 0;   // the coordinate, 0-based
  Index j = -1;  // for a difference q_i − q_j, the second coordinate; else −1
  TermShape shape = TermShape::kPower;
  int power = 2;            // kPower: 1..4 (2..4 for a difference)
  double kappa_sign = 1.0;  // kSin, kCos, kExp: the sign κ starts with
  bool has_wavenumber() const { return shape != TermShape::kPower; }
  bool operator==(const LibraryTerm&) const = default;
};

// The term's name, 1-based as users number coordinates: "q1^2", "q1", "(q1-q2)^4",
// "sin(q1)", "cos(q1-q2)", "exp(q1)", "exp(-q1)", "exp(q2-q1)".
std::string term_name(const LibraryTerm& t);
// The inverse of term_name() for d coordinates; throws Error naming `where`, the text and the
// accepted forms.
LibraryTerm parse_term(const std::string& name, Index d, const std::string& where);

// The full library for d coordinates: per coordinate the powers 1..4, sin, cos, exp(±); per
// pair (all pairs up to d = 4, neighbours i, i+1 beyond: the library grows as d² otherwise)
// the powers 2..4 of the difference, its sin and cos, and exp of it in both directions.
std::vector<LibraryTerm> full_library(Index d);

// φ and its derivatives at the argument u (q_i or q_i − q_j) and wavenumber κ (ignored by a
// power): φ, dφ/du, d²φ/du², and ∂(dφ/du)/∂κ.
struct TermValues {
  double phi = 0.0;
  double d1 = 0.0;
  double d2 = 0.0;
  double d1_kappa = 0.0;
  double phi_kappa = 0.0;  // ∂φ/∂κ
};

// A sin (`shape` kSin) or cos term's values from s = sin(κu) and c = cos(κu): a sin and a cos
// of one argument share their wavenumber, so a caller that evaluates both needs one sin and one
// cos (the values are term_values()'s to the bit).
inline TermValues sinusoid_values(TermShape shape, double u, double kappa, double s, double c) {
  TermValues v;
  if (shape == TermShape::kSin) {
    v.phi = s;
    v.d1 = kappa * c;
    v.d2 = -kappa * kappa * s;
    v.d1_kappa = c - kappa * u * s;
    v.phi_kappa = u * c;
  } else {
    v.phi = c;
    v.d1 = -kappa * s;
    v.d2 = -kappa * kappa * c;
    v.d1_kappa = -s - kappa * u * c;
    v.phi_kappa = -u * s;
  }
  return v;
}

// Inline: a library map evaluates it once per term at every stage of every step.
inline TermValues term_values(const LibraryTerm& t, double u, double kappa) {
  switch (t.shape) {
    case TermShape::kPower: {
      const double u2 = u * u;
      switch (t.power) {
        case 1:
          return {u, 1.0, 0.0, 0.0, 0.0};
        case 2:
          return {u2, 2.0 * u, 2.0, 0.0, 0.0};
        case 3:
          return {u2 * u, 3.0 * u2, 6.0 * u, 0.0, 0.0};
        default:
          return {u2 * u2, 4.0 * u2 * u, 12.0 * u2, 0.0, 0.0};
      }
    }
    case TermShape::kSin:
    case TermShape::kCos:
      return sinusoid_values(t.shape, u, kappa, std::sin(kappa * u), std::cos(kappa * u));
    case TermShape::kExp: {
      const double e = std::exp(kappa * u);
      return {e, kappa * e, kappa * kappa * e, e * (1.0 + kappa * u), u * e};
    }
  }
  return {};
}

// The argument u of term t at positions q (d values).
inline double term_argument(const LibraryTerm& t, const double* q) {
  return t.j < 0 ? q[t.i] : q[t.i] - q[t.j];
}

}  // namespace csympnet
