#include "identify_summary.hpp"

#include <cmath>
#include <cstdio>

#include "progress.hpp"

namespace csympnet::cli {

namespace {

// "ms", or "time unit" when the data's clock has no unit given.
std::string per(const std::optional<TimeUnit>& unit) {
  return unit ? unit->name : std::string("time unit of the data");
}

// Whether any key naming an interval ("interval", "wavenumber_interval", ...) holds one.
bool has_interval(const nlohmann::json& j) {
  if (j.is_array()) {
    for (const auto& x : j)
      if (has_interval(x)) return true;
  } else if (j.is_object()) {
    for (const auto& item : j.items())
      if ((item.key().find("interval") != std::string::npos && !item.value().is_null()) ||
          has_interval(item.value()))
        return true;
  }
  return false;
}

}  // namespace

void print_gamma(const IdentifyResult& r, const std::optional<TimeUnit>& unit) {
  const SandwichInterval& s = *r.interval;
  // The effective blocks, when measured: how many the interval's variance really rests on.
  char effective[64] = "";
  if (s.effective_blocks > 0.0)
    // Two significant digits below 100 ("6.7", "11"), whole numbers above ("150", not "1.5e+02").
    std::snprintf(effective, sizeof effective,
                  s.effective_blocks < 99.5 ? ", %.2g effective" : ", %.0f effective",
                  s.effective_blocks);
  std::printf(
      "gamma_hat = %.10g ± %.2g  [%.10g, %.10g] per %s (%g%% interval, %s, %ld training "
      "blocks%s)\n",
      r.gamma, s.quantile * s.std_error, s.low, s.high, per(unit).c_str(), 100.0 * s.level,
      s.method.c_str(), s.blocks, effective);
  // γ is the energy's decay rate; amplitudes decay as e^{-γt/2}.
  if (unit && unit->name != "s")
    std::printf(
        "gamma_hat = %.6g [%.6g, %.6g] per s; amplitude decay rate gamma/2 = %.6g per s "
        "(time unit %s, from %s)\n",
        r.gamma / unit->seconds, s.low / unit->seconds, s.high / unit->seconds,
        r.gamma / unit->seconds / 2.0, unit->name.c_str(), unit->source.c_str());
  else
    std::printf("amplitude decay rate gamma/2 = %.6g [%.6g, %.6g] per %s\n", r.gamma / 2.0,
                s.low / 2.0, s.high / 2.0, per(unit).c_str());
}

void print_dissipation(const IdentifyResult& r) {
  if (r.dissipation.empty()) return;
  std::printf("dissipation: %s\n", dissipation_sentence(r).c_str());
}

void print_input(const IdentifyResult& r) {
  if (r.input.is_null() || r.input["B"].is_null()) return;
  const nlohmann::json& b = r.input["B"];
  for (std::size_t i = 0; i < b.size(); ++i)
    for (std::size_t j = 0; j < b[i].size(); ++j)
      std::printf("input gain B[q%zu,u%zu]: %.6g [%.6g, %.6g] (q'' = ... + B u, %s hold)\n", i + 1,
                  j + 1, b[i][j].get<double>(), r.input["B_ci_low"][i][j].get<double>(),
                  r.input["B_ci_high"][i][j].get<double>(),
                  r.input["hold"].get<std::string>().c_str());
}

void print_checks(const std::vector<ModelCheck>& checks, bool quiet) {
  for (const ModelCheck& k : checks) {
    if (k.passed && !k.warning && quiet) continue;
    const char* mark = !k.applicable ? "untestable"
                       : !k.passed   ? "FAILED"
                       : k.warning   ? "warning"
                                     : "ok";
    std::printf("check %-16s %-10s %s\n", k.name.c_str(), mark, k.sentence.c_str());
  }
}

void print_modes(const IdentifyResult& r, const std::optional<TimeUnit>& unit) {
  const auto range = [](const std::optional<SandwichInterval>& iv) {
    char buf[96] = "";
    if (iv) std::snprintf(buf, sizeof buf, " [%.6g, %.6g]", iv->low, iv->high);
    return std::string(buf);
  };
  for (std::size_t k = 0; k < r.modes.size(); ++k) {
    const Mode& m = r.modes[k];
    // In a named unit other than s, also in rad/s (the scale people compare with).
    std::string in_s;
    if (unit && unit->name != "s") {
      char buf[128];
      std::snprintf(buf, sizeof buf, " (%.6g rad per s)", m.frequency / unit->seconds);
      in_s = buf;
    }
    std::printf("mode %zu: angular frequency %.6g%s rad per %s%s, damping ratio %.6g%s\n", k + 1,
                m.frequency, range(m.frequency_interval).c_str(), per(unit).c_str(), in_s.c_str(),
                m.damping_ratio, range(m.damping_ratio_interval).c_str());
  }
  if (!r.modes_note.empty()) std::printf("modes: %s\n", r.modes_note.c_str());
  if (r.hamiltonian.is_object()) {
    // From positions alone the momenta's unit, hence H's scale, is not observed: its terms
    // carry no intervals, and the sentence must not promise them.
    const char* where = has_interval(r.hamiltonian) ? "report.json has each term's interval"
                        : r.observed == "positions"
                            ? "from positions alone H is known up to one common factor: its "
                              "terms carry no intervals"
                            : "its terms carry no intervals";
    // The kinetic part too (d = 2 to 4): with a full mass matrix the coupling of a chain may sit in
    // M^-1 alone (V with no difference term), and a potential printed without it reads as
    // uncoupled.
    std::string kinetic;
    const nlohmann::json& w = r.hamiltonian.value("inverse_mass", nlohmann::json());
    if (w.is_array() && w.size() >= 2 && w.size() <= 4) {
      kinetic = ", M^-1 = [";
      for (std::size_t i = 0; i < w.size(); ++i) {
        kinetic += i ? "; " : "";
        for (std::size_t j = 0; j < w[i].size(); ++j) {
          char buf[32];
          std::snprintf(buf, sizeof buf, "%s%.4g", j ? " " : "",
                        w[i][j].is_number() ? w[i][j].get<double>() : NAN);
          kinetic += buf;
        }
      }
      kinetic += "]";
    }
    std::printf("hamiltonian: H = 1/2 p^T M^-1 p + V(q)%s, V(q) = %s (%s)\n", kinetic.c_str(),
                r.hamiltonian.value("potential", std::string()).c_str(), where);
  }
}

// The fitted core in a few words: "library (N terms)", "g:L:w", "la:L:m" (the model file has it
// whole); the configured core when the model has none.
std::string fitted_core(const IdentifyResult& r) {
  nlohmann::json core = r.config.core;
  if (r.model.map) {
    const nlohmann::json spec = r.model.map->hyperparams();
    if (spec.contains("core")) core = spec.at("core");
  }
  if (!core.is_object()) return core.dump();
  const std::string type = core.value("type", std::string());
  if (type == "library")
    return "library (" + std::to_string(core.contains("terms") ? core.at("terms").size() : 0) +
           " terms)";
  if (type == "la")
    return "la:" + std::to_string(core.value("layers", 0)) + ":" +
           std::to_string(core.value("sublayers", 0));
  if (type == "g")
    return "g:" + std::to_string(core.value("layers", 0)) + ":" +
           std::to_string(core.value("width", 0));
  return core.dump();
}

void print_identify_details(const IdentifyResult& r, const std::string& out, bool figure) {
  const bool driven = !r.input.is_null();
  if (driven)
    std::printf("csympnet, d = %lld, %lld params, driven by %lld input%s, core %s\n",
                static_cast<long long>(r.model.dim() / 2),
                static_cast<long long>(r.model.n_params()),
                static_cast<long long>(r.model.map->n_inputs()),
                r.model.map->n_inputs() == 1 ? "" : "s", fitted_core(r).c_str());
  else
    std::printf("csympnet, d = %lld, %lld params, window %ld steps, core %s\n",
                static_cast<long long>(r.model.dim() / 2),
                static_cast<long long>(r.model.n_params()), r.config.window,
                fitted_core(r).c_str());
  // How close each choice between models was (report.json "model_selection").
  for (const nlohmann::json& x : model_selection(r)) {
    const nlohmann::json& m = x["margin"];
    const std::string unit = x.value("margin_unit", std::string());
    char margin[64] = "margin not available";
    if (m.is_number()) {
      if (unit == "relative")
        std::snprintf(margin, sizeof margin, "runner-up's loss %+.3g%%", 100.0 * m.get<double>());
      else
        std::snprintf(margin, sizeof margin, "margin %.3g %s", m.get<double>(), unit.c_str());
    }
    std::printf("model choice (%s): %s, runner-up %s: %s\n",
                x.value("decision", std::string()).c_str(),
                x.value("chosen", std::string()).c_str(),
                x.value("runner_up", std::string()).c_str(), margin);
  }
  // The library core is fitted by Levenberg-Marquardt alone: its AdamW summary ("trained 0
  // epochs ... best validation loss 0") would read as a perfect fit.
  if (driven)
    std::printf(
        "fitted by Levenberg-Marquardt alone: multiple shooting on the positions with "
        "the inputs (no AdamW epochs)\n");
  else if (r.training.epochs_run == 0 && r.config.core.is_object() &&
           r.config.core.value("type", std::string()) == "library")
    std::printf("library core: fitted by Levenberg-Marquardt alone (no AdamW epochs)\n");
  else
    std::printf("%s\n", r.training.brief_report().c_str());
  std::printf(
      "%s\n",
      lm_summary_words(r.lm.iterations, r.lm.accepted, r.lm_best_iteration, r.lm.message).c_str());
  if (driven)
    std::printf("train loss %.3e, held-out loss %.3e (positions, normalised units)\n",
                r.quality.train_loss, r.quality.val_loss);
  else
    std::printf(
        "train loss %.3e, held-out loss %.3e, %s of a window %.2e, structure residual "
        "max %.2e\n",
        r.quality.train_loss, r.quality.val_loss, kHeldOutResidualWords,
        r.quality.val_relative_residual, r.quality.structure_residual_max);
  std::printf("wrote %s/{report.json,model.json,timings.json%s}\n", out.c_str(),
              figure ? ",fit.png,fit.pdf" : "");
}

}  // namespace csympnet::cli
