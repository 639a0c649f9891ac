// `evaluate` (diagnostics of a saved model) and `rollout` (iterate a saved model).
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <string>

#include "commands.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/data/csv.hpp"
#include "csympnet/diagnostics/learned_map.hpp"
#include "csympnet/diagnostics/observed.hpp"
#include "csympnet/diagnostics/positions_score.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/models/model_file.hpp"
#include "csympnet/paper/outputs.hpp"
#include "csympnet/paper/run.hpp"
#include "csympnet/train/positions_state.hpp"
#include "csympnet/train/shooting.hpp"
#include "interrupt.hpp"
#include "rollout_inputs.hpp"
#include "standard_streams.hpp"
#include "system_options.hpp"

namespace csympnet::cli {

namespace {
struct EvaluateArgs {
  std::string model, preset, data, out, columns;
  std::optional<double> h_test;
  std::optional<long> warmup;
  bool force = false;
  SystemOverrides system;
};

Vector parse_state(const std::string& s, Index dim) {
  std::vector<double> v;
  std::stringstream in(s);
  std::string item;
  while (std::getline(in, item, ',')) {
    std::size_t pos = 0;
    double x = 0.0;
    try {
      x = std::stod(item, &pos);
    } catch (const std::exception&) {
      pos = 0;
    }
    if (pos == 0 || pos != item.size() || !std::isfinite(x))
      throw Error("--z0: '" + item + "' is not a finite number; expected " + std::to_string(dim) +
                  " comma-separated finite numbers q1,..,qd,p1,..,pd");
    v.push_back(x);
  }
  if (static_cast<Index>(v.size()) != dim)
    throw Error("--z0 has " + std::to_string(v.size()) + " values; expected " +
                std::to_string(dim) + ", as the model's state q1..qd,p1..pd");
  return Eigen::Map<Vector>(v.data(), dim);
}

// The known system of an evaluation and its diagnostics' settings: --preset, else the one the
// model file records. Without either, only the observed data (--data) can score the model: no
// γ is assumed, and the options that change a system are refused.
struct EvaluateSystem {
  std::optional<RunConfig> config;
  std::optional<System> system;
};
EvaluateSystem evaluate_system(const EvaluateArgs& a, const SavedModel& saved) {
  EvaluateSystem known;
  std::optional<RunConfig>& c = known.config;
  if (!a.preset.empty()) {
    c = default_run_config(a.preset, "csympnet");
  } else if (saved.meta.contains("system") && saved.meta["system"].is_object()) {
    // Only an object is a system (what `run` writes); a plain string or any other value
    // (a label a user or another tool put there) records none.
    c = default_run_config("s1", "csympnet");
    try {
      c->preset.system = saved.meta["system"].get<SystemSpec>();
    } catch (const std::exception& e) {  // Error or nlohmann::json::exception
      throw Error(a.model + ": meta.system is not a valid system (" + e.what() +
                  "); expected one as written by csympnet run, or pass --preset");
    }
  }
  require(c.has_value() || !a.data.empty(), [&] {
    return "--data or --preset is required: " + a.model +
           " does not record its system; expected --data TRAJ.csv (observed trajectories) or "
           "--preset s1|s2|s3|s2-100|s3-100";
  });
  require(c.has_value() || !a.system.any(), [&] {
    return "--d, --gamma, --omega, --k and --alpha change a known system, and " + a.model +
           " records none; expected --preset with them";
  });
  require(c.has_value() || !a.h_test, [&] {
    return std::string(
        "--h-test is the step of the diagnostics against a known system; "
        "expected --preset with it (against --data the observed steps are used)");
  });
  std::optional<System>& sys = known.system;
  if (c) {
    a.system.apply(c->preset);
    if (a.h_test) c->preset.h_test = *a.h_test;
    sys.emplace(c->preset.system);
    require(sys->dim() == saved.model.dim(), [&] {
      return "the model's dimension " + std::to_string(saved.model.dim()) +
             " does not match the system's " + std::to_string(sys->dim());
    });
  }
  return known;
}

// What evaluate scores: observed trajectories of states (or the system's test set), or
// positions (with inputs, a driven record, its momenta set aside).
struct EvaluateData {
  std::vector<Trajectory> tests;
  std::vector<Trajectory> positions;  // a positions file: d × n per trajectory
  bool positions_only = false, driven = false;
  std::string where;  // the data's name, for messages
};
EvaluateData evaluate_data(const EvaluateArgs& a, const SavedModel& saved,
                           const EvaluateSystem& known) {
  require(!a.warmup || !a.data.empty(), [&] {
    return std::string(
        "--warmup is the warm-up window of a positions file; expected --data POSITIONS.csv "
        "with it");
  });
  EvaluateData out;
  std::vector<Trajectory>& tests = out.tests;
  std::vector<Trajectory>& positions = out.positions;
  std::optional<CsvInput> input;
  if (!a.data.empty()) input = read_csv_input(a.data, parse_column_map(a.columns));
  // A record with inputs is scored as positions (its momenta, if any, set aside): a free run
  // driven by its inputs from a state fitted to the warm-up.
  const bool driven_data = out.driven = input && input->inputs > 0;
  const bool positions_data = out.positions_only =
      input && (input->kind == CsvKind::kPositions || driven_data);
  if (input) out.where = input->name;
  require(!a.warmup || positions_data, [&] {
    return "--warmup is the warm-up window of a positions file, and " + a.data +
           " holds states (their rollouts start from the first observed state); expected "
           "--warmup only with a positions file '[traj,]t,q1..qd'";
  });
  if (driven_data) {
    const bool states = input->kind != CsvKind::kPositions;
    positions =
        states ? parse_trajectories_csv(std::move(input->text), input->name, InputColumns::kRead)
               : parse_positions_csv(std::move(input->text), input->name, InputColumns::kRead);
    if (states)
      for (Trajectory& t : positions) t.z = Matrix(t.z.topRows(t.z.rows() / 2));
  } else if (positions_data) {
    positions = parse_positions_csv(std::move(input->text), input->name);
    // A known system is diagnosed on its own test set (the preset's) when there is one.
    if (!a.preset.empty()) {
      Rng rng(known.config->test_seed, "test-trajectories");
      tests =
          generate_test_set(*known.system, known.config->preset.n_test, known.config->preset.h_test,
                            known.config->preset.horizon, rng, known.config->reference)
              .trajectories;
    }
  } else if (input) {
    tests = parse_trajectories_csv(std::move(input->text), input->name);
    // Reading accepts single-point trajectories (they are valid data); a rollout needs two.
    for (std::size_t k = 0; k < tests.size(); ++k) {
      require(tests[k].z.rows() == saved.model.dim(), [&] {
        return a.data + ": the trajectories have " + std::to_string(tests[k].z.rows() / 2) +
               " degrees of freedom; expected d = " + std::to_string(saved.model.dim() / 2) +
               " like the model " + a.model;
      });
      // The L2 error squares differences of states; beyond 1e150 they overflow.
      require(tests[k].z.cwiseAbs().maxCoeff() <= 1e150, [&] {
        return a.data + ": trajectory " + std::to_string(k + 1) +
               " has a state value beyond 1e150 in magnitude (its square overflows "
               "double); expected |value| <= 1e150";
      });
      require(tests[k].steps() >= 1, [&] {
        return a.data + ": trajectory " + std::to_string(k + 1) + " of " +
               std::to_string(tests.size()) +
               " has a single point; expected at least two points per test trajectory";
      });
    }
  } else {
    // The test set's size, span and step are a preset's; none is assumed.
    require(!a.preset.empty(), [&] {
      return "--data or --preset is required to know the test set: " + a.model +
             " records its system but not a test set";
    });
    Rng rng(known.config->test_seed, "test-trajectories");
    tests =
        generate_test_set(*known.system, known.config->preset.n_test, known.config->preset.h_test,
                          known.config->preset.horizon, rng, known.config->reference)
            .trajectories;
  }
  return out;
}

// evaluate's report: the diagnostics against the known system, the observed scores, the
// positions' free-run score and, for a driven record, the simulation.
nlohmann::json evaluate_report(const EvaluateArgs& a, const SavedModel& saved,
                               const EvaluateSystem& known, const EvaluateData& data) {
  // The positions first: a refusal (a short trajectory, a window the model does not explain)
  // comes before any diagnostics of a test set.
  nlohmann::json positions_score;
  if (data.positions_only) {
    PositionsScoreOptions opt;
    opt.warmup = a.warmup;
    opt.where = data.where;
    positions_score = score_positions(saved.model, saved.theta, data.positions, opt);
  }
  const LearnedMap map = learned_map(saved.model, saved.theta);
  nlohmann::json rep;
  if (known.system && !data.tests.empty()) {
    rep = evaluate(map, *known.system, data.tests, known.config->preset.h_test);
    rep["gamma_true"] = known.system->gamma();
    rep["system"] = known.config->preset.system;
    rep["h_test"] = known.config->preset.h_test;
  } else {
    rep["gamma_hat"] = map.gamma_hat ? nlohmann::json(*map.gamma_hat) : nlohmann::json(nullptr);
    rep["gamma_true"] =
        known.system ? nlohmann::json(known.system->gamma()) : nlohmann::json(nullptr);
    rep["system"] =
        known.system ? nlohmann::json(known.config->preset.system) : nlohmann::json(nullptr);
  }
  if (data.driven) {
    // The free-run simulation driven by the record's inputs, in the data's units.
    rep["simulation"] = {{"rmse", positions_score["rmse_per_coordinate"]},
                         {"rmse_all", positions_score["rmse"]},
                         {"nrmse", positions_score["nrmse"]},
                         {"warmup", a.warmup ? nlohmann::json(*a.warmup)
                                             : positions_score["per_trajectory"][0]["warmup"]},
                         {"samples_scored", positions_score["samples_scored"]},
                         {"inputs", data.positions.front().u.rows()},
                         {"rollout_finite", positions_score["rollout_finite"]},
                         {"about",
                          "free run of the model driven by the record's inputs u from a state "
                          "fitted to the first warmup samples of each trajectory (left out of "
                          "the score); rmse per q column in the data's units"}};
  }
  if (data.positions_only) {
    rep["positions"] = std::move(positions_score);
    rep["data"] = a.data;
  } else if (!a.data.empty()) {
    try {
      rep["observed"] = score_observed(map, data.tests);
    } catch (const Error& e) {
      throw Error(a.data + ": " + e.what());
    }
    rep["data"] = a.data;
  }
  rep["model_file"] = a.model;
  rep["model"] = saved.model.type();
  rep["params"] = saved.model.n_params();
  // The trajectories rolled out: the system's test set, else the positions scored.
  rep["test_trajectories"] = data.tests.empty() ? data.positions.size() : data.tests.size();
  return rep;
}

}  // namespace

void add_evaluate(CLI::App& app) {
  auto a = std::make_shared<EvaluateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "evaluate", "Roll a saved model out on test trajectories; print the diagnostics as JSON");
  cmd->add_option("--model", a->model, "Model file")->required()->check(kExistingFile);
  cmd->add_option("--preset", a->preset,
                  "System and test set of this preset (default: the model's own system)")
      ->check(one_of(preset_names()));
  cmd->add_option("--data", a->data,
                  "Observed trajectories CSV: the model is rolled out on them and scored "
                  "(one-step and rollout errors, no system needed); with a system, also the "
                  "test set of its diagnostics (default: the preset's test set). A file of "
                  "positions alone ('[traj,]t,q1..qd') is scored from a state fitted to a "
                  "warm-up window (--warmup), under \"positions\"")
      ->check(kExistingFile);
  add_columns_option(*cmd, a->columns);
  cmd->add_option("--warmup", a->warmup,
                  "With a positions file: the first N samples of each trajectory, to which the "
                  "start state is fitted and which are left out of the score (default: a tenth "
                  "of the samples, at least " +
                      std::to_string(kWarmupDefaultMin) + " and at most " +
                      std::to_string(kWarmupDefaultMax) + ")")
      ->check(kWholeNumber)
      ->check(library_range(kWarmupRange));
  cmd->add_option("--h-test", a->h_test, "Step of the Jacobian diagnostics (default 0.2)")
      ->check(kFiniteNumber)
      ->check(kStep);
  cmd->add_option("--out", a->out, "Also write DIR/report.json")->check(kOutputPath);
  cmd->add_flag("--force", a->force, "Allow writing into a non-empty output directory");
  a->system.add_to(*cmd);
  cmd->callback([a] {
    if (parse_only()) return;
    std::optional<OutputDir> out_dir;
    if (!a->out.empty()) out_dir.emplace(a->out, a->force);
    const SavedModel saved = load_model(a->model);
    const EvaluateSystem known = evaluate_system(*a, saved);
    const EvaluateData data = evaluate_data(*a, saved, known);
    const nlohmann::json rep = evaluate_report(*a, saved, known, data);
    if (out_dir) out_dir->commit({{"report.json", json_file_text(rep)}});
    std::cout << rep.dump(2) << "\n";
  });
}

