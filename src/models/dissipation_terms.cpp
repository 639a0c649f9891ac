#include "csympnet/models/dissipation_terms.hpp"

#include <cmath>
#include <limits>

#include "csympnet/core/error.hpp"

namespace csympnet {

std::string dissipation_kind_name(DissipationKind kind) {
  return kind == DissipationKind::kCoulomb ? "coulomb" : "drag";
}

std::string dissipation_name(const DissipationTerm& t) {
  return dissipation_kind_name(t.kind) + "(p" + std::to_string(t.i + 1) + ")";
}

DissipationTerm parse_dissipation(const std::string& name, Index d, const std::string& where) {
  const auto refuse = [&](const std::string& why) {
    const std::string shown = name.size() <= 40 ? name : name.substr(0, 40) + "...";
    return Error(where + ": '" + shown + "': " + why +
                 "; expected coulomb(pI) or drag(pI) with I in 1.." + std::to_string(d));
  };
  DissipationTerm t;
  std::size_t open = 0;
  if (name.rfind("coulomb(p", 0) == 0) {
    t.kind = DissipationKind::kCoulomb;
    open = 9;
  } else if (name.rfind("drag(p", 0) == 0) {
    t.kind = DissipationKind::kDrag;
    open = 6;
  } else {
    throw refuse("not a dissipation term");
  }
  if (name.size() < open + 2 || name.back() != ')') throw refuse("not a dissipation term");
  Index v = 0;
  for (std::size_t k = open; k + 1 < name.size(); ++k) {
    const char c = name[k];
    if (c < '0' || c > '9') throw refuse("not a dissipation term");
    v = v * 10 + (c - '0');
    if (v > d) throw refuse("coordinate out of range");
  }
  if (v < 1) throw refuse("coordinate out of range");
  t.i = v - 1;
  return t;
}

FlowStep dissipation_flow(DissipationKind kind, double p, double rate, double tau) {
  FlowStep out;
  if (kind == DissipationKind::kCoulomb) {
    const double s = p > 0.0 ? 1.0 : p < 0.0 ? -1.0 : 0.0;
    const double loss = rate * tau;
    // Slip (always, for p ≠ 0, backward in time); at rate 0 the identity to the bit, −0 kept.
    if (std::abs(p) > loss || loss == 0.0) {
      out.p = p - s * loss;
      out.drate = -s * tau;
    } else {  // stick: the clamp holds p at 0
      out.p = 0.0;
      out.dp = 0.0;
    }
    return out;
  }
  const double den = 1.0 + rate * std::abs(p) * tau;
  if (!(den > 0.0)) {
    out.p = out.dp = out.drate = std::numeric_limits<double>::quiet_NaN();
    return out;
  }
  out.p = p / den;
  out.dp = 1.0 / (den * den);
  out.drate = -p * std::abs(p) * tau / (den * den);
  return out;
}

namespace {

// ṗ = c − m sign(p) over T ≥ 0. m < 0 is the backward flow's anti-friction: a moving p never
// stops under it, and a p at rest with |c| ≤ |m| stays at rest (one of the backward
// solutions; the one that undoes a forward stop, so that the triple jump's negative stage keeps
// a mass at rest where it is).
KickStep kick_forward(double x, double c, double m, double T) {
  KickStep out;
  if (x == 0.0) {
    if (std::abs(c) <= std::abs(m)) {  // at rest, and the friction holds it
      out.p = out.dp = 0.0;
      return out;
    }
    const double s = c > 0.0 ? 1.0 : -1.0;
    out.p = (c - m * s) * T;
    out.dforce = T;
    out.drate = -s * T;
    return out;
  }
  const double s = x > 0.0 ? 1.0 : -1.0;
  const double v = c - m * s;  // the rate of p on its side
  // Away from 0, or not reaching it within T: one linear piece.
  if (v * s >= 0.0 || std::abs(v) * T <= std::abs(x)) {
    out.p = x + v * T;
    out.dforce = T;
    out.drate = -s * T;
    return out;
  }
  // p reaches 0 at t0 = −x/v < T: it sticks there, or goes on with the other sign.
  if (std::abs(c) <= m) {
    out.p = out.dp = 0.0;
    return out;
  }
  const double rest = T + x / v;  // T − t0
  const double w = c + m * s;     // the rate on the other side
  out.p = w * rest;
  out.dp = w / v;
  out.dforce = rest - w * x / (v * v);
  out.drate = s * rest + w * x * s / (v * v);
  return out;
}

}  // namespace

KickStep coulomb_kick(double p, double force, double rate, double tau) {
  if (rate == 0.0) {  // the plain kick, to the bit
    KickStep out;
    out.p = p + force * tau;
    out.dforce = tau;
    out.drate = 0.0;  // one-sided at 0; the map takes |θ|, whose derivative there is 0
    return out;
  }
  if (tau >= 0.0) return kick_forward(p, force, rate, tau);
  KickStep out = kick_forward(p, -force, -rate, -tau);
  out.dforce = -out.dforce;
  out.drate = -out.drate;
  return out;
}

}  // namespace csympnet
