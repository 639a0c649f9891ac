// The model-selection table of an identification (report key "model_selection", printed by
// `csympnet fit`): every decision between models that the pipeline took, each with the chosen
// model, the runner-up, the criterion the decision used and both values, so that a reader sees
// how close the call was.
//
// The stages record their trials where they decide (choices.core_candidates,
// choices.library.forward, choices.positions.{core_choice, polynomial_preferred, terms_pruned,
// dissipation_on_positions}); this file only reads those records. It is a summary: the records
// keep every trial.
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>

#include "csympnet/identify/identify.hpp"
#include "csympnet/io/json_text.hpp"
#include "identify_stages.hpp"

namespace csympnet {

namespace {

double number(const nlohmann::json& j, const char* key) {
  const auto it = j.find(key);
  return it != j.end() && it->is_number() ? it->get<double>()
                                          : std::numeric_limits<double>::quiet_NaN();
}

std::string text(const nlohmann::json& j, const char* key) {
  const auto it = j.find(key);
  return it != j.end() && it->is_string() ? it->get<std::string>() : std::string();
}

// "library (q1, q1^2, q1^4)", "library (q1^2) + coulomb", "la:3:8".
std::string model_name(const nlohmann::json& core) {
  if (!core.is_object()) return core.is_string() ? core.get<std::string>() : core.dump();
  std::string name = detail::core_name(core);
  if (name != "library") return name;
  std::string terms;
  for (const auto& t : core.value("terms", nlohmann::json::array()))
    if (t.is_string()) terms += (terms.empty() ? "" : ", ") + t.get<std::string>();
  if (!terms.empty()) name += " (" + terms + ")";
  std::map<std::string, int> kinds;  // "coulomb(p1)" → coulomb
  for (const auto& t : core.value("dissipation", nlohmann::json::array()))
    if (t.is_string()) ++kinds[t.get<std::string>().substr(0, t.get<std::string>().find('('))];
  for (const auto& [kind, n] : kinds) name += " + " + kind;
  return name;
}

nlohmann::json row(const std::string& decision, const std::string& criterion,
                   const std::string& chosen, double chosen_value, const std::string& runner_up,
                   double runner_up_value, double margin, const std::string& margin_unit,
                   const std::string& margin_means) {
  return {{"decision", decision},
          {"criterion", criterion},
          {"chosen", chosen},
          {"chosen_value", finite_or_null(chosen_value)},
          {"runner_up", runner_up},
          {"runner_up_value", finite_or_null(runner_up_value)},
          {"margin", finite_or_null(margin)},
          {"margin_unit", margin_unit},
          {"margin_means", margin_means}};
}

// Lower is better: the chosen candidate (index `chosen`) against the best of the others.
void best_of_the_rest(const nlohmann::json& candidates, std::size_t chosen, const char* value_key,
                      const char* core_key, const std::string& decision,
                      const std::string& criterion, double n, nlohmann::json& rows) {
  std::optional<std::size_t> ru;
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    if (i == chosen || !std::isfinite(number(candidates[i], value_key))) continue;
    if (!ru || number(candidates[i], value_key) < number(candidates[*ru], value_key)) ru = i;
  }
  if (!ru) return;
  const double a = number(candidates[chosen], value_key);
  const double b = number(candidates[*ru], value_key);
  // The losses' difference in standard errors of the chosen loss, √(2/n) of itself (a mean of
  // n squared Gaussian residuals).
  const double se = n > 0.0 ? a * std::sqrt(2.0 / n) : std::numeric_limits<double>::quiet_NaN();
  rows.push_back(row(decision, criterion, model_name(candidates[chosen][core_key]), a,
                     model_name(candidates[*ru][core_key]), b, (b - a) / se, "standard errors",
                     "(runner-up - chosen) / standard error of the chosen loss; positive: the "
                     "chosen fits better"));
}

// A dissipation kind's name in words; a term's name as it is.
std::string readable(const std::string& term) {
  if (term == "coulomb") return "Coulomb friction";
  if (term == "drag") return "quadratic drag";
  return term;
}

// Backward elimination on the linked positions: each term's (or dissipation kind's) last
// trial decides it (a trial followed by {"dropped": name} was made).
void elimination(const nlohmann::json& rec, const std::string& decision, nlohmann::json& rows,
                 bool additions = false) {
  if (!rec.is_object() || !rec.contains("trials")) return;
  std::map<std::string, double> last;                       // term → its last ΔBIC of dropping
  std::map<std::string, std::pair<double, double>> losses;  // term → loss with, without
  std::map<std::string, std::string> by;                    // a swap's new terms
  std::map<std::string, bool> dropped;
  std::vector<std::string> order;
  for (const auto& t : rec["trials"]) {
    if (t.contains("dropped")) {
      dropped[readable(text(t, "dropped"))] = true;
      continue;
    }
    const std::string term = readable(text(t, "term"));
    if (!last.count(term)) order.push_back(term);
    last[term] = number(t, "bic_change");
    losses[term] = {number(t, "loss_before"), number(t, "loss_after")};
    by[term] = text(t, "replaced_by");
  }
  const std::string criterion =
      "Bayesian information criterion of the linked positions fit, n log(loss) + parameters x "
      "log n (n = " +
      std::to_string(rec.value("residuals", 0)) + ")";
  for (const std::string& term : order) {
    // A trial's change is BIC(after it) − BIC(before): for a drop, BIC(without) − BIC(with);
    // for an addition, BIC(with) − BIC(without). A change made is a drop done or a group added.
    const double change = additions ? -last[term] : last[term];
    const bool out = additions ? !dropped[term] : dropped[term];
    const auto [before, after] = losses[term];
    const double with = additions ? after : before;
    const double without = additions ? before : after;
    // A drop reads "with X" / "without X"; a swap "X" / "Y instead of X".
    const std::string kept = by[term].empty() ? "with " + term : term;
    const std::string gone =
        by[term].empty() ? "without " + term : by[term] + " instead of " + term;
    rows.push_back(row(decision, criterion, out ? gone : kept, out ? without : with,
                       out ? kept : gone, out ? with : without, out ? -change : change, "BIC",
                       "BIC(runner-up) - BIC(chosen); positive: the data favour the chosen"));
  }
}

// Friction and drag on the windows: each kind tried (added or not) and each kind the pruning
// kept or dropped, with and without it.
void dissipation_on_windows(const nlohmann::json& rec, const std::string& criterion,
                            const std::string& means, nlohmann::json& rows) {
  if (!rec.is_object() || !rec.contains("rounds")) return;
  for (const auto& s : rec["rounds"]) {
    const bool pruning = text(s, "when") == "pruning";
    const std::string kind = readable(text(s, pruning ? "tried_without" : "tried"));
    if (kind.empty()) continue;
    // Added, or kept by the pruning: "with" won.
    const bool with = pruning ? !s.value("dropped", false) : s.value("earns_its_place", false);
    const double before = number(s, "val_loss_before");
    const double after = number(s, "val_loss_after");
    // Before is without the kind when it was tried for adding, with it when pruning.
    const double with_loss = pruning ? before : after;
    const double without_loss = pruning ? after : before;
    const double chosen = with ? with_loss : without_loss;
    const double other = with ? without_loss : with_loss;
    rows.push_back(row("dissipation", criterion, (with ? "with " : "without ") + kind, chosen,
                       (with ? "without " : "with ") + kind, other, other / chosen - 1.0,
                       "relative", means));
  }
}

}  // namespace