namespace {

// The state at the last sample of a positions file (one trajectory), its momenta fitted with
// the model (state_from_positions); t0 receives that sample's time.
Vector state_at_end_of_positions(const SavedModel& saved, const std::string& path,
                                 const std::string& columns, double& t0) {
  if (!saved.model.is_map() || saved.model.type() != "csympnet")
    throw Error(path +
                ": --from-positions needs a csympnet model (a one-step map with a damping "
                "rate, as fit writes); the model is of type '" +
                saved.model.type() + "'");
  const CsvInput input = read_csv_input(path, parse_column_map(columns));
  if (input.kind != CsvKind::kPositions)
    throw Error(input.name +
                ": expected a positions header '[traj,]t,q1..qd' for "
                "--from-positions (the positions alone, or --columns t=TIME,q1=POSITION "
                "naming them; use --z0 for a state)");
  const Index m = saved.model.map->n_inputs();
  if (m > 0 && input.inputs != m)
    throw Error(input.name + ": the model is driven by " + std::to_string(m) +
                " input(s); expected the window's inputs u1..u" + std::to_string(m) +
                " beside its positions ('t,q1..qd,u1..u" + std::to_string(m) + "')");
  const std::vector<Trajectory> trajs = parse_positions_csv(
      input.text, input.name, m > 0 ? InputColumns::kRead : InputColumns::kRefuse);
  if (trajs.size() != 1 || trajs.front().t.size() < 2)
    throw Error(input.name +
                ": expected one trajectory of at least 2 positions for "
                "--from-positions, got " +
                std::to_string(trajs.size()) + " trajectories");
  const Trajectory& w = trajs.front();
  if (2 * w.z.rows() != saved.model.dim())
    throw Error(input.name + ": " + std::to_string(w.z.rows()) +
                " positions per row; the model has d = " + std::to_string(saved.model.dim() / 2));
  double rms = 0.0;
  // Refused, exit 1, when the fit does not explain the window: no forecast from nonsense.
  const Vector z = checked_state_from_positions(*saved.model.map, saved.theta, w.z, w.t, &rms,
                                                input.name, step_inputs(w.u, 0, w.t.size() - 1));
  t0 = w.t(w.t.size() - 1);
  std::fprintf(stderr, "rollout: state at t = %s fitted to %lld positions (rms residual %s)\n",
               number_text(t0).c_str(), static_cast<long long>(w.t.size()),
               number_text(rms).c_str());
  return z;
}

}  // namespace

