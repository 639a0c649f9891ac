// `run` (generate + train + evaluate a preset) and `describe` (architecture and size).
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>

#include "commands.hpp"
#include "core_option.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/models/model.hpp"
#include "csympnet/paper/outputs.hpp"
#include "csympnet/paper/paper_values.hpp"
#include "csympnet/paper/run.hpp"
#include "interrupt.hpp"
#include "progress.hpp"
#include "system_options.hpp"

namespace csympnet::cli {

namespace {
struct RunArgs {
  std::string preset, model = "csympnet", out, reference = "splitting",
                      recipe = to_string(RunRecipe::kDefault);
  std::optional<std::string> lr_schedule;
  std::optional<double> lr;
  std::uint64_t seed = 42;
  std::optional<long> epochs;
  long val_every = 10;
  double sigma = 0.0, beta_init = 0.1;
  bool no_beta_decay = false, quiet = false, force = false, warm_start = false;
  std::string refine = "none", core;
  std::optional<std::string> refine_solver;
  std::optional<long> refine_iterations;
  int threads = 1;
  SystemOverrides system;
};

// Our numbers, with the paper's beside them where it reports the same quantity.
void print_run_summary(const RunArgs& args, const RunResult& r) {
  const Diagnostics& d = r.diagnostics;
  const auto paper = paper_values(args.preset, args.model);
  std::printf("%s on %s (seed %llu, sigma %g): %lld params, %ld epochs in %.2f s\n",
              args.model.c_str(), args.preset.c_str(), static_cast<unsigned long long>(args.seed),
              args.sigma, static_cast<long long>(r.model.n_params()), r.training.epochs_run,
              r.training.seconds);
  std::printf("  recipe %s\n", r.report["recipe"].get<std::string>().c_str());
  if (r.refine.method != RefineMethod::kNone)
    std::printf("  %s\n", r.refine.brief_report().c_str());
  std::printf("  %-26s %-14s %s\n", "quantity", "ours", "paper (seed 42, sigma 0)");
  auto row = [](const char* name, double ours, std::optional<double> theirs) {
    if (theirs)
      std::printf("  %-26s %-14.4e %.4e\n", name, ours, *theirs);
    else
      std::printf("  %-26s %-14.4e -\n", name, ours);
  };
  if (d.gamma_hat) {
    std::printf("  %-26s %-14.10g ", "gamma_hat", *d.gamma_hat);
    if (paper && paper->gamma_hat)
      std::printf("%.4e\n", *paper->gamma_hat);
    else
      std::printf("-\n");
    row("|gamma_hat - gamma|", *d.gamma_abs_err, paper ? paper->gamma_abs_err : std::nullopt);
  }
  row("L2 rollout error", d.l2_error, paper ? std::optional(paper->l2_error) : std::nullopt);
  row("E[R]", d.residual_mean, paper ? paper->residual_mean : std::nullopt);
  row("max R", d.residual_max, paper ? paper->residual_max : std::nullopt);
  row("E|lambda_hat - lambda*|", d.lambda_abs_err_mean,
      paper ? paper->lambda_abs_err_mean : std::nullopt);
  row("structure residual (max)", d.structure_residual_max, std::nullopt);
  if (d.gamma_hat)
    std::printf(
        "  gamma_hat is a training outcome on the preset, with no interval; `csympnet fit` "
        "identifies gamma on your own data, with an interval and checks\n");
  std::printf("  wrote %s/{report.json,model.json,rollout.csv,reference.csv,energy.csv}\n",
              args.out.c_str());
}

CLI::Option* add_preset_option(CLI::App& cmd, std::string& preset) {
  return cmd.add_option("--preset", preset, "Benchmark preset")
      ->required()
      ->check(one_of(preset_names()));
}
}  // namespace

void add_run(CLI::App& app) {
  auto args = std::make_shared<RunArgs>();
  CLI::App* cmd = app.add_subcommand(
      "run", "Generate a preset's data, train a model, evaluate it, write DIR/report.json");
  add_preset_option(*cmd, args->preset);
  cmd->add_option("--model", args->model, "Model to train")->check(one_of(model_types()));
  // kSeed: CLI11 would wrap "-1" into 2^64 - 1 and clamp 2^64 for an unsigned seed.
  cmd->add_option("--seed", args->seed, "Training seed (data, validation, init); default 42")
      ->check(kSeed);
  // The ranges are the library's (core/options.hpp); here only the syntax is checked first.
  cmd->add_option("--epochs", args->epochs, "Epoch budget (default: the preset's)")
      ->check(kWholeNumber)
      ->check(library_range(kEpochsRange));
  cmd->add_option("--recipe", args->recipe,
                  "Training recipe: default (cosine-annealed rate) or paper (constant rate)")
      ->check(one_of(run_recipe_names()));
  cmd->add_option("--lr", args->lr, "AdamW learning rate (default: the recipe's)")
      ->check(kFiniteNumber)
      ->check(library_range(kLrRange));
  cmd->add_option("--lr-schedule", args->lr_schedule, "constant or cosine (default: the recipe's)")
      ->check(one_of(lr_schedule_names()));
  cmd->add_option("--val-every", args->val_every, "Validate every K epochs (default 10)")
      ->check(kWholeNumber)
      ->check(library_range(kValEveryRange));
  cmd->add_option("--sigma", args->sigma, "Relative observation noise (default 0)")
      ->check(kFiniteNumber)
      ->check(library_range(kSigmaRange));
  cmd->add_option("--reference", args->reference, "Reference solver for the data")
      ->check(one_of({"splitting", "expm", "rk"}));
  cmd->add_option("--beta-init", args->beta_init, "Initial beta of CSympNet-ID (nonzero)")
      ->check(kFiniteNumber)
      ->check(library_nonzero("beta_init"));
  cmd->add_flag("--no-beta-decay", args->no_beta_decay,
                "Exclude beta from weight decay (beyond the paper's recipe)");
  cmd->add_option("--refine", args->refine,
                  "Second stage after AdamW for map models: none (default, the paper's "
                  "recipe), lm (Levenberg-Marquardt) or lbfgs")
      ->check(one_of(refine_method_names()));
  cmd->add_option("--refine-iterations", args->refine_iterations,
                  "Iterations of the second stage (default 300)")
      ->check(kWholeNumber)
      ->check(library_range(kRefineIterationsRange));
  cmd->add_option(
         "--refine-solver", args->refine_solver,
         "LM linear solver: dense_qr, dense_normal_cholesky (both Ceres) or "
         "blas_normal_cholesky (JᵀJ formed once per Jacobian with BLAS; fastest for "
         "many parameters) (default: dense_qr where one Ceres iteration is small enough to "
         "stop within a second of Ctrl-C, else blas_normal_cholesky; report.json's "
         "config.refine.linear_solver says which)")
      ->check(one_of(linear_solver_names()));
  cmd->add_option("--core", args->core,
                  "Symplectic core of csympnet/sympnet: la:L:m or g:L:w (default: the preset's)")
      ->check(kCoreSpec);
  cmd->add_flag("--warm-start", args->warm_start,
                "CSympNet-ID: start beta at the closed-form estimate of gamma from the data");
  add_threads_option(*cmd, args->threads);
  add_arithmetic_option(*cmd);
  cmd->add_option("--out", args->out, "Output directory")->required()->check(kOutputPath);
  cmd->add_flag("--force", args->force, "Allow writing into a non-empty output directory");
  cmd->add_flag("-q,--quiet", args->quiet, "No progress line");
  args->system.add_to(*cmd);
  cmd->callback([args] {
    if (parse_only()) return;
    RunConfig c = default_run_config(args->preset, args->model);
    args->system.apply(c.preset);
    if (!args->core.empty()) c.preset.core = parse_core(args->core);
    c.seed = args->seed;
    c.sigma = args->sigma;
    apply_run_recipe(c, parse_run_recipe(args->recipe));
    if (args->epochs) c.train.epochs = *args->epochs;
    if (args->lr) c.train.adamw.lr = *args->lr;
    if (args->lr_schedule) c.train.lr_schedule = parse_lr_schedule(*args->lr_schedule);
    c.train.val_every = args->val_every;
    c.train.threads = args->threads;
    c.train.adamw.decay_damping = !args->no_beta_decay;
    c.reference.method = parse_reference(args->reference);
    c.beta_init = args->beta_init;
    c.refine.method = parse_refine_method(args->refine);
    if (args->refine_iterations) c.refine.iterations = *args->refine_iterations;
    if (args->refine_solver)
      c.refine.linear_solver = parse_linear_solver(*args->refine_solver);
    else
      c.auto_linear_solver = true;
    c.warm_start = args->warm_start;
    // Every option checked (ranges, the rules between them) before any work.
    at_boundary([&] { c.validate(); });
    const OutputDir out_dir = prepare_output_dir(args->out, args->force);
    RunResult r;
    {
      ProgressLine progress(args->quiet);
      r = run_experiment(c, progress.callback(), /*evaluate_if_stopped=*/true,
                         [] { return interrupted(); });
    }
    out_dir.commit(run_output_files(r));
    if (!args->quiet) print_run_summary(*args, r);
    if (r.training.stop_reason == StopReason::kDiverged)
      throw Error("training diverged at epoch " + std::to_string(r.training.epochs_run + 1) +
                  " (non-finite loss or gradient); the best checkpoint (epoch " +
                  std::to_string(r.training.best_epoch) + ") was kept in " + args->out);
    if (interrupted())
      throw Interrupted("stopped at epoch " + std::to_string(r.training.epochs_run) +
                        "; the best checkpoint (epoch " + std::to_string(r.training.best_epoch) +
                        "), evaluated, and its report are in " + args->out);
  });
}

void add_describe(CLI::App& app) {
  auto preset = std::make_shared<std::string>();
  auto model = std::make_shared<std::string>("csympnet");
  auto system = std::make_shared<SystemOverrides>();
  CLI::App* cmd =
      app.add_subcommand("describe", "Print a preset model's architecture and size as JSON");
  add_preset_option(*cmd, *preset);
  cmd->add_option("--model", *model, "Model")->check(one_of(model_types()));
  system->add_to(*cmd);
  cmd->callback([preset, model, system] {
    if (parse_only()) return;
    Preset p = preset_by_name(*preset);
    system->apply(p);
    const Model m = make_model(model_spec_for(p, *model));
    nlohmann::json out = {{"model", *model},        {"preset", *preset},
                          {"params", m.n_params()}, {"architecture", m.hyperparams()},
                          {"system", p.system},     {"train", train_options_for(p, *model)}};
    std::cout << out.dump(2) << "\n";
  });
}

}  // namespace csympnet::cli
