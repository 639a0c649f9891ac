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

}  // namespace csympnet