void add_rollout(CLI::App& app) {
  auto model = std::make_shared<std::string>();
  auto z0 = std::make_shared<std::string>();
  auto h = std::make_shared<double>(0.0);
  auto steps = std::make_shared<long>(0);
  CLI::App* cmd =
      app.add_subcommand("rollout", "Iterate a saved model from z0; print t,q..,p.. as CSV");
  cmd->add_option("--model", *model, "Model file")->required()->check(kExistingFile);
  auto positions = std::make_shared<std::string>();
  CLI::Option* z0_opt = cmd->add_option("--z0", *z0, "Initial state q1,..,qd,p1,..,pd");
  CLI::Option* pos_opt =
      cmd->add_option("--from-positions", *positions,
                      "Start from the end of a recent record of positions alone (a positions "
                      "CSV 't,q1..qd', one trajectory): its momenta are fitted with the model "
                      "(a csympnet model); the rollout starts at its last time")
          ->check(kExistingFile);
  auto columns = std::make_shared<std::string>();
  add_columns_option(*cmd, *columns)->needs(pos_opt);
  auto inputs = std::make_shared<std::string>();
  CLI::Option* inputs_opt =
      cmd->add_option("--inputs", *inputs,
                      "A driven model's known inputs at each sample time of the rollout: a CSV "
                      "'[t,]u1..um' with --steps + 1 rows (t0, t0 + h, ...), held between "
                      "samples as the model holds them")
          ->check(kExistingFile);
  z0_opt->excludes(pos_opt);
  pos_opt->excludes(z0_opt);
  cmd->add_option("--h", *h, "Step")->required()->check(kFiniteNumber)->check(kStep);
  cmd->add_option("--steps", *steps, "Number of steps")
      ->required()
      ->check(kWholeNumber)
      ->check(in_range(1L, 100000000L));
  cmd->callback([=] {
    if (parse_only()) return;
    const SavedModel saved = load_model(*model);
    const bool from_positions = pos_opt->count() > 0;
    if (z0_opt->count() == 0 && !from_positions)
      throw CLI::ValidationError("--z0",
                                 "expected the initial state q1,..,qd,p1,..,pd, or "
                                 "--from-positions FILE (a record of positions alone)");
    const Index m = saved.model.is_map() ? saved.model.map->n_inputs() : 0;
    if (m > 0 && inputs_opt->count() == 0)
      throw CLI::ValidationError("--inputs", "the model is driven by " + std::to_string(m) +
                                                 " input(s); expected --inputs FILE with u1..u" +
                                                 std::to_string(m) +
                                                 " at each of the --steps + 1 times");
    if (m == 0 && inputs_opt->count() > 0)
      throw CLI::ValidationError("--inputs",
                                 "the model has no inputs (it was fitted to a free record); "
                                 "expected no --inputs");
    double t0 = 0.0;
    Vector z = from_positions ? state_at_end_of_positions(saved, *positions, *columns, t0)
                              : parse_state(*z0, saved.model.dim());
    const Matrix u = m > 0 ? read_rollout_inputs(*inputs, m, *steps, t0, *h) : Matrix();
    const LearnedMap map = learned_map(saved.model, saved.theta);
    Vector hs(1);
    hs(0) = *h;
    // One step: the learned map, or a driven map fed its inputs at the step's start and end.
    const auto step = [&](Index n) -> Vector {
      if (m == 0) return map.step(z, *h);
      Vector un(2 * m);
      un << u.col(n - 1), u.col(n);
      return saved.model.map->forward_driven(saved.theta, z, hs, un, nullptr);
    };
    const Index d = saved.model.dim() / 2;
    std::string line = "t";
    for (Index i = 1; i <= d; ++i) line += ",q" + std::to_string(i);
    for (Index i = 1; i <= d; ++i) line += ",p" + std::to_string(i);
    print_line(line);
    // Streamed, a row per step: memory stays constant for any --steps, and a signal stops it
    // within a few thousand steps (the rows printed are the rollout up to there).
    auto print = [&](Index n) {
      std::string row = round_trip_text(t0 + static_cast<double>(n) * *h);
      for (Index i = 0; i < z.size(); ++i) row += "," + round_trip_text(z(i));
      print_line(row);  // a failed write (a full disk) ends the rollout at once
    };
    print(0);
    for (Index n = 1; n <= *steps; ++n) {
      if (n % 1024 == 0 && interrupted())
        throw Interrupted("rollout stopped after step " + std::to_string(n - 1) +
                          "; the rows printed are the rollout up to it");
      Vector next;
      try {
        next = step(n);
      } catch (const StopRequested&) {
        throw Interrupted("rollout stopped during step " + std::to_string(n) +
                          "; the rows printed are the rollout up to step " + std::to_string(n - 1));
      } catch (const Error& e) {
        // A vector-field model's integrator gave up (its step budget, a state that blew up).
        const std::string why = e.what();
        throw Error("rollout: step " + std::to_string(n) +
                    " (t = " + number_text(static_cast<double>(n) * *h) + ", --h " +
                    number_text(*h) + ") failed: " + why +
                    (why.find("expected") != std::string::npos
                         ? std::string()
                         : "; expected a model that can be iterated at --h " + number_text(*h) +
                               " from this --z0 (try a smaller step)"));
      }
      // Non-finite output is an error, not rows of nan: say where the rollout broke down.
      if (!next.allFinite())
        throw Error("rollout: the state is not finite after step " + std::to_string(n) +
                    " (t = " + number_text(static_cast<double>(n) * *h) +
                    "); expected a finite state: the model cannot be iterated at --h " +
                    number_text(*h) + " from this --z0 (try a smaller step)");
      z = std::move(next);
      print(n);
    }
  });
}

}  // namespace csympnet::cli