nlohmann::json model_selection(const IdentifyResult& r) {
  nlohmann::json rows = nlohmann::json::array();
  const nlohmann::json& c = r.choices;
  if (!c.is_object()) return rows;
  // The cores on the windows (records with momenta; positions: the velocity start).
  const bool positions = r.observed == "positions";
  if (c.contains("core_candidates") && c["core_candidates"].size() > 1) {
    const nlohmann::json& cand = c["core_candidates"];
    std::size_t win = 0;
    for (std::size_t i = 1; i < cand.size(); ++i)
      if (number(cand[i], "val_loss") < number(cand[win], "val_loss")) win = i;
    best_of_the_rest(cand, win, "val_loss", "core",
                     positions ? "core on the velocity start" : "core",
                     positions ? "held-out loss of windows on velocities from local fits"
                               : "held-out loss of the windows",
                     std::numeric_limits<double>::quiet_NaN(), rows);
  }
  // The library's groups added on the windows: each round's kept group against the best other
  // group fitted in that round; a last round that kept none against its best group.
  const nlohmann::json lib = c.value("library", nlohmann::json::object());
  const std::string group_criterion =
      positions ? "held-out loss of windows on velocities from local fits (a group must lower "
                  "it by the keep threshold)"
                : "held-out loss of the windows (a group must lower it by the keep threshold)";
  const std::string relative_means =
      "relative excess of the runner-up's loss; negative: the runner-up fits a little better but "
      "not by enough to earn its parameters";
  if (lib.is_object() && lib.contains("forward") && lib["forward"].is_array()) {
    nlohmann::json round = nlohmann::json::array();
    const auto none_kept = [&](const nlohmann::json& tried) {
      std::optional<std::size_t> ru;
      for (std::size_t i = 0; i < tried.size(); ++i)
        if (!ru || number(tried[i], "val_loss_after") < number(tried[*ru], "val_loss_after"))
          ru = i;
      if (!ru) return;
      const double before = number(tried[*ru], "val_loss_before");
      const double after = number(tried[*ru], "val_loss_after");
      rows.push_back(row("library group added", group_criterion, "none", before,
                         text(tried[*ru], "terms"), after, after / before - 1.0, "relative",
                         relative_means));
    };
    for (const auto& s : lib["forward"]) {
      if (!s.contains("kept")) {
        // A group the score test left unfitted has no held-out loss to compare.
        if (s.contains("val_loss_after")) round.push_back(s);
        continue;
      }
      const std::string kept = text(s, "kept");
      std::optional<std::size_t> ru;
      for (std::size_t i = 0; i < round.size(); ++i)
        if (text(round[i], "terms") != kept &&
            (!ru || number(round[i], "val_loss_after") < number(round[*ru], "val_loss_after")))
          ru = i;
      if (ru)
        rows.push_back(row("library group added", group_criterion, kept, number(s, "val_loss"),
                           text(round[*ru], "terms"), number(round[*ru], "val_loss_after"),
                           number(round[*ru], "val_loss_after") / number(s, "val_loss") - 1.0,
                           "relative", relative_means));
      round = nlohmann::json::array();
    }
    none_kept(round);
  }
  dissipation_on_windows(lib.value("dissipation", nlohmann::json()),
                         std::string(positions ? "held-out loss of windows on velocities from "
                                                 "local fits"
                                               : "held-out loss of the windows") +
                             " (a kind enters when the amplitude check calls for it and the loss "
                             "falls by the keep threshold)",
                         relative_means, rows);
  if (!positions || !c.contains("positions")) return rows;
  const nlohmann::json& p = c["positions"];
  if (p.contains("core_choice")) {
    const nlohmann::json& cand = p["core_choice"]["candidates"];
    std::size_t win = 0;
    for (std::size_t i = 0; i < cand.size(); ++i)
      if (cand[i].value("chosen", false)) win = i;
    const double n = number(p["core_choice"], "validation_residuals");
    best_of_the_rest(cand, win, "held_out_position_loss", "model", "core",
                     "held-out loss of the positions (the library is kept within three "
                     "standard errors of the lowest)",
                     n, rows);
  }
  for (const auto& round : p.value("force_law_on_chain", nlohmann::json::array()))
    elimination(round, "force law added", rows, true);
  elimination(p.value("polynomial_preferred", nlohmann::json()), "term family", rows);
  elimination(p.value("terms_pruned", nlohmann::json()), "higher power", rows);
  elimination(p.value("dissipation_on_positions", nlohmann::json()), "dissipation", rows);
  return rows;
}

}  // namespace csympnet
