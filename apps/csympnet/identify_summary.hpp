// What `fit` (the identification recipe) prints on standard output: γ̂ with its interval, in
// the data's time unit and, when the unit is known, per second, with the amplitude decay rate
// γ̂/2; the modes; the checks of the model's assumptions; the budgets and the quality.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "csympnet/identify/identify.hpp"
#include "csympnet/identify/time_unit.hpp"

namespace csympnet::cli {

// γ̂ and its interval (identified fits only), e.g.
//   gamma_hat = 4.879e-05 ± 2e-07  [4.86e-05, 4.9e-05] per ms (95% interval, ...)
//   gamma_hat = 0.04879 [0.0486, 0.049] per s; amplitude decay rate gamma/2 = 0.0244 per s
void print_gamma(const IdentifyResult& r, const std::optional<TimeUnit>& unit);
// The checks of the model's assumptions: a failed one always, in words; the others unless
// quiet.
// The dissipation found, when the model has friction or drag beside gamma: "dissipation:
// viscous gamma = ... plus dry friction mu = ...".
void print_dissipation(const IdentifyResult& r);

// A driven record's input gain B (q'' = ... + B u) with its interval, one line per entry.
void print_input(const IdentifyResult& r);

void print_checks(const std::vector<ModelCheck>& checks, bool quiet);
// The modes of an identified fit, one line each (report.json "modes" has them in every case).
void print_modes(const IdentifyResult& r, const std::optional<TimeUnit>& unit);
// What `fit` prints beyond γ̂ and the checks unless -q: the model, the budgets, the quality,
// and the files written (the figure's when it was drawn).
void print_identify_details(const IdentifyResult& r, const std::string& out, bool figure);

}  // namespace csympnet::cli
