#include "csympnet/identify/identify.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <sstream>

#include "../kernels/registry.hpp"
#include "../train/lapack.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/core/options.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/identify/model_checks.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/io/json_text.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/models/model_file.hpp"
#include "csympnet/models/normalized_map.hpp"
#include "csympnet/train/window_loss.hpp"
#include "identify_stages.hpp"

namespace csympnet {

const std::vector<std::string>& dof_scales_names() {
  static const std::vector<std::string> names = {"auto", "learned", "fixed"};
  return names;
}

std::string to_string(DofScales s) {
  return dof_scales_names().at(static_cast<std::size_t>(s));
}

DofScales parse_dof_scales(const std::string& text, const char* key) {
  return static_cast<DofScales>(choice_index(key, dof_scales_names(), text));
}

const std::vector<std::string>& dissipation_choices() {
  static const std::vector<std::string> names = {"auto", "viscous", "viscous+coulomb",
                                                 "viscous+drag"};
  return names;
}

const std::vector<std::string>& record_fit_choices() {
  static const std::vector<std::string> names = {"auto", "windows", "whole"};
  return names;
}

const std::vector<std::string>& identify_loss_names() {
  static const std::vector<std::string> names = {"balanced", "one-step"};
  return names;
}

void IdentifyConfig::validate() const {
  kWindowRange.check(window);
  kIdentifyEpochsRange.check(epochs);
  kLmIterationsRange.check(lm_iterations);
  kLrRange.check(lr);
  kValFractionRange.check(val_fraction);
  kBlocksRange.check(target_blocks);
  kLevelRange.check(level);
  kThreadsRange.check(static_cast<long>(threads));
  choice_index("dissipation", dissipation_choices(), dissipation);
  choice_index("record_fit", record_fit_choices(), record_fit);
}

void to_json(nlohmann::json& j, const IdentifyConfig& c) {
  j = {{"core", c.core},
       {"seed", c.seed},
       {"window", c.window},
       {"balanced", c.balanced},
       {"normalize", c.normalize},
       {"epochs", c.epochs},
       {"lr", c.lr},
       {"lm_iterations", c.lm_iterations},
       {"val_fraction", c.val_fraction},
       {"target_blocks", c.target_blocks},
       {"level", c.level},
       {"dof_scales", to_string(c.dof_scales)},
       {"derived_momenta", c.use_derived_momenta ? "use" : "set_aside"},
       {"dissipation", c.dissipation},
       {"record_fit", c.record_fit}};
  if (c.init) j["init"] = {{"file", c.init->file}, {"checksum", c.init->checksum}};
}

std::shared_ptr<const IdentifyInit> load_identify_init(const std::string& file) {
  auto out = std::make_shared<IdentifyInit>();
  out->file = file;
  nlohmann::json doc;
  SavedModel saved;
  try {
    doc = parse_json_text(read_text_file(file), file, "a csympnet model file", model_file_limits());
    saved = model_from_json(doc, file);
  } catch (const OptionError&) {
    throw;
  } catch (const StopRequested&) {
    throw;
  } catch (const Error& e) {
    throw OptionError("init", e.what());
  }
  // model_from_json checked the checksum against the contents: it is the file's.
  out->checksum = doc.at("checksum").get<std::string>();
  out->model = std::move(saved.model);
  out->theta = std::move(saved.theta);
  const nlohmann::json& spec = doc.at("model");
  if (!out->model.is_map() || out->model.type() != "csympnet" ||
      !out->model.damping_param_index().has_value())
    throw OptionError("init", file + ": a model of type '" + out->model.type() +
                                  "'; expected a CSympNet-ID (\"type\": \"csympnet\"), the "
                                  "one-step map with a damping rate that fit refines");
  // The rules --beta-init follows hold for a model file's β too (a β of 0 used to surface
  // later as a failure blamed on the data).
  const double beta = out->theta(*out->model.damping_param_index());
  if (beta == 0.0)
    throw OptionError("init", file +
                                  ": its damping parameter beta is 0; expected a nonzero beta, "
                                  "as --beta-init requires (a model csympnet fitted)");
  out->inner_spec = spec;
  if (spec.contains("normalization")) {
    Normalization n;
    from_json(spec.at("normalization"), n);
    out->normalization = std::move(n);
    out->inner_spec.erase("normalization");
  }
  out->dof_scales = out->inner_spec.contains("dof_scales");
  return out;
}

IdentifyConfig make_identify_config(const nlohmann::json& settings) {
  require(settings.is_object(),
          [&] { return "identify settings: expected a JSON object, got " + settings.dump(); });
  static const char* const kKeys[] = {
      "core",    "seed", "window",          "balanced",     "normalize", "dof_scales",
      "epochs",  "lr",   "lm_iterations",   "val_fraction", "blocks",    "level",
      "threads", "init", "derived_momenta", "dissipation",  "record_fit"};
  for (const auto& item : settings.items()) {
    const bool known = std::any_of(std::begin(kKeys), std::end(kKeys),
                                   [&](const char* k) { return item.key() == k; });
    require(known, [&] { return "identify settings: unknown key '" + item.key() + "'"; });
  }
  // Each value of the JSON kind its key needs, refused by name otherwise (nlohmann's own
  // type_error.302 named neither the key nor what was expected).
  using J = nlohmann::json;
  const auto given = [&](const char* key, const std::function<bool(const J&)>& is_kind,
                         const std::string& expected) {
    if (!settings.contains(key)) return false;
    const J& v = settings.at(key);
    // What was given, in words without braces (an OptionError's problem spells {key}).
    const std::string what = v.is_null()     ? "null"
                             : v.is_string() ? "a string"
                             : v.is_array()  ? "a list"
                             : v.is_object() ? "an object"
                                             : v.dump();
    if (!is_kind(v)) throw OptionError(key, "got " + what + "; expected " + expected);
    return true;
  };
  const auto whole = [](const J& v) { return v.is_number_integer(); };
  const auto number = [](const J& v) { return v.is_number(); };
  const auto flag = [](const J& v) { return v.is_boolean(); };
  const auto text = [](const J& v) { return v.is_string(); };
  IdentifyConfig c;
  if (settings.contains("core")) c.core = settings.at("core");
  if (given(
          "seed",
          [](const J& v) {
            return v.is_number_unsigned() || (v.is_number_integer() && v.get<std::int64_t>() >= 0);
          },
          "a whole number >= 0"))
    c.seed = settings.at("seed").get<std::uint64_t>();
  if (given("window", whole, "a whole number")) c.window = settings.at("window");
  if (given("balanced", flag, "true or false")) c.balanced = settings.at("balanced");
  if (given("normalize", flag, "true or false")) c.normalize = settings.at("normalize");
  if (given("dof_scales", text, "a string (one of auto, learned, fixed)"))
    c.dof_scales = parse_dof_scales(settings.at("dof_scales").get<std::string>());
  if (given("epochs", whole, "a whole number")) c.epochs = settings.at("epochs");
  if (given("lr", number, "a number")) c.lr = settings.at("lr");
  if (given("lm_iterations", whole, "a whole number"))
    c.lm_iterations = settings.at("lm_iterations");
  if (given("val_fraction", number, "a number")) c.val_fraction = settings.at("val_fraction");
  if (given("blocks", whole, "a whole number")) c.target_blocks = settings.at("blocks");
  if (given("level", number, "a number")) c.level = settings.at("level");
  if (given("threads", whole, "a whole number")) c.threads = settings.at("threads");
  static const std::vector<std::string> kDerived = {"set_aside", "use"};
  if (given("derived_momenta", text, "a string (one of set_aside, use)"))
    c.use_derived_momenta = choice_index("derived_momenta", kDerived,
                                         settings.at("derived_momenta").get<std::string>()) == 1;
  if (given("dissipation", text, "a string (one of auto, viscous, viscous+coulomb, viscous+drag)"))
    c.dissipation = settings.at("dissipation").get<std::string>();
  if (given("record_fit", text, "a string (one of auto, windows, whole)"))
    c.record_fit = settings.at("record_fit").get<std::string>();
  c.validate();
  // Refused here, before any data are read, as well as in identify() for a config built by
  // hand: friction and drag are terms of the library core.
  const bool forced = c.dissipation != "auto" && c.dissipation != "viscous";
  const bool library_core =
      c.core.is_null() || (c.core.is_object() && c.core.value("type", "") == "library");
  const bool with_init = settings.contains("init") && !settings.at("init").is_null();
  if (forced && (!library_core || with_init))
    throw OptionError("dissipation", "'" + c.dissipation +
                                         "' is a term of the library core; expected core "
                                         "library (or none given) and no init file, or "
                                         "dissipation auto or viscous");
  if (settings.contains("init") && !settings.at("init").is_null()) {
    if (!settings.at("init").is_string() || settings.at("init").get<std::string>().empty())
      throw OptionError("init", "expected the path of a model file");
    c.init = load_identify_init(settings.at("init").get<std::string>());
    const IdentifyInit& init = *c.init;
    if (!c.core.is_null())
      throw OptionError(
          "core", "cannot be given with {init}: the model file " + init.file + " fixes the core");
    if (!c.normalize && init.normalization)
      throw OptionError("normalize", "cannot be switched off with {init}: the model file " +
                                         init.file +
                                         " carries a normalisation, and its parameters are in "
                                         "those units");
    const bool learned = c.dof_scales == DofScales::kLearned;
    if (c.dof_scales != DofScales::kAuto && learned != init.dof_scales)
      throw OptionError("dof_scales",
                        "'" + to_string(c.dof_scales) + "' disagrees with {init}: " + init.file +
                            (init.dof_scales ? " learns" : " has no") + " per-dof momentum scales");
  }
  return c;
}

void to_json(nlohmann::json& j, const IdentifyQuality& q) {
  j = {{"train_loss", q.train_loss},
       {"val_loss", q.val_loss},
       {"val_relative_residual", q.val_relative_residual},
       {"null_ratio", q.null_ratio},
       {"structure_residual_max", q.structure_residual_max}};
}

namespace {

IdentifyResult identify_once(const std::vector<Trajectory>& trajs, bool pairs_only,
                             const IdentifyConfig& config, const IdentifyHooks& hooks,
                             bool confirm_growth);

// A given library core is read by the model files' reader (read_library_spec), so it refuses
// what a model file refuses, in the same words. Of its keys the identification takes only the
// terms (none: it selects them); the integrator, the mass matrix and the scales it chooses
// itself (identification.md, "The Hamiltonian-library core"), so a key that sets them is
// refused rather than ignored.
void check_given_library_core(const nlohmann::json& core, Index d) {
  if (!core.is_object() || !core.contains("type") || core.at("type") != "library") return;
  read_library_spec(core, d, "core");
  require(!core.contains("inputs"), [] {
    return std::string(
        "core: key 'inputs' is for a record with known inputs (columns u1..um, Python's u=); "
        "this record has none");
  });
  for (const char* key : {"order", "substeps", "mass", "coordinate_scales"})
    require(!core.contains(key), [&] {
      return std::string("core: key '") + key +
             "' is chosen by the identification (order 6, substeps refined until the "
             "integrator's error is below the residuals, the mass matrix and the scales from "
             "the data); expected only the keys type, terms and dissipation (a model file of such "
             "a core is refitted with init)";
    });
}

void check_inputs(const std::vector<Trajectory>& trajs, const IdentifyConfig& config) {
  config.validate();
  require(!trajs.empty(), "fit: no data");
  for (std::size_t k = 0; k < trajs.size(); ++k)
    trajs[k].validate("fit: trajectory " + std::to_string(k));
  const Index d = trajs.front().z.rows() / 2;
  check_given_library_core(config.core, d);
  // Friction and drag are terms of the library core: a forced one needs that core.
  const bool forced =
      config.dissipation == "viscous+coulomb" || config.dissipation == "viscous+drag";
  const bool library_core = config.core.is_null() ||
                            (config.core.is_object() && config.core.value("type", "") == "library");
  if (forced && (!library_core || config.init != nullptr))
    throw OptionError("dissipation",
                      "'" + config.dissipation +
                          "' is a term of the library core; expected core library (or none "
                          "given) and no init file, or dissipation auto or viscous");
  const IdentifyInit* init = config.init.get();
  if (init != nullptr && init->model.dim() != 2 * d)
    throw OptionError("init",
                      init->file + " is a model of d = " + std::to_string(init->model.dim() / 2) +
                          " degrees of freedom, but the data have d = " + std::to_string(d) +
                          "; expected a model of the data's dimension");
}

// The init file's map at its parameters must predict finite states on these data: a
// coefficient or wavenumber of 1e300 otherwise surfaced later as an error blamed on the data
// ("windows: non-finite value", or a Gauss-Newton matrix that could not be factored).
void check_init_start(const detail::Candidate& x, const detail::CandidateFit& fit,
                      const detail::BlockSplit& split, const IdentifyInit& init) {
  const double loss = fit.loss(x, split.train);
  if (std::isfinite(loss)) return;
  throw OptionError("init", init.file +
                                ": the model's map at the file's parameters predicts non-finite "
                                "states from these data (training loss " +
                                number_text(loss) +
                                " at the start); expected a model whose parameters give finite "
                                "predictions on data like these (its coefficients or "
                                "wavenumbers may be far too large)");
}

}  // namespace

IdentifyResult identify(const std::vector<Trajectory>& trajs, bool pairs_only,
                        const IdentifyConfig& config, const IdentifyHooks& hooks) {
  const lapack::SingleThreaded one_thread;  // the same bits on every core count (lapack.hpp)
  // Momenta computed from noisy positions would hand the damping rate their differenced noise
  // and the filter's bias: they are set aside, and the positions fitted alone.
  if (!pairs_only) {
    check_inputs(trajs, config);
    ModelCheck derived = measured_momenta_check(trajs, false);
    if (derived.applicable && !derived.passed && !config.use_derived_momenta) {
      std::vector<Trajectory> positions;
      for (const Trajectory& t : trajs) positions.push_back({t.t, t.z.topRows(t.z.rows() / 2), {}});
      derived.passed = true;
      derived.sentence = derived.sentence.substr(0, derived.sentence.find(": they carry")) +
                         "): they would hand the damping rate the positions' noise differenced "
                         "and the filter's bias, so they were set aside and the momenta fitted "
                         "as hidden states from the positions alone";
      return detail::positions_in_place_of_momenta(positions, config, hooks, derived);
    }
  }
  return identify_once(trajs, pairs_only, config, hooks, true);
}

namespace detail {

// The data in reversed time: each trajectory (a pair is a two-point trajectory) read from its
// end, t' = t_end − t. Growing motion, dp/dt = −∇V + g p (g > 0), is then decaying motion at
// the rate g (with p' = −p, a change of sign the model's core absorbs).
std::vector<Trajectory> reversed_in_time(const std::vector<Trajectory>& trajs) {
  std::vector<Trajectory> out;
  for (const Trajectory& t : trajs) {
    Trajectory r;
    r.t = (t.t(t.t.size() - 1) - t.t.array()).reverse().matrix();
    r.z = t.z.rowwise().reverse();
    out.push_back(std::move(r));
  }
  return out;
}

// When the dissipation check finds growing motion, the same pipeline runs on the record in
// reversed time, where growing motion decays: its γ̂ and interval are the growth rate and its
// interval. If the reversed record seems to grow too, no process explains both directions:
// the "growth" is a bias (noise at small damping), and the check is left undecided.
GrowthRate confirm_growth(const std::vector<Trajectory>& trajs, const Refit& refit,
                          const IdentifyConfig& config, const IdentifyHooks& hooks,
                          ModelChecks checks, bool stopped) {
  GrowthRate out;
  out.checks = std::move(checks);
  ModelCheck* growth = nullptr;
  for (ModelCheck& k : out.checks)
    if (k.name == "dissipation" && !k.passed) growth = &k;
  if (growth == nullptr || stopped || config.init != nullptr) return out;
  if (hooks.stage) hooks.stage("growth rate (the same fit in reversed time)");
  const IdentifyResult rev = refit(reversed_in_time(trajs));
  if (rev.stopped) {
    out.stopped = true;
    return out;
  }
  nlohmann::json g = {{"rate", rev.gamma}, {"verdict", rev.verdict}, {"reasons", rev.reasons}};
  bool grows_backwards = false;
  for (const ModelCheck& k : rev.checks)
    grows_backwards = grows_backwards || (k.name == "dissipation" && !k.passed);
  std::ostringstream s;
  s.precision(4);
  if (grows_backwards) {
    growth->passed = true;
    growth->applicable = false;
    s << "not decided: the record seems to gain energy in both directions of time, which no "
         "energy input explains (a bias of noise at weak damping); signed rate "
      << growth->details.value("signed_rate", 0.0) << " forwards";
    growth->sentence = s.str();
  } else if (rev.identified) {
    g["interval"] = {rev.interval->low, rev.interval->high};
    s << "the motion grows: energy is being added (negative damping or forcing), at a rate "
      << rev.gamma << " [" << rev.interval->low << ", " << rev.interval->high
      << "] per time unit (the same fit in reversed time, where the motion decays)";
    growth->sentence = s.str();
    growth->effect = rev.gamma;
  }
  growth->details["reversed_time_fit"] = g;
  return out;
}

namespace {

// The candidate cores: the given one, the init file's, or an LA and a G core chosen between by
// validation loss; the library core first (fit_core), unless beyond kLibraryMaxD.
struct CoreCandidates {
  bool choosing = false;
  bool library_given = false;
  bool library_tried = false;
  std::vector<nlohmann::json> cores;  // the neural (or given, or init file's) cores
};
CoreCandidates core_candidates(const IdentifyConfig& c, const IdentifyConfig& given,
                               const DataFacts& facts) {
  CoreCandidates out;
  out.choosing = c.core.is_null();
  out.library_given = !out.choosing && given.init == nullptr && c.core.is_object() &&
                      c.core.contains("type") && c.core.at("type") == "library";
  // A forced friction or drag term lives in the library core alone: the only candidate.
  const bool forced_dissipation = c.dissipation != "auto" && c.dissipation != "viscous";
  out.cores = out.choosing && !forced_dissipation ? default_cores(facts.d, facts.varying_steps)
              : out.library_given || out.choosing ? std::vector<nlohmann::json>{}
                                                  : std::vector<nlohmann::json>{c.core};
  // Beyond d = kLibraryMaxD the library core is left out of the choice (its cost, about d² per
  // LM iteration, passes the neural cores'); given with --core library, it runs at any d.
  out.library_tried =
      out.library_given || (out.choosing && (facts.d <= kLibraryMaxD || forced_dissipation));
  return out;
}

// Progress reports γ̂ in the data's time units, not the normalised ones the fit works in.
IdentifyHooks in_user_units(const IdentifyHooks& hooks, double tau) {
  IdentifyHooks user_hooks = hooks;
  if (hooks.progress)
    user_hooks.progress = [&hooks, tau](const TrainProgress& p) {
      TrainProgress q = p;
      q.gamma_hat = p.gamma_hat / tau;
      return hooks.progress(q);
    };
  return user_hooks;
}

// The chosen core as the windows left it, for the stages after fit_core.
void keep_chosen(CoreFit& f, const CandidateFit& fit) {
  const Candidate& best = f.cand[f.best];
  f.theta = best.theta;
  f.training = best.training;
  f.stopped = fit.stopped();
  f.lm = best.lm;
  f.lm_best_iteration = best.lm_best_iteration;
  for (const Candidate& x : f.cand) {
    f.lm_seconds += x.lm_seconds;
    f.adamw_seconds += x.training.seconds;
  }
  f.gamma = best.inner.map->damping_rate(f.theta).value_or(0.0) / f.units.normalization.time_scale;
  f.train_loss = fit.loss(best, f.split.train);
  f.val_loss = fit.loss(best, f.split.val);
}

}  // namespace

CoreFit fit_core(const std::vector<Trajectory>& trajs, bool pairs_only,
                 const IdentifyConfig& config, const IdentifyHooks& hooks,
                 const FloorTest& floor_test, const RefitFollows& refit_follows) {
  check_inputs(trajs, config);
  const Communicator& comm =
      hooks.communicator != nullptr ? *hooks.communicator : serial_communicator();
  CoreFit f;
  IdentifyConfig& c = f.config;  // resolved as each stage chooses
  c = config;
  f.choices = nlohmann::json::object();
  f.facts = inspect_data(trajs, pairs_only);
  f.units = choose_units(trajs, pairs_only, config);
  c.normalize = f.units.normalize;
  f.choices.update(f.units.choices);
  // A property of the data alone, reported whatever the fit does.
  f.data_check = measured_momenta_check(f.units.trajectories, pairs_only);
  if (config.use_derived_momenta && !f.data_check.passed) {
    f.data_check.passed = true;
    f.data_check.sentence +=
        " (used as given, derived_momenta = use: the interval does not account for "
        "that bias)";
  }
  f.split = split_blocks(f.units.trajectories, pairs_only, config);
  f.choices["blocks"] = f.split.summary;
  const IdentifyHooks user_hooks = in_user_units(hooks, f.units.normalization.time_scale);

  if (config.init != nullptr) c.core = config.init->inner_spec.at("core");
  CoreCandidates cc = core_candidates(c, config, f.facts);
  if (hooks.stage) hooks.stage("warm start");
  f.warm = warm_start(f.split, f.facts.d, config);
  c.dof_scales = f.warm.dof_scales;
  f.choices.update(f.warm.choices);
  CandidateFit fit(config, c, user_hooks, comm, f.split,
                   1.0 / static_cast<double>(std::max<std::size_t>(cc.cores.size(), 1)));
  // The library core first: where it explains the held-out data to the noise floor, the
  // neural cores are not trained (their budget buys nothing the data can show).
  std::optional<Candidate> library;
  std::string floor_reason;
  if (cc.choosing && !cc.library_tried)
    f.choices["library_skipped"] = "d = " + std::to_string(f.facts.d) + " > " +
                                   std::to_string(kLibraryMaxD) +
                                   ": the library core is not tried by default (--core library "
                                   "runs it)";
  bool library_thinned = false;
  if (cc.library_tried) {
    if (hooks.stage) hooks.stage("library core");
    // Its final fit is a start where a fit of the record follows once it is chosen.
    const bool start_only = refit_follows && refit_follows(nlohmann::json{{"type", "library"}});
    LibraryFit lib = fit_library(fit, cc.library_given ? c.core : nlohmann::json::object(),
                                 f.facts.d, f.warm.beta_init, f.units.normalization, c.balanced,
                                 comm, c.dissipation, start_only);
    library_thinned = lib.thinned;
    if (hooks.stage) hooks.stage("library: the noise-floor test");
    // Not judged after a stop request: the fit ends with the candidate as it stands.
    const bool stopping = fit.stop_requested();
    const bool at_floor =
        !stopping &&
        (floor_test && cc.choosing ? floor_test(lib.cand, f.split, floor_reason, lib.record)
                                   : at_noise_floor(lib.cand, f.split, c.balanced, floor_reason));
    if (stopping) floor_reason = "not judged: a stop was requested";
    if (at_floor && cc.choosing) cc.cores.clear();
    lib.record["floor"] = floor_reason;
    f.choices["library"] = lib.record;
    library = std::move(lib.cand);
  }
  f.cand = make_candidates(cc.cores, f.facts.d, f.warm.beta_init, c, config.seed);
  if (config.init != nullptr) check_init_start(f.cand.front(), fit, f.split, *config.init);
  if (library) f.cand.insert(f.cand.begin(), std::move(*library));
  f.choice = choose_core(f.cand, fit, cc.choosing, f.facts.varying_steps, config);
  f.best = f.choice.index;
  c.core = f.choice.core;
  c.epochs = f.choice.epochs;
  c.lm_iterations = f.choice.lm_iterations;
  f.choices.update(f.choice.choices);
  if (cc.choosing && f.cand.size() == 1) f.choices["core_reason"] = floor_reason;
  if (cc.library_given) f.choices["core_reason"] = "given: the library core, its terms selected";
  Candidate& best = f.cand[f.best];
  f.lm_fits = best.inner.n_params() <= 6000;
  if (!f.lm_fits) f.choices["lm_note"] = "more than 6000 parameters: no LM, no interval";
  f.choices["lm_patience"] = kLmPatience;
  f.windows = adapt_windows(best, fit, f.split, config, f.facts.summary.value("pairs_file", false),
                            c.balanced, refit_follows && refit_follows(best.core));
  f.thinned_start = f.windows.thinned || (best.pretrained && library_thinned && f.best == 0);
  f.choices.update(f.windows.choices);
  c.window = f.split.m;
  f.choices["window"] = f.split.m;
  keep_chosen(f, fit);
  return f;
}

void windows_on_every_window(CoreFit& f, const IdentifyConfig& config, const IdentifyHooks& hooks) {
  if (!f.thinned_start) return;
  const Communicator& comm =
      hooks.communicator != nullptr ? *hooks.communicator : serial_communicator();
  const IdentifyHooks user_hooks = in_user_units(hooks, f.units.normalization.time_scale);
  CandidateFit fit(config, f.config, user_hooks, comm, f.split, 1.0);
  Candidate& best = f.cand[f.best];
  const long budget = fit.lm_budget(best, 15.0);
  fit.lm(best, budget, "LM on longer windows (every window)",
         CandidateFit::LmEnd::kChi2OrGammaSettled);
  f.choices["then_every_window"] = {
      {"why",
       "the chosen core was fitted on thinned windows as a start, and the fit of the record that "
       "was to refit theta was not made: LM on every window"},
      {"lm_iterations", best.lm.iterations}};
  f.thinned_start = false;
  f.theta = best.theta;
  f.lm = best.lm;
  f.lm_best_iteration = best.lm_best_iteration;
  f.stopped = f.stopped || fit.stopped();
  f.gamma = best.inner.map->damping_rate(f.theta).value_or(0.0) / f.units.normalization.time_scale;
  f.train_loss = fit.loss(best, f.split.train);
  f.val_loss = fit.loss(best, f.split.val);
}

Model user_model(const Model& inner, const Normalization& units, const IdentifyInit* init) {
  nlohmann::json user_spec = inner.hyperparams();
  if (init == nullptr || init->normalization) user_spec["normalization"] = units;
  return make_model(user_spec);
}

IntervalBasis interval_basis(const CoreFit& f, const Vector& theta, const nlohmann::json& core,
                             double train_loss, double val_loss) {
  IntervalBasis at;
  at.theta = theta;
  at.units = f.units.normalization;
  at.level = f.config.level;
  at.balanced = f.config.balanced;
  at.train_loss = train_loss;
  at.val_loss = val_loss;
  if (core.is_object() && core.value("type", nlohmann::json()) == "library") {
    at.library = f.choices.value("library", nlohmann::json::object());
    at.library_core = core;
  }
  return at;
}

Evidence evidence(const CoreFit& f, const FinalFit& end, ModelChecks checks,
                  std::vector<std::string> reasons, bool stopped) {
  Evidence e;
  e.gamma = end.gamma;
  e.interval = end.interval.interval;
  e.quality = end.quality;
  e.training_stop = end.training.value_or(f.training).stop_reason;
  e.level = f.config.level;
  e.stopped = stopped;
  e.checks = std::move(checks);
  e.reasons = std::move(reasons);
  return e;
}

// The one place the result is put together: what fit_core's stages found, and where the
// route's last fit ended and how it was judged.
IdentifyResult assemble(const CoreFit& f, const FinalFit& end) {
  IdentifyResult r;
  r.config = f.config;
  r.data = f.facts.summary;
  r.normalization = f.units.normalization;
  r.choices = f.choices;
  r.choices.update(end.choices);
  if (end.core) {
    r.config.core = *end.core;
    r.choices["core"] = *end.core;
  }
  r.warm_start = f.warm.gamma;
  r.warm_start_note = f.warm.note;
  r.training = end.training.value_or(f.training);
  r.lm = end.lm.value_or(f.lm);
  r.lm_best_iteration = f.lm_best_iteration;
  r.adamw_seconds = f.adamw_seconds;
  r.lm_seconds = f.lm_seconds;
  r.interval_seconds = end.interval.seconds;
  r.observed = end.observed;
  r.theta = end.theta;
  r.gamma = end.gamma;
  r.quality = end.quality;
  r.interval = end.interval.interval;
  r.modes = end.interval.modes.list;
  r.modes_note = end.interval.modes.note;
  r.hamiltonian = end.hamiltonian;
  r.dissipation = end.dissipation;
  r.checks = end.verdict.checks;
  r.reasons = end.verdict.reasons;
  r.identified = end.verdict.identified;
  r.rejected = end.verdict.rejected;
  r.verdict = end.verdict.text;
  r.stopped = f.stopped || end.stopped;
  r.model = user_model(f.cand[f.best].inner, r.normalization, f.config.init.get());
  return r;
}

}  // namespace detail

namespace {

// The windows route: fit_core, then (a record with momenta) the whole record, γ̂'s interval,
// the quality, the checks, the growth rate in reversed time, the verdict; assembled from what
// each returns.
IdentifyResult identify_once(const std::vector<Trajectory>& trajs, bool pairs_only,
                             const IdentifyConfig& config, const IdentifyHooks& hooks,
                             bool confirm_growth_in_reversed_time) {
  using namespace detail;
  CoreFit f = fit_core(trajs, pairs_only, config, hooks, {},
                       [pairs_only, &config](const nlohmann::json& core) {
                         return !pairs_only && whole_record_wanted(core, config);
                       });
  const Communicator& comm =
      hooks.communicator != nullptr ? *hooks.communicator : serial_communicator();
  FinalFit end;
  end.theta = f.theta;
  end.gamma = f.gamma;
  end.quality.train_loss = f.train_loss;
  end.quality.val_loss = f.val_loss;
  nlohmann::json core = f.config.core;
  bool stopped = f.stopped;
  // γ̂'s interval and the model's quality, in the user's time units.
  const bool assess = !stopped && f.lm_fits && f.training.stop_reason != StopReason::kDiverged;
  // Trajectories with momenta: the whole record fitted with q and p observed, its interval
  // (identify_states.cpp); else the windows' interval.
  bool whole = false;
  if (assess && !pairs_only && whole_record_wanted(f.cand[f.best].core, f.config)) {
    WholeRecordFit w = fit_whole_record(f, config, hooks);
    stopped = stopped || w.stopped;
    end.choices["whole_record"] = w.record;
    if (w.core) core = *w.core;
    end.core = w.core;
    whole = w.fitted;
    if (whole) {
      end.theta = w.theta;
      end.gamma = w.gamma;
      end.quality.train_loss = w.train_loss;
      end.quality.val_loss = w.val_loss;
      end.interval = std::move(w.interval);
    }
  }
  if (assess && !whole && !stopped && f.thinned_start) {
    windows_on_every_window(f, config, hooks);
    end.theta = f.theta;
    end.gamma = f.gamma;
    end.quality.train_loss = f.train_loss;
    end.quality.val_loss = f.val_loss;
    stopped = stopped || f.stopped;
  }
  const OneStepMap& map = *f.cand[f.best].inner.map;
  if (assess && !whole && !stopped) {
    end.interval = interval(
        map, interval_basis(f, end.theta, core, end.quality.train_loss, end.quality.val_loss),
        f.split, f.units.trajectories, hooks, comm);
    stopped = stopped || end.interval.stopped;
  }
  const HeldOutQuality held = measure_quality(map, end.theta, f.split, f.facts.d);
  end.quality.val_relative_residual = held.val_relative_residual;
  end.quality.null_ratio = held.null_ratio;
  end.quality.structure_residual_max = held.structure_residual_max;
  const Normalization& units = f.units.normalization;
  ModelChecks checks = {f.data_check};
  if (assess && !stopped)
    for (ModelCheck& k :
         run_checks(map, end.theta, f.split, units.time_scale, f.config.level, hooks))
      checks.push_back(std::move(k));
  if (confirm_growth_in_reversed_time) {
    GrowthRate growth = confirm_growth(
        trajs,
        [&](const std::vector<Trajectory>& reversed) {
          return identify_once(reversed, pairs_only, config, hooks, false);
        },
        config, hooks, std::move(checks), stopped);
    checks = std::move(growth.checks);
    stopped = stopped || growth.stopped;
  }
  end.verdict = verdict(f.split, f.facts.h_max, f.lm_fits,
                        evidence(f, end, std::move(checks), end.interval.reasons, stopped));
  end.hamiltonian = end.interval.hamiltonian.is_null()
                        ? hamiltonian_report(map, end.theta, units, {})
                        : end.interval.hamiltonian;
  end.dissipation = end.interval.dissipation && !end.interval.dissipation->empty()
                        ? *end.interval.dissipation
                        : dissipation_terms_report(map, end.theta, units, {});
  end.stopped = stopped;
  return assemble(f, end);
}

// The report's "dissipation": the viscous rate first, then friction and drag; intervals as
// claims, only for an identified γ̂.
nlohmann::json dissipation_report(const IdentifyResult& r) {
  nlohmann::json terms = nlohmann::json::array();
  const bool claim = r.identified && r.interval.has_value();
  terms.push_back({{"kind", "viscous"},
                   {"dof", nullptr},
                   {"value", r.gamma},
                   {"low", claim ? nlohmann::json(r.interval->low) : nlohmann::json(nullptr)},
                   {"high", claim ? nlohmann::json(r.interval->high) : nlohmann::json(nullptr)},
                   {"unit", "1/time unit: p' = ... - gamma p"}});
  for (nlohmann::json t : r.dissipation) {
    if (!r.identified) t["low"] = t["high"] = nullptr;
    terms.push_back(std::move(t));
  }
  return {{"terms", terms},
          {"sentence", dissipation_sentence(r)},
          {"level", r.interval ? nlohmann::json(r.interval->level) : nlohmann::json(nullptr)},
          {"choice", r.config.dissipation},
          {"about",
           "the dissipation of the fitted model: the viscous rate gamma (the conformal factor), "
           "Coulomb friction as the deceleration mu of its coordinate (q'' = ... - mu "
           "sign(q')), quadratic drag as c (q'' = ... - c q'|q'|), in the data's units; "
           "intervals are the sandwich intervals of gamma_hat's kind, given only when "
           "gamma_hat is identified"}};
}

// The modes: frequencies and damping ratios always; their intervals, as γ̂'s, only when γ̂ is
// identified.
nlohmann::json modes_report(const IdentifyResult& r) {
  nlohmann::json list = nlohmann::json::array();
  const auto claim = [&](const std::optional<SandwichInterval>& iv) {
    return r.identified && iv ? nlohmann::json::array({iv->low, iv->high})
                              : nlohmann::json(nullptr);
  };
  for (const Mode& m : r.modes)
    list.push_back({{"angular_frequency", m.frequency},
                    {"angular_frequency_interval", claim(m.frequency_interval)},
                    {"damping_ratio", m.damping_ratio},
                    {"damping_ratio_interval", claim(m.damping_ratio_interval)}});
  return {{"list", list},
          {"about",
           "the fitted map linearised at its equilibrium: natural angular frequency (radians per "
           "time unit of the data) and damping ratio of each oscillating mode, for small "
           "oscillations; a nonlinear system's frequencies change with amplitude"},
          {"note", r.modes_note}};
}

}  // namespace

std::string dissipation_sentence(const IdentifyResult& r) {
  const auto range = [&](const nlohmann::json& lo, const nlohmann::json& hi) {
    if (!r.identified || lo.is_null() || hi.is_null()) return std::string();
    return " [" + detail::significant(lo.get<double>()) + ", " +
           detail::significant(hi.get<double>()) + "]";
  };
  std::string s = "viscous gamma = " + detail::significant(r.gamma);
  if (r.identified && r.interval)
    s += " [" + detail::significant(r.interval->low) + ", " +
         detail::significant(r.interval->high) + "]";
  s += " per time unit";
  for (const auto& t : r.dissipation) {
    const bool coulomb = t["kind"] == "coulomb";
    s += std::string(" plus ") + (coulomb ? "dry friction mu" : "quadratic drag c");
    if (r.model.dim() > 2) s += "_" + std::to_string(t["dof"].get<Index>());
    s += " = " + detail::significant(t["value"].get<double>()) + range(t["low"], t["high"]) +
         (coulomb ? " (q unit per time unit squared)" : " (per q unit)");
  }
  if (r.dissipation.empty()) s += " (no friction or drag term in the model)";
  return s;
}

namespace {

// Removes every "seconds" key below `x` (a stage's wall time in the choices' records), keeping
// each in `out` (when given) under its path, e.g. "choices.positions.linking.stages[1].seconds".
void take_wall_seconds(nlohmann::json& x, const std::string& path, nlohmann::json* out) {
  if (x.is_object()) {
    if (x.contains("seconds") && x["seconds"].is_number()) {
      if (out != nullptr) (*out)[path + ".seconds"] = x["seconds"];
      x.erase("seconds");
    }
    for (auto it = x.begin(); it != x.end(); ++it)
      take_wall_seconds(*it, path + "." + it.key(), out);
  } else if (x.is_array()) {
    for (std::size_t i = 0; i < x.size(); ++i)
      take_wall_seconds(x[i], path + "[" + std::to_string(i) + "]", out);
  }
}

}  // namespace

nlohmann::json identify_report(const IdentifyResult& r) {
  nlohmann::json j = {
      {"model", "csympnet"},
      {"identified", r.identified},
      {"not_identified_reason",
       r.identified ? nlohmann::json(nullptr)
                    : nlohmann::json([&] {
                        std::string s;
                        for (const auto& x : r.reasons) s += (s.empty() ? "" : "; ") + x;
                        return r.stopped && s.empty() ? std::string("interrupted") : s;
                      }())},
      {"reasons", r.reasons},
      {"verdict", r.verdict},
      {"checks", r.checks},
      {"observed", r.observed},
      {"gamma_unit", "1/time unit of the data"},
      {"gamma_hat", r.gamma},
      // The interval as a claim: only for an identified γ̂ ("interval" keeps its details).
      {"gamma_ci_low", r.identified ? nlohmann::json(r.interval->low) : nlohmann::json(nullptr)},
      {"gamma_ci_high", r.identified ? nlohmann::json(r.interval->high) : nlohmann::json(nullptr)},
      {"gamma_ci_level", r.interval ? nlohmann::json(r.interval->level) : nlohmann::json(nullptr)},
      {"gamma_ci_method", r.interval ? nlohmann::json(r.interval->method) : nlohmann::json(nullptr)},
      {"interval", r.interval ? nlohmann::json(*r.interval) : nlohmann::json(nullptr)},
      {"hamiltonian", r.hamiltonian},
      {"dissipation", dissipation_report(r)},
      {"data", r.data},
      {"normalization", r.normalization},
      {"choices", r.choices},
      {"model_selection", model_selection(r)},
      {"config", r.config},
      {"params", r.model.n_params()},
      {"warm_start", r.warm_start ? nlohmann::json({{"gamma_normalised", r.warm_start->gamma},
                                                    {"method", to_string(r.warm_start->method)}})
                                  : nlohmann::json(r.warm_start_note)},
      {"training", [&] {
         nlohmann::json t = r.training;
         t.erase("seconds");  // wall times go to timings.json: the report is the same run to run
         return t;
       }()},
      {"lm",
       {{"iterations", r.lm.iterations},
        {"accepted", r.lm.accepted},
        {"best_iteration", r.lm_best_iteration},
        {"initial_cost", r.lm.initial_cost},
        {"final_cost", r.lm.final_cost},
        {"message", r.lm.message}}},
      {"quality", r.quality},
      {"stopped", r.stopped},
      {"architecture", r.model.hyperparams()}};
  j["modes"] = modes_report(r);
  if (!r.input.is_null()) j["input"] = r.input;
  if (r.config.init)
    j["init"] = {{"file", r.config.init->file}, {"checksum", r.config.init->checksum}};
  // As a run's configuration records it (run.cpp): only when not the default.
  if (kernels::arithmetic() != kernels::kDefaultArithmetic)
    j["arithmetic"] = kernels::to_string(kernels::arithmetic());
  // The stages' wall times (identify_wall_seconds) stay out: the report is the same run to run.
  take_wall_seconds(j["choices"], "choices", nullptr);
  return j;
}

nlohmann::json identify_wall_seconds(const IdentifyResult& r) {
  nlohmann::json choices = r.choices, out = nlohmann::json::object();
  take_wall_seconds(choices, "choices", &out);
  return out;
}

}  // namespace csympnet
