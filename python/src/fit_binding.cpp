// Training from Python: fit_pairs (paper/fit.hpp, what `csympnet fit` runs) and run
// (paper/run.hpp, what `csympnet run` runs). Training releases the GIL; the progress
// callback takes it back after each validation to call the user's callback, or, without one,
// at most every 50 ms (signal_poll.hpp) to let Ctrl-C stop the run.
#include <limits>
#include <optional>
#include <string>
#include <type_traits>

#include <pybind11/stl.h>

#include "convert.hpp"
#include "csympnet/identify/identify.hpp"
#include "csympnet/identify/time_unit.hpp"
#include "csympnet/paper/fit.hpp"
#include "csympnet/paper/run.hpp"
#include "model_binding.hpp"
#include "signal_poll.hpp"

namespace csympnet::py_binding {

namespace {

// Wraps an optional Python callable as a ProgressCallback. The callable gets a dict and stops
// training by returning False. A Python exception raised by it, or a pending signal
// (KeyboardInterrupt), stops training and is re-raised by rethrow_if_stopped() once the GIL is
// held again.
class PythonProgress {
 public:
  explicit PythonProgress(py::object callback) : callback_(std::move(callback)) {}

  ProgressCallback callback() {
    return [this](const TrainProgress& p) {
      // Without a callback the GIL is taken only to look for signals, as often as
      // should_stop() does: a validation can come every few microseconds.
      if (callback_.is_none() && !signal_clock_.due()) return true;
      py::gil_scoped_acquire gil;
      try {
        if (PyErr_CheckSignals() != 0) throw py::error_already_set();
        if (callback_.is_none()) return true;
        py::dict info;
        info["stage"] = p.stage;
        info["epoch"] = p.epoch;
        info["epochs"] = p.epochs;
        info["train_loss"] = std::isnan(p.train_loss) ? py::none() : py::cast(p.train_loss);
        info["val_loss"] = std::isnan(p.val_loss) ? py::none() : py::cast(p.val_loss);
        info["best_val_loss"] =
            std::isnan(p.best_val_loss) ? py::none() : py::cast(p.best_val_loss);
        info["gamma"] = std::isnan(p.gamma_hat) ? py::none() : py::cast(p.gamma_hat);
        info["seconds"] = p.seconds;
        const py::object result = callback_(info);
        return result.is_none() || result.cast<bool>();
      } catch (py::error_already_set& e) {
        error_.emplace(std::move(e));
        return false;
      }
    };
  }

  // For the stages after AdamW (LM, L-BFGS, the bootstrap): true once a signal is pending
  // (KeyboardInterrupt, re-raised by rethrow_if_stopped) or the callback has stopped the fit.
  // Python's signals are looked at every kSignalPollInterval at most.
  std::function<bool()> should_stop() {
    return [this] {
      if (error_) return true;
      if (!signal_clock_.due()) return false;
      py::gil_scoped_acquire gil;
      if (PyErr_CheckSignals() != 0) {
        error_.emplace();  // fetches the pending KeyboardInterrupt
        return true;
      }
      return false;
    };
  }

  // Call with the GIL held.
  void rethrow_if_stopped() {
    if (error_) {
      py::error_already_set e = std::move(*error_);
      error_.reset();
      throw e;
    }
  }

