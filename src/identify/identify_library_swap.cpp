// Swaps between term families of the library core, each started from the replaced terms'
// potential: a sin/cos or exp group for the powers of the same argument (parsimony, judged on
// the linked record by identify_prune.cpp), and a coordinate's powers 3 and 4 for a sin/cos
// pair of it (offered where a chain breaks, identify_force_law.cpp).
#include <algorithm>
#include <optional>

#include <Eigen/QR>

#include "csympnet/core/dense.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "identify_stages.hpp"

namespace csympnet::detail {

namespace {

bool same_argument(const LibraryTerm& a, const LibraryTerm& b) {
  return (a.i == b.i && a.j == b.j) || (a.j >= 0 && a.i == b.j && a.j == b.i);
}

LibraryTerm power_of(const LibraryTerm& arg, int n) {
  LibraryTerm t;
  t.i = arg.i;
  t.j = arg.j;
  t.shape = TermShape::kPower;
  t.power = n;
  return t;
}

// A swap's candidate: the library core of `next` (lib's core otherwise), θ from lib's: the
// mass, the damping, the dissipation rates in their order, and the coefficient and wavenumber
// of each of lib's terms but the `replaced` ones; the new terms' start is the caller's.
struct Swapped {
  PolynomialAlternative alt;
  const HamiltonianLibraryMap* map = nullptr;
  // A term's place in the new map, found by name (a parsed term's fields other than its shape
  // and argument may differ from one built here).
  Index index_of(const LibraryTerm& t) const {
    const std::string name = term_name(t);
    const auto& placed = map->terms();
    const auto at = std::find_if(placed.begin(), placed.end(),
                                 [&](const LibraryTerm& u) { return term_name(u) == name; });
    require(at != placed.end(), "library: a term of the alternative was not placed");
    return static_cast<Index>(at - placed.begin());
  }
  double& coefficient(const LibraryTerm& t) {
    return alt.candidate.theta(map->coefficient_index(index_of(t)));
  }
};
Swapped swapped_candidate(const Candidate& lib, Index d, const std::vector<LibraryTerm>& next,
                          const std::vector<std::size_t>& replaced) {
  const auto& old = dynamic_cast<const HamiltonianLibraryMap&>(*lib.inner.map);
  const std::vector<LibraryTerm>& terms = old.terms();
  const auto is_replaced = [&](std::size_t k) {
    return std::find(replaced.begin(), replaced.end(), k) != replaced.end();
  };
  Swapped out;
  PolynomialAlternative& alt = out.alt;
  for (std::size_t k : replaced)
    alt.replaced += (alt.replaced.empty() ? "" : ", ") + term_name(terms[k]);
  for (const LibraryTerm& t : next)
    if (std::find(terms.begin(), terms.end(), t) == terms.end())
      alt.by += (alt.by.empty() ? "" : ", ") + term_name(t);
  Candidate& c = alt.candidate;
  c.core = lib.core;
  c.core["terms"] = nlohmann::json::array();
  for (const LibraryTerm& t : next) c.core["terms"].push_back(term_name(t));
  c.inner = make_model({{"type", "csympnet"}, {"d", d}, {"core", c.core}, {"beta_init", 0.1}});
  out.map = dynamic_cast<const HamiltonianLibraryMap*>(c.inner.map.get());
  require(out.map != nullptr, "library: the alternative is not a library map");
  const HamiltonianLibraryMap& nm = *out.map;
  c.theta = Vector::Zero(c.inner.n_params());
  c.theta.head(nm.mass_size()) = lib.theta.head(old.mass_size());
  c.theta(*nm.damping_param_index()) = lib.theta(*old.damping_param_index());
  // The core (copied) keeps the dissipation terms in their order: their rates carry over.
  for (Index k = 0; k < static_cast<Index>(old.dissipation().size()); ++k)
    c.theta(nm.dissipation_index(k)) = lib.theta(old.dissipation_index(k));
  for (std::size_t k = 0; k < terms.size(); ++k) {
    if (is_replaced(k)) continue;
    const Index to = out.index_of(terms[k]);
    const auto from = static_cast<Index>(k);
    c.theta(nm.coefficient_index(to)) = lib.theta(old.coefficient_index(from));
    if (nm.wavenumber_index(to) >= 0)
      c.theta(nm.wavenumber_index(to)) = lib.theta(old.wavenumber_index(from));
  }
  c.training = lib.training;
  c.pretrained = true;
  return out;
}

}  // namespace

std::vector<PolynomialAlternative> polynomial_alternatives(const Candidate& lib, Index d,
                                                           const Matrix& q) {
  std::vector<PolynomialAlternative> out;
  const auto* map = dynamic_cast<const HamiltonianLibraryMap*>(lib.inner.map.get());
  if (map == nullptr || q.cols() < 8) return out;
  const std::vector<LibraryTerm>& terms = map->terms();
  const Vector& scales = map->coordinate_scales();
  std::vector<bool> done(terms.size(), false);
  for (std::size_t g = 0; g < terms.size(); ++g) {
    if (done[g] || terms[g].shape == TermShape::kPower) continue;
    // The group: every sin/cos of this argument, or this exp alone.
    std::vector<std::size_t> group;
    for (std::size_t k = 0; k < terms.size(); ++k)
      if (!done[k] && terms[k].shape != TermShape::kPower && same_argument(terms[k], terms[g]) &&
          (terms[g].shape == TermShape::kExp ? k == g : terms[k].shape != TermShape::kExp))
        group.push_back(k);
    for (std::size_t k : group) done[k] = true;
    const LibraryTerm& arg = terms[g];
    // The new terms: the others, then the powers of the argument (a difference's linear part
    // goes to its two coordinates' linear terms).
    std::vector<LibraryTerm> next;
    for (std::size_t k = 0; k < terms.size(); ++k)
      if (std::find(group.begin(), group.end(), k) == group.end()) next.push_back(terms[k]);
    const auto ensure = [&next](const LibraryTerm& t) {
      if (std::find(next.begin(), next.end(), t) == next.end()) next.push_back(t);
    };
    const LibraryTerm base = power_of(arg, 1);
    const bool difference = arg.j >= 0;
    if (difference) {
      LibraryTerm a = power_of(arg, 1), b = power_of(arg, 1);
      a.j = -1;
      b.i = arg.j;
      b.j = -1;
      ensure(a);
      ensure(b);
    }
    for (int n = difference ? 2 : 1; n <= 4; ++n) ensure(power_of(base, n));
    // The group's potential as a polynomial of degree 4 in its argument, by least squares over
    // the positions' arguments: the new coefficients' start.
    const Index n = q.cols();
    Matrix x(n, 4);
    Vector y = Vector::Zero(n);
    for (Index s = 0; s < n; ++s) {
      const double u =
          difference ? scales(arg.i) * q(arg.i, s) - scales(arg.j) * q(arg.j, s) : q(arg.i, s);
      for (int p = 1; p <= 4; ++p) x(s, p - 1) = std::pow(u, p);
      for (std::size_t k : group) {
        const Index ki = static_cast<Index>(k);
        const double kappa = lib.theta(map->wavenumber_index(ki));
        const double uk = difference && terms[k].i != arg.i ? -u : u;
        y(s) += lib.theta(map->coefficient_index(ki)) * term_values(terms[k], uk, kappa).phi;
      }
    }
    // Centred columns: the constant is no term.
    const Vector ones = Vector::Ones(n);
    const Matrix xc = x.rowwise() - x.colwise().mean();
    const Vector poly = dense::least_squares(xc, Vector(y - ones * y.mean()));
    if (!poly.allFinite()) continue;
    Swapped sw = swapped_candidate(lib, d, next, group);
    for (int p = 1; p <= 4; ++p) {
      if (difference && p == 1) {
        LibraryTerm a = base, b = base;
        a.j = -1;
        b.i = arg.j;
        b.j = -1;
        sw.coefficient(a) += poly(0) * scales(arg.i);
        sw.coefficient(b) -= poly(0) * scales(arg.j);
        continue;
      }
      sw.coefficient(power_of(base, p)) += poly(p - 1);
    }
    out.push_back(std::move(sw.alt));
  }
  return out;
}

std::vector<PolynomialAlternative> periodic_alternatives(const Candidate& lib, Index d,
                                                         const Matrix& q) {
  std::vector<PolynomialAlternative> out;
  const auto* map = dynamic_cast<const HamiltonianLibraryMap*>(lib.inner.map.get());
  if (map == nullptr || q.cols() < 8) return out;
  const std::vector<LibraryTerm>& terms = map->terms();
  for (Index i = 0; i < d; ++i) {
    const auto on_i = [i](const LibraryTerm& t) { return t.i == i && t.j < 0; };
    const bool has_wave = std::any_of(terms.begin(), terms.end(), [&](const LibraryTerm& t) {
      return on_i(t) && t.has_wavenumber();
    });
    std::vector<std::size_t> removed;
    for (std::size_t k = 0; k < terms.size(); ++k)
      if (on_i(terms[k]) && terms[k].shape == TermShape::kPower && terms[k].power >= 3)
        removed.push_back(k);
    if (has_wave || removed.empty()) continue;
    LibraryTerm base;
    base.i = i;
    base.j = -1;
    base.shape = TermShape::kPower;
    base.power = 1;
    LibraryTerm sin_t = base, cos_t = base;
    sin_t.shape = TermShape::kSin;
    cos_t.shape = TermShape::kCos;
    const LibraryTerm square = power_of(base, 2);
    std::vector<LibraryTerm> next;
    for (std::size_t k = 0; k < terms.size(); ++k)
      if (std::find(removed.begin(), removed.end(), k) == removed.end()) next.push_back(terms[k]);
    // The linear and square terms take what the pair adds below degree 3 (sin(κu) ≈ κu − …).
    for (const LibraryTerm& t : {base, square})
      if (std::find(next.begin(), next.end(), t) == next.end()) next.push_back(t);
    next.push_back(sin_t);
    next.push_back(cos_t);
    // The removed powers' potential by q_i, q_i², sin(κ q_i) and cos(κ q_i) over the positions,
    // κ such that the argument spans about ±1 (least squares, centred: the constant is no term).
    const Index n = q.cols();
    const double span = (q.row(i).array() - q.row(i).mean()).abs().maxCoeff();
    const double kappa = span > 0.0 ? 1.0 / span : 1.0;
    Matrix x(n, 4);
    Vector y = Vector::Zero(n);
    for (Index s = 0; s < n; ++s) {
      const double u = q(i, s);
      x(s, 0) = u;
      x(s, 1) = term_values(square, u, 0.0).phi;
      x(s, 2) = term_values(sin_t, u, kappa).phi;
      x(s, 3) = term_values(cos_t, u, kappa).phi;
      for (std::size_t k : removed)
        y(s) += lib.theta(map->coefficient_index(static_cast<Index>(k))) *
                term_values(terms[k], u, 0.0).phi;
    }
    const Matrix xc = x.rowwise() - x.colwise().mean();
    const Vector fit = dense::least_squares(xc, Vector(y - Vector::Ones(n) * y.mean()));
    if (!fit.allFinite()) continue;
    Swapped sw = swapped_candidate(lib, d, next, removed);
    sw.coefficient(base) += fit(0);
    sw.coefficient(square) += fit(1);
    sw.coefficient(sin_t) = fit(2);
    sw.coefficient(cos_t) = fit(3);
    Vector& theta = sw.alt.candidate.theta;
    for (const LibraryTerm& t : {sin_t, cos_t})
      if (const Index w = sw.map->wavenumber_index(sw.index_of(t)); w >= 0) theta(w) = kappa;
    out.push_back(std::move(sw.alt));
  }
  return out;
}

Candidate library_with(const Candidate& lib, Index d, const std::vector<LibraryTerm>& next,
                       const std::vector<DissipationTerm>& next_dissipation) {
  const auto* map = dynamic_cast<const HamiltonianLibraryMap*>(lib.inner.map.get());
  require(map != nullptr, "library: the candidate to change is not a library map");
  Candidate c;
  c.core = lib.core;
  c.training = lib.training;
  c.lm = lib.lm;
  c.lm_best_iteration = lib.lm_best_iteration;
  c.lm_seconds = lib.lm_seconds;
  c.val_loss = lib.val_loss;
  c.pretrained = lib.pretrained;
  c.core["terms"] = nlohmann::json::array();
  for (const LibraryTerm& t : next) c.core["terms"].push_back(term_name(t));
  set_dissipation_spec(c.core, next_dissipation);
  c.inner = make_model({{"type", "csympnet"}, {"d", d}, {"core", c.core}, {"beta_init", 0.1}});
  const auto* nm = dynamic_cast<const HamiltonianLibraryMap*>(c.inner.map.get());
  require(nm != nullptr, "library: the changed candidate is not a library map");
  // Each term kept carries its coefficient (and wavenumber) over; a new term starts at 0.
  c.theta = Vector::Zero(c.inner.n_params());
  c.theta.head(map->mass_size()) = lib.theta.head(map->mass_size());
  const std::vector<LibraryTerm>& old = map->terms();
  for (std::size_t k = 0; k < next.size(); ++k) {
    const auto at = std::find(old.begin(), old.end(), next[k]);
    if (at == old.end()) continue;
    const Index from = static_cast<Index>(at - old.begin());
    const Index to = static_cast<Index>(k);
    c.theta(nm->coefficient_index(to)) = lib.theta(map->coefficient_index(from));
    if (map->wavenumber_index(from) >= 0 && nm->wavenumber_index(to) >= 0)
      c.theta(nm->wavenumber_index(to)) = lib.theta(map->wavenumber_index(from));
  }
  c.theta(*nm->damping_param_index()) = lib.theta(*map->damping_param_index());
  // A dissipation term kept carries its rate over (a rate left at 0, where |θ| has no slope,
  // could never move again); a new one starts at the map's own nonzero start.
  const std::vector<DissipationTerm>& old_dis = map->dissipation();
  for (std::size_t k = 0; k < next_dissipation.size(); ++k) {
    const auto at = std::find(old_dis.begin(), old_dis.end(), next_dissipation[k]);
    c.theta(nm->dissipation_index(static_cast<Index>(k))) =
        at == old_dis.end()
            ? HamiltonianLibraryMap::kDissipationInit
            : lib.theta(map->dissipation_index(static_cast<Index>(at - old_dis.begin())));
  }
  return c;
}

Candidate library_with_terms(const Candidate& lib, Index d, const std::vector<LibraryTerm>& next) {
  const auto* map = dynamic_cast<const HamiltonianLibraryMap*>(lib.inner.map.get());
  require(map != nullptr, "library: the candidate to change is not a library map");
  return library_with(lib, d, next, map->dissipation());
}

std::optional<Candidate> with_rest_position_terms(const Candidate& lib, Index d) {
  const auto* map = dynamic_cast<const HamiltonianLibraryMap*>(lib.inner.map.get());
  if (map == nullptr) return std::nullopt;
  std::vector<LibraryTerm> next = map->terms();
  for (Index i = 0; i < d; ++i) {
    LibraryTerm t;
    t.i = i;
    t.j = -1;
    t.shape = TermShape::kPower;
    t.power = 1;
    if (std::find(next.begin(), next.end(), t) == next.end()) next.push_back(t);
  }
  if (next.size() == map->terms().size()) return std::nullopt;
  // The old terms keep their places (the new ones come last, at 0).
  return library_with_terms(lib, d, next);
}

}  // namespace csympnet::detail
