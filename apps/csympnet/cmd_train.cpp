// `train` and `fit`: learn a one-step map from a user's CSV (pairs or trajectories).
#include <unistd.h>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "commands.hpp"
#include "core_option.hpp"
#include "csympnet/core/communicator.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/data/csv.hpp"
#include "csympnet/identify/identify.hpp"
#include "csympnet/identify/time_unit.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/models/model_file.hpp"
#include "csympnet/paper/fit.hpp"
#include "csympnet/paper/outputs.hpp"
#include "csympnet/train/loss.hpp"
#include "fit_figure.hpp"
#include "identify_summary.hpp"
#include "interrupt.hpp"
#include "progress.hpp"
#include "stage_clock.hpp"
#include "system_options.hpp"

namespace csympnet::cli {

namespace {
// The options as given; those not given are left to the recipe (FitConfig's, or
// IdentifyConfig's for fit's default recipe).
struct FitArgs {
  explicit FitArgs(FitConfig r) : classic(std::move(r)), warm_start(classic.warm_start) {}
  // The recipe of `train` (FitConfig::adamw_only) or of `fit --recipe classic`
  // (FitConfig::identification): one-step loss, second stage, bootstrap.
  FitConfig classic;
  std::string data, val, out, core;
  std::string columns;  // --columns: the file's own header names (ColumnMap)
  std::optional<std::string> model, lr_schedule, refine, refine_solver;
  std::optional<double> lr, val_fraction, beta_init;
  std::optional<std::uint64_t> seed;
  std::optional<long> epochs, val_every, refine_iterations, bootstrap, chunk_pairs, batch_size;
  bool no_beta_decay = false, quiet = false, force = false;
  bool warm_start;
  int threads = 1;
  // fit's identification recipe (identify/identify.hpp), or "classic" (`classic` above),
  // which `train` always uses.
  std::string recipe = "identify";
  long window = 0, lm_iterations = 0, blocks = 20;
  std::string loss = "balanced", dof_scales = "auto", derived_momenta = "set-aside";
  std::string dissipation = "auto";
  std::string record_fit = "auto";
  std::string init;       // --init FILE: a model file to start from (IdentifyConfig::init)
  std::string time_unit;  // --time-unit: the clock's unit, for the report only (time_unit.hpp)
  bool no_normalize = false;
  bool no_figures = false;  // --no-figures: no OUT/fit.png, OUT/fit.pdf (fit_figure.hpp)
  double level = 0.95;
};

void add_fit_options(CLI::App& cmd, FitArgs& a) {
  const FitConfig& recipe = a.classic;
  add_columns_option(cmd, a.columns);
  cmd.add_option("--core", a.core,
                 "Symplectic core: la:L:m, g:L:w, or library (fit only: a Hamiltonian from a "
                 "library of terms, selected from the data). Default: fit tries the library "
                 "core, then, unless it explains the data to the noise floor, an LA and a G "
                 "core, and keeps the lowest validation loss; train takes one by dimension")
      ->check(kCoreSpec);
  cmd.add_option("--model", a.model, "csympnet (default) or sympnet")
      ->check(one_of(fit_model_names()));
  // The ranges are the library's (core/options.hpp); here only the syntax is checked first.
  cmd.add_option("--epochs", a.epochs, "Epoch budget (default: by dimension)")
      ->check(kWholeNumber)
      ->check(library_range(kFitEpochsRange));
  cmd.add_option("--lr", a.lr, "AdamW learning rate (default 1e-3)")
      ->check(kFiniteNumber)
      ->check(library_range(kLrRange));
  cmd.add_option("--lr-schedule", a.lr_schedule, "cosine (default) or constant (the paper's)")
      ->check(one_of(lr_schedule_names()));
  cmd.add_option("--val-every", a.val_every, "Validate every K epochs (default 10)")
      ->check(kWholeNumber)
      ->check(library_range(kValEveryRange));
  // kSeed: CLI11 would wrap "-1" into 2^64 - 1 and clamp 2^64 for an unsigned seed.
  cmd.add_option("--seed", a.seed, "Seed of the validation split and the init (default 42)")
      ->check(kSeed);
  cmd.add_option("--val-fraction", a.val_fraction,
                 "Held-out share when no --val is given (default 0.2)")
      ->check(kFiniteNumber)
      ->check(library_range(kValFractionRange));
  cmd.add_option("--beta-init", a.beta_init, "Initial beta of CSympNet-ID (nonzero)")
      ->check(kFiniteNumber)
      ->check(library_nonzero("beta_init"));
  cmd.add_flag("--no-beta-decay", a.no_beta_decay, "Exclude beta from weight decay");
  // Two flags rather than CLI11's "!--no-warm-start", whose help reads "{false}".
  CLI::Option* on =
      cmd.add_flag("--warm-start", a.warm_start,
                   std::string("Start beta at the closed-form estimate of gamma from the data") +
                       (a.warm_start ? " (default)" : " (default: off)"));
  CLI::Option* off = cmd.add_flag_callback(
      "--no-warm-start", [&a] { a.warm_start = false; }, "Start beta at --beta-init instead");
  on->excludes(off);
  cmd.add_option("--refine", a.refine,
                 "Second stage after AdamW: none (the paper's recipe), lm, lbfgs, or auto (lm, "
                 "or lbfgs for large models) (default: " +
                     (recipe.refine_method ? to_string(*recipe.refine_method) : "auto") + ")")
      ->check(one_of(refine_choice_names()));
  cmd.add_option("--refine-iterations", a.refine_iterations,
                 "Iterations of the second stage (default 300)")
      ->check(kWholeNumber)
      ->check(library_range(kRefineIterationsRange));
  cmd.add_option("--refine-solver", a.refine_solver,
                 "LM linear solver: dense_qr, dense_normal_cholesky (both Ceres) or "
                 "blas_normal_cholesky (JᵀJ formed once per Jacobian with BLAS; fastest for "
                 "many parameters) (default: dense_qr; --refine auto takes "
                 "blas_normal_cholesky above 1000 parameters)")
      ->check(one_of(linear_solver_names()));
  cmd.add_option("--bootstrap", a.bootstrap,
                 "Bootstrap replicates: the spread of gamma_hat over refits on resampled "
                 "trajectories, in report.json (0: none; >= 10) (default: none). Not an "
                 "interval: plain `fit` identifies gamma with one")
      ->check(kWholeNumber)
      ->check(library_range(kBootstrapRange));
  add_threads_option(cmd, a.threads);
  add_arithmetic_option(cmd);
  cmd.add_option("--chunk-pairs", a.chunk_pairs,
                 "Pairs per chunk of the loss's sums (default 0: one chunk up to 512 pairs, 256 "
                 "above); the result depends on it, not on --threads or mpirun's ranks")
      ->check(kWholeNumber)
      ->check(library_range(kChunkPairsRange));
  cmd.add_option("--batch-size", a.batch_size,
                 "Mini-batches of this many pairs, reshuffled each epoch (default 0: one "
                 "full-batch step per epoch)")
      ->check(kWholeNumber)
      ->check(library_range(kBatchSizeRange));
  cmd.add_option("--out", a.out, "Output directory")->required()->check(kOutputPath);
  cmd.add_flag("--force", a.force, "Allow writing into a non-empty output directory");
  cmd.add_flag("-q,--quiet", a.quiet, "No progress line");
}

void run_fit(const FitArgs& a, bool verbose_summary) {
  FitSettings s;
  s.model = a.model;
  if (!a.core.empty()) s.core = parse_core(a.core);
  s.seed = a.seed;
  s.val_fraction = a.val_fraction;
  s.beta_init = a.beta_init;
  s.epochs = a.epochs;
  s.val_every = a.val_every;
  s.threads = a.threads;
  s.chunk_pairs = a.chunk_pairs;
  s.batch_size = a.batch_size;
  s.lr = a.lr;
  s.lr_schedule = a.lr_schedule;
  if (a.no_beta_decay) s.decay_damping = false;
  s.warm_start = a.warm_start;
  s.refine = a.refine;
  s.refine_iterations = a.refine_iterations;
  s.refine_solver = a.refine_solver;
  s.bootstrap = a.bootstrap;
  // Every option checked (ranges, spellings, the rules between them) before any work.
  FitConfig c = at_boundary([&] { return make_fit_config(a.classic, s); });
  // Under mpirun: one training over the ranks, its AdamW stage only; rank 0 alone talks and
  // writes (docs/architecture.md, "One training over MPI ranks").
  const Communicator& comm = process_communicator();
  const bool lead = comm.rank() == 0;
  if (comm.size() > 1) {
    if (c.refine_method != RefineMethod::kNone || c.bootstrap_replicates.value_or(1) != 0)
      throw Error("under mpirun with " + std::to_string(comm.size()) +
                  " ranks only the AdamW stage runs over the ranks; expected --refine none "
                  "--bootstrap 0 (train's defaults), or one process for the later stages");
    c.train.communicator = &comm;
  }
  std::optional<OutputDir> out_dir;
  if (lead) out_dir.emplace(prepare_output_dir(a.out, a.force));
  // Trajectory files keep the trajectory of each pair, so the bootstrap can resample them.
  // The training reader first: it refuses, at their line, values too large to train on and
  // files whose trajectories give no pairs, which the plain readers accept.
  const ColumnMap columns = parse_column_map(a.columns);
  PairSet data;
  std::vector<Index> groups;
  std::string data_name;
  {  // the text goes once parsed: at 40,000 pairs of d = 100 it is 300 MB
    const CsvInput input = read_csv_input(a.data, columns);  // once: a pipe or "-" works too
    data_name = input.name;
    data = parse_any_as_pairs(input.text, input.name);
    if (input.kind == CsvKind::kTrajectories) {
      const std::vector<Trajectory> trajs = parse_trajectories_csv(input.text, input.name);
      for (std::size_t k = 0; k < trajs.size(); ++k)
        groups.insert(groups.end(), static_cast<std::size_t>(trajs[k].steps()),
                      static_cast<Index>(k));
    }
  }
  std::optional<PairSet> val;
  if (!a.val.empty()) {
    const CsvInput val_input = read_csv_input(a.val, columns);
    val = parse_any_as_pairs(val_input.text, val_input.name);
    if (val->d() != data.d())
      throw Error("--val " + a.val + " has d = " + std::to_string(val->d()) + " (" +
                  std::to_string(2 * val->d()) + " state columns) but " + data_name + " has d = " +
                  std::to_string(data.d()) + "; expected validation data of the same system");
  }
  FitResult r;
  {
    ProgressLine progress(a.quiet || !lead);
    ProgressCallback line = progress.callback();
    // A signal may reach the ranks at different epochs: they agree at each validation.
    if (comm.size() > 1)
      line = [line, &comm](const TrainProgress& p) { return !comm.any(!line(p)); };
    r = fit_pairs(data, val, c, line, groups, [] { return interrupted(); });
  }
  if (!lead) {  // the same result as rank 0's, which reports it
    if (interrupted())
      throw Interrupted("rank " + std::to_string(comm.rank()) +
                        " stopped with the others; rank 0 saved the best checkpoint in " + a.out);
    return;
  }
  const auto gamma = r.model.damping_rate(r.theta);
  nlohmann::json report = fit_report(r);
  report["data"] = a.data;
  if (!a.columns.empty()) report["columns"] = a.columns;
  if (!a.val.empty()) report["validation"] = a.val;
  const auto quality = [&report](const char* key) { return report["quality"][key].get<double>(); };
  // One set: the report, the wall times (apart, so the report stays bit-identical run to
  // run) and the model, committed together.
  out_dir->commit(
      {{"report.json", json_file_text(report)},
       {"timings.json",
        json_file_text({{"train_seconds", r.training.seconds},
                        {"refine_seconds", r.refine.seconds},
                        {"bootstrap_seconds", r.interval ? r.interval->seconds : 0.0}})},
       {"model.json",
        model_file_text(r.model, r.theta,
                        {{"data", a.data}, {"seed", r.config.seed}, {"train", r.config.train}})}});
  if (gamma)
    std::printf("gamma_hat = %.10g per time unit of the data (%s)\n", *gamma, kNoIntervalNote);
  if (gamma && r.interval)
    std::printf(
        "bootstrap spread of gamma_hat over %ld refits: [%.6g, %.6g] (not an interval; "
        "report.json \"bootstrap\")\n",
        r.interval->replicates, r.interval->low, r.interval->high);
  if (!r.scale_note.empty()) std::fprintf(stderr, "csympnet: warning: %s\n", r.scale_note.c_str());
  if (verbose_summary || !a.quiet) {
    std::printf("%s, d = %lld, %lld training / %lld validation pairs, %lld params\n",
                to_string(r.config.model).c_str(), static_cast<long long>(r.train.d()),
                static_cast<long long>(r.train.size()), static_cast<long long>(r.val.size()),
                static_cast<long long>(r.model.n_params()));
    if (r.warm_start)
      std::printf("warm start gamma_0 = %.6g (%s)\n", r.warm_start->gamma,
                  to_string(r.warm_start->method).c_str());
    else if (!r.warm_start_note.empty())
      std::printf("no warm start (%s); beta started at %g\n", r.warm_start_note.c_str(),
                  r.config.beta_init);
    std::printf("%s\n", r.training.brief_report().c_str());
    if (r.refine.method != RefineMethod::kNone)
      std::printf("%s\n", r.refine.brief_report().c_str());
    std::printf("train loss %.3e, held-out loss %.3e, %s of a step %.2e\n", quality("train_loss"),
                quality("val_loss"), kHeldOutResidualWords, quality("val_relative_residual"));
    std::printf(
        "structure residual mean %.2e, max %.2e; wrote %s/{report.json,model.json,timings.json}\n",
        quality("structure_residual_mean"), quality("structure_residual_max"), a.out.c_str());
  }
  if (r.training.stop_reason == StopReason::kDiverged)
    throw Error("training diverged at epoch " + std::to_string(r.training.epochs_run + 1) +
                " (non-finite loss or gradient); the best checkpoint (epoch " +
                std::to_string(r.training.best_epoch) + ") was kept in " + a.out);
  if (interrupted()) {
    if (r.refine.stopped)
      throw Interrupted(
          "stopped in the second stage (" + to_string(r.config.refine.method) + ") after " +
          std::to_string(r.refine.iterations) + " iterations; the best iterate (" +
          std::to_string(r.refine.best_iteration) + ") and its report are in " + a.out);
    if (r.stopped && r.training.stop_reason == StopReason::kBudget)
      throw Interrupted("stopped during the bootstrap (" + r.interval_note +
                        "); the refined model and its report are in " + a.out);
    if (!r.stopped) throw Interrupted("the fit had finished; its complete result is in " + a.out);
    throw Interrupted("stopped at epoch " + std::to_string(r.training.epochs_run) +
                      "; the best checkpoint (epoch " + std::to_string(r.training.best_epoch) +
                      ") and its report are in " + a.out);
  }
}
// `fit` with the identification recipe.
namespace fs = std::filesystem;

// The figure of a committed fit (OUT/fit.png, OUT/fit.pdf), or why there is none: the
// figure reads the record again, so it needs a file, not standard input or a pipe, and a
// record, not pairs.
FigureOutcome figure_of(const FitArgs& a, bool pairs_only) {
  std::error_code ec;
  if (pairs_only) return {false, a.data + " holds pairs, not a record to simulate"};
  if (a.data == "-" || !fs::is_regular_file(a.data, ec))
    return {false,
            "the data were read from standard input or a pipe; `python3 -m "
            "csympnet.fit_figure OUT --data FILE` draws it from a copy"};
  return draw_fit_figure(a.out);
}
// The identification's settings from fit's options, every one checked (ranges, spellings)
// before any work; the classic recipe's and train's options refused by name.
IdentifyConfig identify_config_of(const FitArgs& a, const CLI::App& cmd) {
  for (const char* only_train : {"--chunk-pairs", "--batch-size"})
    if (cmd.count(only_train) > 0)
      throw CLI::ValidationError(only_train, "belongs to train and --recipe classic");
  for (const char* classic :
       {"--refine", "--refine-iterations", "--refine-solver", "--bootstrap", "--warm-start",
        "--val", "--beta-init", "--no-beta-decay", "--lr-schedule", "--val-every"})
    if (cmd.count(classic) > 0)
      throw CLI::ValidationError(classic,
                                 "belongs to --recipe classic; the default recipe "
                                 "chooses it itself (docs/identification.md)");
  nlohmann::json settings = {{"window", a.window},
                             {"balanced", a.loss == "balanced"},
                             {"normalize", !a.no_normalize},
                             {"dof_scales", a.dof_scales},
                             {"derived_momenta", a.derived_momenta == "use" ? "use" : "set_aside"},
                             {"dissipation", a.dissipation},
                             {"record_fit", a.record_fit},
                             {"lm_iterations", a.lm_iterations},
                             {"blocks", a.blocks},
                             {"level", a.level},
                             {"threads", a.threads}};
  if (!a.core.empty()) settings["core"] = parse_core(a.core);
  if (a.seed) settings["seed"] = *a.seed;
  if (a.epochs) settings["epochs"] = *a.epochs;
  if (a.lr) settings["lr"] = *a.lr;
  if (a.val_fraction) settings["val_fraction"] = *a.val_fraction;
  if (!a.init.empty()) settings["init"] = a.init;
  return at_boundary([&] { return make_identify_config(settings); });
}

// The record as fit reads it: its kind (positions, pairs, trajectories; with inputs or not)
// and its trajectories (pairs become two-sample trajectories).
struct FitRecord {
  bool positions_only = false, pairs_only = false, driven = false;
  std::vector<Trajectory> trajs;
};
FitRecord read_fit_record(const CsvInput& input) {
  FitRecord rec;
  rec.positions_only = input.kind == CsvKind::kPositions;
  // Known inputs (u1..um): the driven route, on the positions with the inputs.
  rec.driven = input.inputs > 0;
  // The training reader first: it refuses, at their line, values too large to train on and
  // files whose trajectories give no pairs, which the plain readers accept.
  const PairSet checked =
      rec.positions_only || rec.driven ? PairSet{} : parse_any_as_pairs(input.text, input.name);
  rec.pairs_only = input.kind == CsvKind::kPairs;
  if (rec.driven) {
    rec.trajs = rec.positions_only
                    ? parse_positions_csv(input.text, input.name, InputColumns::kRead)
                    : parse_trajectories_csv(input.text, input.name, InputColumns::kRead);
  } else if (rec.positions_only) {
    rec.trajs = parse_positions_csv(input.text, input.name);
  } else if (rec.pairs_only) {
    for (Index j = 0; j < checked.size(); ++j) {
      Trajectory t;
      t.t.resize(2);
      t.t << 0.0, checked.h(j);
      t.z.resize(checked.dim(), 2);
      t.z.col(0) = checked.z0.col(j);
      t.z.col(1) = checked.z1.col(j);
      rec.trajs.push_back(std::move(t));
    }
  } else {
    rec.trajs = parse_trajectories_csv(input.text, input.name);
  }
  return rec;
}

// What fit tells as it works: the stages on stderr, AdamW on the progress line, LM one line a
// second at most (on a terminal, redrawn in place) and the last one; every poll of the stop
// request and of the progress an agreement over MPI ranks.
IdentifyHooks fit_hooks(const Communicator& comm, bool talk, const ProgressCallback& adamw_line,
                        StageClock& clock) {
  IdentifyHooks hooks;
  hooks.should_stop = [] { return interrupted(); };
  if (comm.size() > 1) {
    // A signal may reach the ranks at different moments: every poll is an agreement.
    hooks.communicator = &comm;
    hooks.should_stop = [&comm] { return comm.any(interrupted()); };
  }
  hooks.stage = [talk, &clock](const std::string& s) {
    clock.enter(s);
    if (talk)
      std::fprintf(stderr, "%sfit: %s\n", isatty(STDERR_FILENO) == 1 ? "\n" : "", s.c_str());
  };
  auto last = std::make_shared<std::chrono::steady_clock::time_point>();
  const bool tty = isatty(STDERR_FILENO) == 1;
  hooks.progress = [adamw_line, talk, last, tty](const TrainProgress& p) {
    if (std::strcmp(p.stage, "lm") != 0) return adamw_line(p);
    if (!talk) return true;
    const auto now = std::chrono::steady_clock::now();
    if (p.epoch < p.epochs && now - *last < std::chrono::seconds(1)) return true;
    *last = now;
    std::fprintf(stderr, "%s  LM iteration %ld / %ld, validation loss %.3e%s", tty ? "\r" : "",
                 p.epoch, p.epochs, p.val_loss, tty ? "" : "\n");
    return true;  // an interrupt reaches LM through should_stop
  };
  if (comm.size() > 1)
    hooks.progress = [line = hooks.progress, &comm](const TrainProgress& p) {
      return !comm.any(!line(p));
    };
  return hooks;
}

// report.json, timings.json and model.json as one set in OUT; a figure of an earlier fit there
// is removed, since it would not show this one.
void write_fit_outputs(const FitArgs& a, const IdentifyResult& r,
                       const std::optional<TimeUnit>& unit, const StageClock& clock,
                       OutputDir& out_dir) {
  nlohmann::json report = identify_report(r);
  report["data"]["file"] = a.data;
  if (!a.columns.empty()) report["data"]["columns"] = a.columns;
  report["time_unit"] = time_unit_report(unit, report);
  out_dir.commit(
      {{"report.json", json_file_text(report)},
       {"timings.json", json_file_text([&] {
          nlohmann::json t = clock.report();
          t["train_seconds"] = r.adamw_seconds;
          t["lm_seconds"] = r.lm_seconds;
          t["interval_seconds"] = r.interval_seconds;
          t["choices_seconds"] = identify_wall_seconds(r);
          return t;
        }())},
       {"model.json", model_file_text(r.model, r.theta, [&] {
          nlohmann::json meta = {{"data", a.data}, {"seed", r.config.seed}, {"recipe", "identify"}};
          if (r.config.init) meta["init"] = r.config.init->file;
          // The interval travels with the model (csympnet.load(...).gamma_interval), as the
          // model files of Python's identify carry it: only an identified γ̂ has one.
          if (r.identified && r.interval) {
            meta["gamma_interval"] = {r.interval->low, r.interval->high};
            meta["gamma_interval_level"] = r.interval->level;
          }
          return meta;
        }())}});
  for (const char* name : kFitFigureFiles) {
    std::error_code ec;
    fs::remove(fs::path(a.out) / name, ec);
  }
}

// The fit's figure, unless skipped or impossible; whether it was drawn. An interrupt while
// drawing leaves no half set of figures.
bool draw_fit_figures(const FitArgs& a, const FitRecord& rec, const IdentifyResult& r) {
  if (a.no_figures || r.stopped || interrupted()) return false;
  std::fflush(stdout);  // the answer first, while the figure is drawn
  const FigureOutcome f = figure_of(a, rec.pairs_only);
  if (interrupted()) {
    for (const char* name : kFitFigureFiles) {
      std::error_code ec;
      fs::remove(fs::path(a.out) / name, ec);
    }
    throw Interrupted(
        "stopped while drawing the figure; report.json and model.json are "
        "complete in " +
        a.out);
  }
  if (!f.drawn)
    std::fprintf(stderr, "fit: figure not drawn: %s (--no-figures skips it)\n", f.why.c_str());
  return f.drawn;
}

void run_identify(const FitArgs& a, const CLI::App& cmd) {
  const IdentifyConfig c = identify_config_of(a, cmd);
  // Under mpirun: one fit over the ranks, its window sums shared out; rank 0 alone talks and
  // writes (docs/architecture.md, "Identification over MPI ranks").
  const Communicator& comm = process_communicator();
  const bool lead = comm.rank() == 0;
  std::optional<OutputDir> out_dir;
  if (lead) out_dir.emplace(prepare_output_dir(a.out, a.force));
  const ColumnMap columns = parse_column_map(a.columns);
  // The clock's unit changes only the report: given, or stated by the time column's name.
  std::optional<TimeUnit> unit;
  if (!a.time_unit.empty()) unit = parse_time_unit(a.time_unit, "--time-unit");
  for (const auto& [canonical, own] : columns.columns)
    if (canonical == "t" && !unit) unit = time_unit_of_column(own);
  const FitRecord rec = read_fit_record(read_csv_input(a.data, columns));  // once: a pipe works
  IdentifyResult r;
  StageClock clock;  // where the fit's time goes (timings.json)
  {
    ProgressLine progress(a.quiet || !lead);
    clock.enter("preparing the data");
    const IdentifyHooks hooks = fit_hooks(comm, !a.quiet && lead, progress.callback(), clock);
    try {
      r = rec.driven           ? identify_driven(rec.trajs, rec.positions_only, c, hooks)
          : rec.positions_only ? identify_positions(rec.trajs, c, hooks)
                               : identify(rec.trajs, rec.pairs_only, c, hooks);
    } catch (const OptionError& e) {  // an option the data cannot take (--window on pairs)
      // --init names its own file: the data are not to blame.
      if (e.message(cli_spelling()).rfind("--init", 0) == 0) throw;
      throw Error(a.data + ": " + e.message(cli_spelling()));
    } catch (const Error& e) {
      throw Error(a.data + ": " + e.what());  // what the data lack: name the file
    }
    clock.finish();
  }
  if (!lead) {  // the same result as rank 0's, which reports it
    if (r.stopped)
      throw Interrupted("rank " + std::to_string(comm.rank()) +
                        " stopped with the others; rank 0 saved the best parameters in " + a.out);
    return;
  }
  write_fit_outputs(a, r, unit, clock, *out_dir);
  if (r.identified) {
    print_gamma(r, unit);
    print_dissipation(r);
    print_input(r);
    print_modes(r, unit);
  } else {
    std::printf("gamma_hat: %s\n", r.rejected ? "model rejected" : "not identified");
  }
  print_checks(r.checks, a.quiet);
  const bool figure = draw_fit_figures(a, rec, r);
  if (!a.quiet) print_identify_details(r, a.out, figure);
  if (r.stopped)
    throw Interrupted("stopped; the best parameters so far and their report are in " + a.out);
  if (!r.identified) {
    std::string why;
    for (const auto& x : r.reasons) why += (why.empty() ? "" : "; ") + x;
    why += " (report: " + (fs::path(a.out) / "report.json").string() + ")";
    if (r.rejected) throw ModelRejected(why);
    throw NotIdentified(why);
  }
}
}  // namespace

// DATA as the first argument, or as --data: one option each, so that help lists it once as
// required and --data once as its other spelling (one "data,--data" option was listed in both
// places, each time as REQUIRED). Given neither, a usage error (exit 2) as CLI11's own.
void add_data_argument(CLI::App& cmd, std::string& data, const std::string& help) {
  CLI::Option* positional =
      cmd.add_option("data", data, help + " (required; or give it as --data)")->check(kInputFile);
  CLI::Option* named = cmd.add_option("--data", data, "The same as DATA, named")->check(kInputFile);
  positional->excludes(named);
  cmd.parse_complete_callback([&cmd, positional, named] {
    const CLI::Option* help_flag = cmd.get_help_ptr();
    const bool help_asked = help_flag != nullptr && help_flag->count() > 0;
    if (positional->count() == 0 && named->count() == 0 && !help_asked)
      throw CLI::RequiredError("DATA (a CSV file, or --data FILE)");
  });
}

void add_train(CLI::App& app) {
  // train: AdamW alone unless told otherwise (FitConfig::adamw_only).
  auto a = std::make_shared<FitArgs>(FitConfig::adamw_only());
  CLI::App* cmd = app.add_subcommand("train", "Train a model on pairs (or trajectories) CSV");
  add_data_argument(*cmd, a->data, "Training CSV (pairs or trajectories); - for stdin");
  cmd->add_option("--val", a->val, "Validation CSV (default: a split of DATA)")
      ->check(kExistingFile);
  add_fit_options(*cmd, *a);
  cmd->callback([a] {
    if (parse_only()) return;
    run_fit(*a, false);
  });
}

// `fit --help` in groups, by what each option applies to (options of both recipes are many,
// and most users need only the first group).
void group_fit_options(CLI::App& cmd) {
  const std::vector<std::pair<const char*, std::vector<const char*>>> groups = {
      {"Your data", {"--data", "--columns", "--time-unit"}},
      {"Identification (the default recipe)",
       {"--core", "--window", "--loss", "--no-normalize", "--dof-scales", "--derived-momenta",
        "--dissipation", "--record-fit", "--lm-iterations", "--level", "--blocks", "--init",
        "--epochs", "--lr", "--seed", "--val-fraction", "--threads"}},
      {"Only with --recipe classic (training a map: one-step loss, second stage, bootstrap)",
       {"--recipe", "--model", "--val", "--lr-schedule", "--val-every", "--beta-init",
        "--no-beta-decay", "--warm-start", "--no-warm-start", "--refine", "--refine-iterations",
        "--refine-solver", "--bootstrap", "--chunk-pairs", "--batch-size"}},
      {"Output", {"--out", "--force", "--quiet", "--no-figures"}},
  };
  for (CLI::Option* o : cmd.get_options())
    for (const auto& [group, names] : groups)
      for (const char* name : names)
        if (o->check_name(name)) o->group(group);
}

void add_fit(CLI::App& app) {
  // fit identifies γ: with --recipe classic, FitConfig's identification recipe
  // (docs/identification.md).
  auto a = std::make_shared<FitArgs>(FitConfig::identification());
  CLI::App* cmd = app.add_subcommand(
      "fit", "Fit CSympNet-ID to your own pairs or trajectories and print gamma_hat");
  add_data_argument(*cmd, a->data, "CSV of pairs or trajectories; - for standard input");
  add_fit_options(*cmd, *a);
  cmd->add_option("--recipe", a->recipe,
                  "identify (default: windows, balanced residuals, LM, a block interval) or "
                  "classic (one-step loss, --refine, --bootstrap)")
      ->check(one_of({"identify", "classic"}));
  cmd->add_option("--window", a->window,
                  "Steps per window of the loss (default 0: automatic, up to 4)")
      ->check(kWholeNumber)
      ->check(library_range(kWindowRange));
  cmd->add_option("--loss", a->loss,
                  "balanced (default: residuals in the middle of the map) or one-step")
      ->check(one_of(identify_loss_names()));
  cmd->add_flag("--no-normalize", a->no_normalize, "Fit in the data's own units and offsets");
  cmd->add_option("--dof-scales", a->dof_scales,
                  "Per-dof momentum scales as parameters, for velocities instead of momenta: "
                  "auto (default: learned when d > 1), learned or fixed")
      ->check(one_of(dof_scales_names()));
  cmd->add_option("--derived-momenta", a->derived_momenta,
                  "p columns computed from noisy positions (numpy.gradient, Savitzky-Golay): "
                  "set-aside (default: fit the positions alone, momenta as hidden states) or "
                  "use (as given, with a warning: the interval does not cover the filter's bias)")
      ->check(CLI::IsMember({"set-aside", "use"}));
  cmd->add_option("--dissipation", a->dissipation,
                  "Dissipation beside the viscous rate gamma (library core): auto (default: "
                  "Coulomb friction or quadratic drag when the held-out loss and the amplitude "
                  "check both call for them), viscous, viscous+coulomb or viscous+drag")
      ->check(one_of(dissipation_choices()));
  cmd->add_option("--record-fit", a->record_fit,
                  "Trajectories with momenta: auto (default), windows (balanced windows of a "
                  "few steps) or whole (then the whole record by multiple shooting, q and p "
                  "observed with their own noise)")
      ->check(one_of(record_fit_choices()));
  cmd->add_option("--lm-iterations", a->lm_iterations,
                  "Levenberg-Marquardt budget (default 0: scaled to the problem)")
      ->check(kWholeNumber)
      ->check(library_range(kLmIterationsRange));
  cmd->add_option("--level", a->level, "Level of the interval for gamma (default 0.95)")
      ->check(library_range(kLevelRange));
  cmd->add_option("--blocks", a->blocks,
                  "Segments a long trajectory is cut into, for validation and the interval "
                  "(default 20)")
      ->check(kWholeNumber)
      ->check(library_range(kBlocksRange));
  cmd->add_option("--time-unit", a->time_unit,
                  "The unit of the time column: s, ms, us, ns, min or h (default: read from a "
                  "--columns time name such as t_ms or timestamp_s). Only the report changes: "
                  "gamma also per s, and the amplitude decay rate gamma/2")
      ->check(one_of(time_unit_names()));
  cmd->add_option("--init", a->init,
                  "Model file of CSympNet-ID to start from (from `fit`, or saved by "
                  "csympnet.torch): its core, parameters and units; AdamW only with --epochs")
      ->check(kExistingFile);
  cmd->add_option("--val", a->val, "Validation CSV (default: a split of DATA)")
      ->check(kExistingFile);
  cmd->add_flag("--no-figures", a->no_figures,
                "Draw no figure. By default the identification draws OUT/fit.png and "
                "OUT/fit.pdf (python3 with matplotlib): the record against the model's free "
                "run, the residuals, the amplitude decay with gamma_hat, the modes");
  group_fit_options(*cmd);
  CLI::App* self = cmd;
  cmd->callback([a, self] {
    if (parse_only()) return;
    const FitModel model =
        a->model ? parse_fit_model(*a->model) : a->classic.model;  // --model was checked
    const bool identify = a->recipe == "identify" && model == FitModel::kCSympNet;
    if (self->count("--time-unit") > 0 && !identify)
      throw CLI::ValidationError("--time-unit",
                                 "belongs to the default recipe (--recipe identify) "
                                 "with --model csympnet");
    if (!a->init.empty() && !identify)
      throw CLI::ValidationError("--init",
                                 "belongs to the default recipe (--recipe identify) "
                                 "with --model csympnet");
    if (identify)
      run_identify(*a, *self);
    else
      run_fit(*a, true);
  });
}

}  // namespace csympnet::cli