 private:
  py::object callback_;
  std::optional<py::error_already_set> error_;
  SignalPollClock signal_clock_;
};

PairSet pairs_from(const DArray& z0, const DArray& z1, const DArray& h, const std::string& name) {
  PairSet p;
  p.z0 = states_from(z0, name + " z0");
  p.z1 = states_from(z1, name + " z1", p.z0.rows());
  p.h = vector_from(h, name + " h", p.z0.cols());
  p.validate(name);
  return p;
}

// The options of csympnet.fit as given (None: the recipe's).
struct FitArgs {
  FitSettings settings;
  std::vector<Index> groups;  // trajectory of each training pair, or empty
};

std::unique_ptr<PyModel> fit(const DArray& z0, const DArray& z1, const DArray& h,
                             const std::optional<py::tuple>& val, const FitArgs& a,
                             const py::object& progress) {
  // csympnet.fit runs `csympnet fit --recipe classic`: the identification recipe. Every
  // option is checked here, before any work (an OptionError names it as Python spells it).
  const FitConfig c = make_fit_config(FitConfig::identification(), a.settings);
  const PairSet train = pairs_from(z0, z1, h, "training pairs");
  std::optional<PairSet> val_pairs;
  if (val) {
    require(val->size() == 3, "validation: expected a (z0, z1, h) triple");
    val_pairs = pairs_from((*val)[0].cast<DArray>(), (*val)[1].cast<DArray>(),
                           (*val)[2].cast<DArray>(), "validation pairs");
  }
  require(a.groups.empty() || static_cast<Index>(a.groups.size()) == train.size(),
          "groups: expected one trajectory label per training pair");

  PythonProgress watch(progress);
  FitResult r;
  {
    py::gil_scoped_release nogil;
    r = fit_pairs(train, val_pairs, c, watch.callback(), a.groups, watch.should_stop());
  }
  watch.rethrow_if_stopped();

  auto out = std::make_unique<PyModel>();
  out->training = r.training;
  // A map trained with the classic recipe: γ̂ is a training outcome with no interval
  // (kNoIntervalNote); a bootstrap asked for is its spread, in meta["bootstrap"].
  const nlohmann::json train_json = r.config.train;
  out->meta = {{"source", "python fit"},        {"seed", r.config.seed},
               {"train", train_json},           {"config", r.config},
               {"pairs_train", r.train.size()}, {"pairs_val", r.val.size()}};
  if (r.interval) out->meta["bootstrap"] = *r.interval;
  if (!r.interval_note.empty()) out->meta["gamma_interval_note"] = r.interval_note;
  if (!r.scale_note.empty()) out->meta["warnings"] = {r.scale_note};
  out->model = std::move(r.model);
  out->theta = std::move(r.theta);
  return out;
}

struct RunArgs {
  std::string preset, model, recipe, reference, system_json;
  std::uint64_t seed;
  std::optional<long> epochs;
  std::optional<double> lr;
  std::optional<std::string> lr_schedule;
  long val_every;
  double sigma, beta_init;
  bool decay_damping;
  int threads;
};

// One preset run as `csympnet run` does it (apps/csympnet/cmd_run.cpp): returns the model,
// the report as JSON text, the learned rollouts and the reference test trajectories.
py::tuple run(const RunArgs& a, const py::object& progress) {
  RunConfig c = default_run_config(a.preset, a.model);
  const nlohmann::json overrides = parse_json(a.system_json, "system");
  if (!overrides.is_null()) {
    nlohmann::json sys = c.preset.system;
    sys.update(overrides);
    c.preset.system = sys.get<SystemSpec>();
  }
  c.seed = a.seed;
  c.sigma = a.sigma;
  apply_run_recipe(c, parse_run_recipe(a.recipe));
  if (a.epochs) c.train.epochs = *a.epochs;
  if (a.lr) c.train.adamw.lr = *a.lr;
  if (a.lr_schedule) c.train.lr_schedule = parse_lr_schedule(*a.lr_schedule);
  c.train.val_every = a.val_every;
  c.train.threads = a.threads;
  c.train.adamw.decay_damping = a.decay_damping;
  c.reference.method = parse_reference(a.reference);
  c.beta_init = a.beta_init;
  c.validate();  // every option, before any work

  PythonProgress watch(progress);
  RunResult r;
  {
    py::gil_scoped_release nogil;
    r = run_experiment(c, watch.callback(), true, watch.should_stop());
  }
  watch.rethrow_if_stopped();

  auto model = std::make_unique<PyModel>();
  model->training = r.training;
  model->meta = {{"source", "python run"},
                 {"preset", c.preset.name},
                 {"system", c.preset.system},
                 {"seed", c.seed},
                 {"train", r.report["config"]["train"]}};
  model->model = std::move(r.model);
  model->theta = std::move(r.theta);
  py::list rollouts;
  for (const Matrix& z : r.diagnostics.rollouts) rollouts.append(states_to(z));
  return py::make_tuple(std::move(model), r.report.dump(), rollouts,
                        trajectories_to(r.data.test.trajectories));
}

// identify() (what `csympnet fit` runs): returns the model and the report as JSON text.
// `positions_only`: each z is a record of positions alone, (M, d), fitted by
// identify_positions (or identify_driven on its positions); else states (M, 2d).
py::tuple identify_trajectories(const py::sequence& trajs, bool pairs_only,
                                const std::string& config_json, const py::object& progress,
                                bool positions_only, const py::object& inputs) {
  // Every option checked first, before any work.
  const IdentifyConfig c = make_identify_config(parse_json(config_json, "config"));
  std::vector<Trajectory> data = positions_only ? positions_from(trajs, "trajectories")
                                                : trajectories_from(trajs, "trajectories");
  // Known inputs, one (M, m) array per trajectory: the driven route (identify_driven).
  const bool driven = !inputs.is_none();
  if (driven) {
    const auto seq = inputs.cast<py::sequence>();
    require(seq.size() == data.size(), "u: expected one array of inputs per trajectory");
    for (std::size_t k = 0; k < data.size(); ++k) {
      const std::string where = "u[" + std::to_string(k) + "]";
      data[k].u = states_from(seq[k].cast<DArray>(), where);
      require(data[k].u.cols() == data[k].t.size(), [&] {
        return where + ": " + std::to_string(data[k].u.cols()) + " rows of inputs for " +
               std::to_string(data[k].t.size()) + " sample times; expected one row per time";
      });
      // Positions are checked by identify_driven (a state's validate() wants 2d rows).
      if (!positions_only) data[k].validate("trajectories[" + std::to_string(k) + "]");
    }
  }
  PythonProgress watch(progress);
  IdentifyHooks hooks;
  hooks.progress = watch.callback();  // AdamW and LM
  // LM and the interval poll for Ctrl-C through the same watcher.
  hooks.should_stop = watch.should_stop();
  IdentifyResult r;
  {
    py::gil_scoped_release nogil;
    if (driven)
      r = identify_driven(data, positions_only, c, hooks);
    else if (positions_only)
      r = identify_positions(data, c, hooks);
    else
      r = identify(data, pairs_only, c, hooks);
  }
  watch.rethrow_if_stopped();  // a KeyboardInterrupt, or the progress callback's exception
  if (r.stopped) {
    PyErr_SetNone(PyExc_KeyboardInterrupt);
    throw py::error_already_set();
  }
  const nlohmann::json report = identify_report(r);
  auto out = std::make_unique<PyModel>();
  out->training = r.training;
  // Only an identified γ̂ carries its interval (as in the report's gamma_ci_low/high).
  if (r.identified && r.interval)
    out->gamma_interval = std::pair{r.interval->low, r.interval->high};
  out->meta = {{"source", "python identify"}, {"seed", r.config.seed}, {"recipe", "identify"}};
  if (out->gamma_interval) {
    out->meta["gamma_interval"] = {out->gamma_interval->first, out->gamma_interval->second};
    out->meta["gamma_interval_level"] = r.interval->level;
  }
  out->model = std::move(r.model);
  out->theta = std::move(r.theta);
  return py::make_tuple(std::move(out), report.dump());
}

}  // namespace

void bind_fit(py::module_& m) {
  m.def("identify", &identify_trajectories, py::arg("trajectories"), py::arg("pairs_only"),
        py::arg("config_json"), py::arg("progress"), py::arg("positions_only") = false,
        py::arg("inputs") = py::none(),
        "identify() of identify/identify.hpp (wrapped by csympnet.identify).");
  // The spellings of the second stage's methods and LM's solvers (train/refine.hpp).
  m.def("refine_methods", &refine_method_names);
  m.def("refine_choices", &refine_choice_names);  // "auto", then refine_methods()
  m.def("linear_solvers", &linear_solver_names);
  m.def("fit_models", &fit_model_names);
  m.def("lr_schedules", &lr_schedule_names);
  m.def("dof_scales", &dof_scales_names);
  m.def("identify_losses", &identify_loss_names);
  m.def("run_recipes", &run_recipe_names);
  // The clock's unit (identify/time_unit.hpp): its names, the unit a time column's name
  // states, and the report's "time_unit" object for an identification's report.
  m.def("time_units", &time_unit_names);
  m.def("time_unit_of_column", [](const std::string& column) -> std::optional<std::string> {
    const std::optional<TimeUnit> u = time_unit_of_column(column);
    return u ? std::optional<std::string>(u->name) : std::nullopt;
  });
  m.def("time_unit_report", [](const std::optional<std::string>& unit, const std::string& source,
                               const std::string& report_json) {
    std::optional<TimeUnit> u;
    if (unit) u = parse_time_unit(*unit, source);
    return time_unit_report(u, parse_json(report_json, "report")).dump();
  });
  // The recipe csympnet.fit's defaults mirror, as JSON text (tests/test_fit.py compares them).
  m.def("fit_recipe_json", [] { return nlohmann::json(FitConfig::identification()).dump(); });
  m.def(
      "fit_pairs",
      [](const DArray& z0, const DArray& z1, const DArray& h, const std::optional<py::tuple>& val,
         std::optional<std::string> model, const std::string& core_json,
         std::optional<std::uint64_t> seed, std::optional<double> val_fraction,
         std::optional<double> beta_init, std::optional<long> epochs, std::optional<long> val_every,
         std::optional<double> lr, std::optional<std::string> lr_schedule,
         std::optional<double> lr_final_fraction, std::optional<double> weight_decay,
         std::optional<bool> decay_damping, std::optional<bool> warm_start,
         std::optional<std::string> refine, std::optional<long> refine_iterations,
         std::optional<std::string> refine_solver, std::optional<long> bootstrap,
         std::vector<Index> groups, std::optional<int> threads, std::optional<long> chunk_pairs,
         std::optional<long> batch_size, const py::object& progress) {
        FitArgs a;
        FitSettings& s = a.settings;
        s.model = std::move(model);
        s.core = parse_json(core_json, "core");
        s.seed = seed;
        s.val_fraction = val_fraction;
        s.beta_init = beta_init;
        s.epochs = epochs;
        s.val_every = val_every;
        s.lr = lr;
        s.lr_schedule = std::move(lr_schedule);
        s.lr_final_fraction = lr_final_fraction;
        s.weight_decay = weight_decay;
        s.decay_damping = decay_damping;
        s.warm_start = warm_start;
        s.refine = std::move(refine);
        s.refine_iterations = refine_iterations;
        s.refine_solver = std::move(refine_solver);
        s.bootstrap = bootstrap;
        s.threads = threads;
        s.chunk_pairs = chunk_pairs;
        s.batch_size = batch_size;
        a.groups = std::move(groups);
        return fit(z0, z1, h, val, a, progress);
      },
      py::arg("z0"), py::arg("z1"), py::arg("h"), py::arg("val"), py::arg("model"),
      py::arg("core_json"), py::arg("seed"), py::arg("val_fraction"), py::arg("beta_init"),
      py::arg("epochs"), py::arg("val_every"), py::arg("lr"), py::arg("lr_schedule"),
      py::arg("lr_final_fraction"), py::arg("weight_decay"), py::arg("decay_damping"),
      py::arg("warm_start"), py::arg("refine"), py::arg("refine_iterations"),
      py::arg("refine_solver"), py::arg("bootstrap"), py::arg("groups"), py::arg("threads"),
      py::arg("chunk_pairs"), py::arg("batch_size"), py::arg("progress"),
      "fit_pairs() of paper/fit.hpp (wrapped by csympnet.fit).");
  m.def(
      "run",
      [](const std::string& preset, const std::string& model, std::uint64_t seed,
         std::optional<long> epochs, const std::string& recipe, std::optional<double> lr,
         std::optional<std::string> lr_schedule, long val_every, double sigma, double beta_init,
         bool decay_damping, const std::string& reference, const std::string& system_json,
         int threads, const py::object& progress) {
        const RunArgs a{preset,        model,  recipe,      reference, system_json, seed,
                        epochs,        lr,     lr_schedule, val_every, sigma,       beta_init,
                        decay_damping, threads};
        return run(a, progress);
      },
      py::arg("preset"), py::arg("model"), py::arg("seed"), py::arg("epochs"), py::arg("recipe"),
      py::arg("lr"), py::arg("lr_schedule"), py::arg("val_every"), py::arg("sigma"),
      py::arg("beta_init"), py::arg("decay_damping"), py::arg("reference"), py::arg("system_json"),
      py::arg("threads"), py::arg("progress"),
      "run_experiment() of paper/run.hpp (wrapped by csympnet.run).");
}

}  // namespace csympnet::py_binding
