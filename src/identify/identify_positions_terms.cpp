// The library core's terms judged on segments of the positions, where the floor test found
// smooth structure left (identify_positions.hpp, positions_floor).
//
// The terms were selected on velocities from local fits (identify_library.cpp), whose errors
// hide a force law's anharmonic part: between families that differ by less than those errors
// the choice is a coin toss. On a pendulum record from positions (1,000 samples, 80 positions
// per period) a quartic and a sin/cos pair lowered the velocity stage's held-out loss by 66.3%
// and 66.2%, the quartic was kept, and over segments of two periods it left positions
// residuals with a lag-one correlation of 0.47: two neural cores were trained (7 of the fit's
// 8.6 CPU s) for what the sin/cos pair explains. Over those segments the force law shows, so
// the additions and swaps are judged there, by the same information criterion as every change
// on the linked chain (identify_prune.cpp).
#include <algorithm>
#include <chrono>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "csympnet/core/stop.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/train/shooting.hpp"
#include "identify_chain.hpp"
#include "identify_positions.hpp"

namespace csympnet::detail {

namespace {

// Every change offered: a coordinate's missing powers 3 and 4, its sin/cos pair (added, or in
// place of its powers 3 and 4), and a sin/cos or exp group replaced by the powers of its
// argument.
std::vector<ChainChange> changes_of(const Candidate& c, Index d, const Matrix& q) {
  std::vector<ChainChange> out = force_law_additions(c, d, q);
  const auto swaps = [&](std::vector<PolynomialAlternative> alts) {
    for (PolynomialAlternative& alt : alts) {
      const Index fewer = c.inner.n_params() - alt.candidate.inner.n_params();
      out.push_back({alt.replaced, std::move(alt.candidate), fewer, alt.by, {}});
    }
  };
  swaps(periodic_alternatives(c, d, q));
  swaps(polynomial_alternatives(c, d, q));
  return out;
}

}  // namespace

TermsOnSegments terms_on_segments(const Candidate& lib, const SegmentFit& start, Index d,
                                  const Matrix& q, const ShootingOptions& options,
                                  const StopSearch& stop) {
  TermsOnSegments out;
  out.lib = library_with_terms(lib, d, library_map(lib).terms());
  out.lib.theta = start.theta;
  out.fit.theta = start.theta;
  out.fit.train = start.train;
  out.fit.val = start.val;
  out.fit.rep = start.rep;
  out.trials = nlohmann::json::array();
  const Index n = start.train.segs.n_residuals();
  if (!(start.rep.final_loss > rounding_loss(start.train.segs))) return out;
  std::map<std::string, double> last;
  // Each change lowers the criterion, so no set of terms comes back at the same fit; the cap
  // bounds a search whose refits wander (two changes per coordinate, and two more).
  const Index rounds = 2 * d + 2;
  for (Index round = 0; round < rounds; ++round) {
    std::optional<ChainChange> best;
    std::optional<SegmentFit> best_fit;
    double best_change = 0.0;
    for (ChainChange& change : changes_of(out.lib, d, q)) {
      throw_if_stop_requested("the library terms judged on the positions");
      if (const auto was = last.find(change.name); was != last.end() && was->second > kClearlyWorse)
        continue;
      ShootingOptions opt = options;
      opt.n_free = free_parameters(*change.candidate.inner.map, d);
      opt.iterations = std::min(options.iterations, kTrialIterations);
      const auto t0 = std::chrono::steady_clock::now();
      SegmentFit fit = fit_segments(*change.candidate.inner.map, change.candidate.theta,
                                    out.fit.train, out.fit.val, opt);
      if (fit.rep.stopped) throw_if_stop_requested("the library terms judged on the positions");
      const double delta =
          bic_change_of_dropping(out.fit.rep.final_loss, fit.rep.final_loss, n, change.parameters);
      last[change.name] = delta;
      out.trials.push_back(
          {{"terms", change.name},
           {"parameters_removed", change.parameters},
           {"loss_before", out.fit.rep.final_loss},
           {"loss_after", fit.rep.final_loss},
           {"held_out_loss_after", fit.rep.val_loss},
           {"bic_change", delta},
           {"lm_iterations", fit.rep.iterations},
           {"seconds",
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()}});
      if (!change.replaced_by.empty()) out.trials.back()["replaced_by"] = change.replaced_by;
      if (delta < best_change) {
        best_change = delta;
        best = std::move(change);
        best_fit = std::move(fit);
      }
    }
    if (!best) break;
    out.trials.push_back({{"made", best->name}, {"bic_change", best_change}});
    if (best_fit->rep.iterations >= kTrialIterations) {
      ShootingOptions opt = options;
      opt.n_free = free_parameters(*best->candidate.inner.map, d);
      opt.iterations = std::max<long>(1, options.iterations - kTrialIterations);
      SegmentFit on = fit_segments(*best->candidate.inner.map, best_fit->theta, best_fit->train,
                                   best_fit->val, opt);
      if (on.rep.stopped) throw_if_stop_requested("the library terms judged on the positions");
      out.trials.back()["fitted_on"] = {{"lm_iterations", on.rep.iterations},
                                        {"loss", on.rep.final_loss}};
      if (on.rep.final_loss <= best_fit->rep.final_loss) best_fit = std::move(on);
    }
    out.lib = std::move(best->candidate);
    out.lib.theta = best_fit->theta;
    out.fit = std::move(*best_fit);
    out.changed = true;
    if (stop && stop(out.lib, out.fit)) break;
  }
  return out;
}

}  // namespace csympnet::detail
