// A richer force law where the linked chain breaks (docs/identification.md, "Positions only").
//
// The library terms are selected on the velocity start, by one-step residuals of velocities from
// local fits. At many samples per period those barely see a force's anharmonic part: a pendulum
// at 85 samples per period swinging to 0.5 rad kept `q1, q1^2` alone, and the linking then
// stopped where the harmonic model could no longer follow the positions. Over the longer
// segments of that next stage the force law shows, so the additions are judged there, by the
// same information criterion as every other change on the chain.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "csympnet/core/stop.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "identify_chain.hpp"

namespace csympnet::detail {

namespace {

LibraryTerm single(Index i, TermShape shape, int power) {
  LibraryTerm t;
  t.i = i;
  t.j = -1;
  t.shape = shape;
  t.power = power;
  return t;
}

}  // namespace

std::vector<ChainChange> force_law_additions(const Candidate& c, Index d, const Matrix& q) {
  std::vector<ChainChange> out;
  const std::vector<LibraryTerm>& terms = library_map(c).terms();
  const auto has = [&terms](const LibraryTerm& t) {
    return std::find(terms.begin(), terms.end(), t) != terms.end();
  };
  for (Index i = 0; i < d; ++i) {
    std::vector<LibraryTerm> next = terms;
    std::string name;
    for (const int n : {3, 4})
      if (const LibraryTerm t = single(i, TermShape::kPower, n); !has(t)) {
        next.push_back(t);
        name += (name.empty() ? "" : ", ") + term_name(t);
      }
    if (next.size() > terms.size()) {
      Candidate x = library_with_terms(c, d, next);
      const Index added = x.inner.n_params() - c.inner.n_params();
      out.push_back({name, std::move(x), -added, "", {}});
    }
    const bool periodic_or_exp = std::any_of(terms.begin(), terms.end(), [i](const LibraryTerm& t) {
      return t.i == i && t.j < 0 && t.has_wavenumber();
    });
    if (periodic_or_exp || q.cols() == 0) continue;
    next = terms;
    next.push_back(single(i, TermShape::kSin, 1));
    next.push_back(single(i, TermShape::kCos, 1));
    Candidate x = library_with_terms(c, d, next);
    const HamiltonianLibraryMap& m = library_map(x);
    const double span = (q.row(i).array() - q.row(i).mean()).abs().maxCoeff();
    x.theta(m.wavenumber_index(static_cast<Index>(terms.size()))) = span > 0.0 ? 1.0 / span : 1.0;
    const Index added = x.inner.n_params() - c.inner.n_params();
    out.push_back({term_name(next[next.size() - 2]) + ", " + term_name(next.back()),
                   std::move(x),
                   -added,
                   "",
                   {}});
  }
  return out;
}

bool richer_force_law_on_chain(Candidate& lib, Index d, const Matrix& q,
                               const std::vector<Trajectory>& nt, const RecordLayout& layout,
                               LinkedFit& linked, const ShootingSegments& val, Matrix& val_z0,
                               const ShootingOptions& options, std::vector<Matrix>& states,
                               nlohmann::json& rec) {
  if (dynamic_cast<const HamiltonianLibraryMap*>(lib.inner.map.get()) == nullptr ||
      linked.linked_fully || linked.chain.segs.size() == 0 || linked.per_piece <= 0)
    return false;
  // The next stage's chain, where the linking found that the core does not follow.
  LinkedFit next;
  next.chain = cut_chain(nt, layout, 4 * linked.per_piece, states);
  if (next.chain.segs.size() == 0 || next.chain.segs.size() >= linked.chain.segs.size())
    return false;
  // The current core refitted there: the criterion's reference.
  Candidate current = library_with_terms(lib, d, library_map(lib).terms());
  Matrix vz = val_z0;
  ShootingOptions opt = options;
  opt.n_free = current.inner.n_params();
  next.report = fit_shooting(*current.inner.map, current.theta, next.chain.z0, next.chain.segs, vz,
                             val, watching_damping(*current.inner.map, opt));
  if (next.report.stopped) throw_if_stop_requested("the richer force laws on the chain");
  nlohmann::json trials = nlohmann::json::array();
  // The additions, and each coordinate's powers of degree 3 and 4 swapped for a sin/cos pair
  // (a quartic chosen over the short segments before may stop following a pendulum's swing
  // over the longer ones).
  const auto changes = [d, &q](const Candidate& c) {
    std::vector<ChainChange> out = force_law_additions(c, d, q);
    for (PolynomialAlternative& alt : periodic_alternatives(c, d, q)) {
      const Index fewer = c.inner.n_params() - alt.candidate.inner.n_params();
      out.push_back({alt.replaced, std::move(alt.candidate), fewer, alt.by, {}});
    }
    return out;
  };
  const bool changed =
      change_while_the_criterion_falls(current, next, val, vz, options, states, changes, trials);
  nlohmann::json record = {
      {"rule",
       "where the linking stopped, each coordinate's missing powers 3 and 4 and its sin/cos pair "
       "(added, or in place of its powers 3 and 4) are fitted over the next stage's longer "
       "segments, and the best change is made while it lowers the Bayesian information "
       "criterion there, n log(loss) + parameters x log n; the linking then goes on with the "
       "richer core"},
      {"positions_per_segment", 4 * linked.per_piece},
      {"residuals", next.chain.segs.n_residuals()},
      {"loss_of_the_core_as_selected", next.report.final_loss},
      {"trials", trials}};
  if (!changed) {
    rec["force_law_on_chain"] = record;
    return false;
  }
  lib = std::move(current);
  val_z0 = vz;
  linked = link_segments(*lib.inner.map, lib.theta, nt, layout, 4 * linked.per_piece, states, val,
                         val_z0, options, next.report);
  rec["force_law_on_chain"] = record;
  return true;
}

}  // namespace csympnet::detail
