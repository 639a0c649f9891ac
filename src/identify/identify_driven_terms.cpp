// The driven route's terms (identify_driven.hpp): forward selection by BIC over the training
// segments, then the powers and sin/cos pairs dropped while that lowers the criterion.
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "csympnet/core/stop.hpp"
#include "identify_driven.hpp"

namespace csympnet::detail {

namespace {

// Additions the selection of a driven record's terms may make.
constexpr int kDrivenAdditions = 3;
// LM iterations of each trial fit of the selection (the chosen terms are fitted in full).
constexpr long kSelectionIterations = 50;

// The Bayesian information criterion of a fit over the training segments (the same segments,
// hence the same hidden start states, for every candidate): n log(loss) + parameters x log n.
double driven_bic(const DrivenFit& f, Index n) {
  const double nn = static_cast<double>(n);
  return f.rep.final_loss > 0.0 && std::isfinite(f.rep.final_loss)
             ? nn * std::log(f.rep.final_loss) +
                   static_cast<double>(f.map.n_params()) * std::log(nn)
             : std::numeric_limits<double>::infinity();
}

// The additions offered to `terms`: per coordinate its missing powers 3 and 4, and its sin/cos
// pair when it has no sinusoid yet; per pair of coordinates (up to d = 4, neighbours beyond)
// the missing powers 3 and 4 of their difference.
std::vector<std::pair<std::string, std::vector<LibraryTerm>>> driven_additions(
    const std::vector<LibraryTerm>& terms, Index d) {
  std::vector<std::pair<std::string, std::vector<LibraryTerm>>> out;
  const auto has = [&terms](const LibraryTerm& t) {
    return std::find(terms.begin(), terms.end(), t) != terms.end();
  };
  const auto offer = [&](const std::vector<std::string>& names) {
    std::vector<LibraryTerm> next = terms;
    std::string added;
    for (const std::string& n : names)
      if (const LibraryTerm t = parse_term(n, d, "core"); !has(t)) {
        next.push_back(t);
        added += (added.empty() ? "" : ", ") + n;
      }
    if (!added.empty()) out.emplace_back(added, std::move(next));
  };
  for (Index i = 0; i < d; ++i) {
    const std::string q = "q" + std::to_string(i + 1);
    offer({q + "^3", q + "^4"});
    const bool periodic = std::any_of(terms.begin(), terms.end(), [i](const LibraryTerm& t) {
      return t.i == i && t.j < 0 && t.has_wavenumber();
    });
    if (!periodic) offer({"sin(" + q + ")", "cos(" + q + ")"});
  }
  for (Index i = 0; i < d; ++i)
    for (Index j = i + 1; j < d; ++j) {
      if (d > 4 && j != i + 1) continue;
      const std::string x = "(q" + std::to_string(i + 1) + "-q" + std::to_string(j + 1) + ")";
      offer({x + "^3", x + "^4"});
    }
  return out;
}

}  // namespace

// Forward selection by BIC over the training segments, a few additions at most, then each
// power of degree 3 or 4 or sin/cos pair dropped while that lowers the criterion. The velocity-free
// analogue of the free route's selection: the input excites the record's whole range of amplitudes,
// and the positions judge the force law. Every trial in record["selection"].
DrivenFit select_driven_terms(DrivenFit fit, const LibrarySpec& spec, Index m,
                              const std::vector<Trajectory>& nt, const DrivenCut& cut,
                              const IdentifyConfig& config, const IdentifyHooks& hooks,
                              nlohmann::json& record) {
  const Index d = fit.map.d();
  const Index n = cut.train.n_residuals();
  nlohmann::json trials = nlohmann::json::array();
  const auto names = [](const std::vector<LibraryTerm>& ts) {
    std::string out;
    for (const LibraryTerm& t : ts) out += (out.empty() ? "" : ", ") + term_name(t);
    return out;
  };
  const auto try_terms = [&](const std::string& what, const std::vector<LibraryTerm>& terms) {
    throw_if_stop_requested("the selection of a driven record's terms");
    DrivenFit x =
        fit_driven(driven_map(spec, terms, d, m), nt, cut, config, hooks, kSelectionIterations);
    const double change = driven_bic(x, n) - driven_bic(fit, n);
    trials.push_back({{"change", what},
                      {"terms", names(terms)},
                      {"loss", x.rep.final_loss},
                      {"bic_change", change}});
    return std::make_pair(change, std::move(x));
  };
  for (int round = 0; round < kDrivenAdditions; ++round) {
    std::optional<std::pair<double, DrivenFit>> best;
    for (const auto& [what, terms] : driven_additions(fit.map.terms(), d)) {
      auto t = try_terms("add " + what, terms);
      if (t.first < 0.0 && (!best || t.first < best->first)) best = std::move(t);
    }
    if (!best) break;
    fit = std::move(best->second);
    trials.push_back({{"made", names(fit.map.terms())}});
  }
  for (bool dropped = true; dropped;) {
    dropped = false;
    const std::vector<LibraryTerm> terms = fit.map.terms();
    for (std::size_t k = 0; k < terms.size(); ++k) {
      // A power of degree 3 or 4, or a coordinate's sin/cos pair (at its sin): a sinusoid
      // taken first can mimic the powers added after it.
      const bool power = terms[k].shape == TermShape::kPower && terms[k].power >= 3;
      if (!power && terms[k].shape != TermShape::kSin) continue;
      std::vector<LibraryTerm> next;
      std::string what;
      for (const LibraryTerm& t : terms) {
        const bool goes = power ? t == terms[k]
                                : t.i == terms[k].i && t.j == terms[k].j &&
                                      (t.shape == TermShape::kSin || t.shape == TermShape::kCos);
        if (goes)
          what += (what.empty() ? "" : ", ") + term_name(t);
        else
          next.push_back(t);
      }
      auto t = try_terms("drop " + what, next);
      if (t.first >= 0.0) continue;
      fit = std::move(t.second);
      trials.push_back({{"made", names(fit.map.terms())}});
      dropped = true;
      break;
    }
  }
  // The terms chosen, fitted in full from their equation-error start.
  fit = fit_driven(driven_map(spec, fit.map.terms(), d, m), nt, cut, config, hooks);
  record["selection"] = {
      {"rule",
       "from the quadratic terms, the addition (a coordinate's or a difference's powers 3 and 4, "
       "or a coordinate's sin/cos pair) that lowers the Bayesian information criterion of the "
       "training segments most, n log(loss) + parameters x log n, while one does (at most " +
           std::to_string(kDrivenAdditions) +
           "); then each power of degree 3 or 4, or sin/cos pair, dropped while that lowers it; "
           "trial fits take at most " +
           std::to_string(kSelectionIterations) +
           " LM iterations, the terms chosen are fitted again in full"},
      {"residuals", n},
      {"trials", trials}};
  return fit;
}

}  // namespace csympnet::detail
